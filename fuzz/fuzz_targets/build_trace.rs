#![no_main]
//! Fuzz target: see `quiver::checks::build_and_trace`.

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| quiver::checks::build_and_trace(data));
