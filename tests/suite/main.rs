//! quiver's integration tests, one crate: every module below tests one part of the pipeline
//! against an oracle (the brute-force reference, the single-ray kernel, obvhs, the SPD's
//! published counts, exact geometry). Shared helpers live in `common`.

mod common;

mod build;
mod contract;
mod equivalence;
mod fuzz_regressions;
mod hard_cases;
mod havran;
mod inputs;
mod meshes;
mod mixed;
mod motion;
mod motion_mesh;
mod obvhs;
mod packets;
mod point;
mod predict;
mod refit;
mod render;
mod save;
mod sbvh;
mod scale;
mod scenes;
mod world;
