//! quiver-scenes: what quiver traces. Eric Haines' Standard Procedural Databases (all ten
//! generators, curve and patch mode), NFF, OBJ, PLY and glTF files, a seeded triangle soup; the SPD's
//! analytic shapes as quiver primitives; a scene's BVH ([`accel::SceneBvh`]); and the
//! Whitted renderer that follows the SPD testing procedure ([`render`]).
//!
//! ```
//! use quiver_rt::{BuildOptions, RayQuery};
//! use quiver_scenes::{accel::SceneBvh, Scene};
//! let scene = Scene::load("balls2").unwrap(); // 91 spheres and a floor polygon
//! let bvh = SceneBvh::build(&scene, &BuildOptions::default());
//! let ray = scene.camera.ray(0.0, 0.0);
//! let hit = bvh.closest_hit(&ray).unwrap();
//! let object = &scene.objects[bvh.object_of(hit.prim) as usize];
//! assert!(bvh.normal(&ray, &hit).is_normalized());
//! # let _ = object;
//! ```
//!
//! Mesh files are read by quiver's own readers ([`scene::obj`], [`scene::ply`],
//! [`scene::gltf`]), errors naming file and line, or file and element or JSON item.

#![warn(missing_docs)]

pub mod accel;
pub mod instanced;
pub mod primitive;
pub mod render;
pub mod rng;
pub mod scene;

pub use scene::{Camera, Scene};
