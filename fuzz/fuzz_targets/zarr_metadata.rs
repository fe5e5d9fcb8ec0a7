//! `cargo fuzz run zarr_metadata`: the body is [`chunkc::fuzzing::zarr_metadata`], which the replay test
//! (tests/fuzz_corpus.rs) also runs on every checked-in corpus file.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    chunkc::fuzzing::zarr_metadata(data);
});
