#![no_main]
//! Fuzz target: see `lightloom_nodes::fuzzing::normal_map`.

libfuzzer_sys::fuzz_target!(|data: &[u8]| lightloom_nodes::fuzzing::normal_map(data));
