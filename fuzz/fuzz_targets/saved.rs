#![no_main]
//! Fuzz target: see `quiver_lab::checks::saved_bvh`.

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| quiver_lab::checks::saved_bvh(data));
