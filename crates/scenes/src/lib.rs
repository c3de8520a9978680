//! quiver-scenes: scenes for quiver.

pub mod accel;
pub mod primitive;
pub mod render;
pub mod rng;
pub mod scene;

pub use scene::{Camera, Scene};
