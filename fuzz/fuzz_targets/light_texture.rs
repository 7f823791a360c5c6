#![no_main]
//! Fuzz target: see `lightloom_nodes::fuzzing::light_texture`.

libfuzzer_sys::fuzz_target!(|data: &[u8]| lightloom_nodes::fuzzing::light_texture(data));
