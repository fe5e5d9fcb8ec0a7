//! `cargo fuzz run hdf5_attributes`: the body is [`chunkc::fuzzing::hdf5_attributes`], which the replay test
//! (tests/fuzz_corpus.rs) also runs on every checked-in corpus file.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    chunkc::fuzzing::hdf5_attributes(data);
});
