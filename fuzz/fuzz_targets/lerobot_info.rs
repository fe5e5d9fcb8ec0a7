//! `cargo fuzz run lerobot_info`: the body is [`chunkc::fuzzing::lerobot_info`], which the replay test
//! (tests/fuzz_corpus.rs) also runs on every checked-in corpus file.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    chunkc::fuzzing::lerobot_info(data);
});
