#![no_main]
//! Fuzz target: see `quiver_lab::checks::point_queries`.

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| quiver_lab::checks::point_queries(data));
