#![no_main]
//! Fuzz target: see `quiver::checks::obj_load`.

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| quiver::checks::obj_load(data));
