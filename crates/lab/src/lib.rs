//! quiver-lab: quiver's harness.

pub mod accuracy;
pub mod checks;
pub mod measure;
pub mod obvhs_bridge;
pub mod rays;
