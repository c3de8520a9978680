//! quiver: ray shooting on CPUs.
//!
//! The pipeline, one module per stage:
//! [`scene`] (geometry sources) → [`build`] (SAH trees over primitive bounds) →
//! [`layout`] (compact node arrays) → [`traverse`] (closest-hit and any-hit queries).
//! [`primitive`] holds the SPD's analytic shapes; [`accel`] picks the triangle or mixed path
//! for a scene; [`measure`] times ray sets for reports and benchmarks.
//!
//! ```
//! use quiver::{scene::Scene, build::{BuildConfig, Builder}, Bvh2};
//! let scene = Scene::load("tetra3").unwrap();
//! let tris = scene.triangles();
//! let (bvh, tree) = Bvh2::build(&tris, &BuildConfig::default(), Builder::Binned);
//! let ray = scene.camera.ray(0.1, -0.2);
//! assert_eq!(bvh.closest_hit(&ray), quiver::reference::closest_hit(&tris, &ray));
//! assert!(tree.sah_cost(&BuildConfig::default()) > 0.0);
//! ```

pub mod accel;
pub mod accuracy;
pub mod build;
pub mod checks;
pub mod geometry;
pub mod intersect;
pub mod layout;
pub mod measure;
#[cfg(feature = "cli")]
pub mod obvhs_bridge;
pub mod primitive;
pub mod rays;
pub mod render;
pub mod rng;
pub mod scene;
pub mod traverse;

pub use geometry::{Aabb, Hit, Primitive, Ray, TriHit, Triangle};
pub use layout::{Bvh, Bvh2, Layout};
pub use traverse::reference;
