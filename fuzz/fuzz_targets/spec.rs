//! `cargo fuzz run spec`: the body is [`chunkc::fuzzing::spec`], which the replay test
//! (tests/fuzz_corpus.rs) also runs on every checked-in corpus file.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    chunkc::fuzzing::spec(data);
});
