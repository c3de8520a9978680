#![no_main]
//! Fuzz target: see `quiver_lab::checks::from_tree_against_reference`.

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| quiver_lab::checks::from_tree_against_reference(data));
