//! A scene's BVH with the right primitive type: all-triangle scenes take the pure triangle
//! path, scenes with analytic shapes (SPD curve mode) the mixed [`Prim`] path. Hits report
//! the primitive; [`SceneBvh::object_of`] maps it back to the scene object (and material).
//!
//! ```
//! use quiver_scenes::accel::SceneBvh;
//! use quiver::build::{BuildConfig, Builder};
//! use quiver::{Layout};
//! use quiver_scenes::{scene::Scene};
//! let scene = Scene::load("tetra3").unwrap();
//! let (bvh, _) = SceneBvh::build(&scene, &BuildConfig::default(), Builder::Binned, Layout::Bvh4Dfs);
//! let hit = bvh.closest_hit(&scene.camera.ray(0.0, 0.0)).unwrap();
//! assert!((bvh.object_of(hit.prim) as usize) < scene.objects.len());
//! ```

use quiver::build::{BuildConfig, BuildTree, Builder};
use quiver::geometry::{Hit, Ray, TriHit, Triangle};
use quiver::layout::{Bvh, Layout};
use crate::primitive::{PatchTriangle, Prim};
use crate::scene::Scene;
use quiver::traverse::{ConservativeBoxes, Counters, PacketMode, Stats};
use glam::Vec3A;

/// The BVH of one scene.
#[derive(Clone, Debug)]
pub struct SceneBvh {
    kind: Kind,
    /// For each primitive (input order), the index of its scene object.
    owner: Vec<u32>,
}

#[derive(Clone, Debug)]
enum Kind {
    /// Triangles and, where they came from patches, their vertex normals.
    Triangles(Bvh<Triangle>, Vec<Triangle>, Vec<Option<[Vec3A; 3]>>),
    Mixed(Bvh<Prim>, Vec<Prim>),
}

macro_rules! each {
    ($self:expr, $b:ident => $e:expr) => {
        match &$self.kind {
            Kind::Triangles($b, ..) => $e,
            Kind::Mixed($b, _) => $e,
        }
    };
}

impl SceneBvh {
    /// Builds over the scene's primitives: triangles when every object is one, the mixed
    /// path otherwise.
    pub fn build(
        scene: &Scene,
        config: &BuildConfig,
        builder: Builder,
        layout: Layout,
    ) -> (SceneBvh, BuildTree) {
        if scene.is_all_triangles() {
            Self::build_triangles(scene, config, builder, layout)
        } else {
            let (prims, owner) = scene.prims();
            let (bvh, tree) = Bvh::build(&prims, config, builder, layout);
            (
                SceneBvh {
                    kind: Kind::Mixed(bvh, prims),
                    owner,
                },
                tree,
            )
        }
    }

    /// Builds over triangles only (patch mode): polygons triangulated, patches kept as
    /// triangles with their vertex normals for smooth shading, spheres and cones tessellated.
    pub fn build_triangles(
        scene: &Scene,
        config: &BuildConfig,
        builder: Builder,
        layout: Layout,
    ) -> (SceneBvh, BuildTree) {
        let (tris, owner, normals) = scene.triangles_with_normals();
        let (bvh, tree) = Bvh::build(&tris, config, builder, layout);
        (
            SceneBvh {
                kind: Kind::Triangles(bvh, tris, normals),
                owner,
            },
            tree,
        )
    }

    /// Primitives in the BVH.
    pub fn primitives(&self) -> usize {
        self.owner.len()
    }

    /// True for the pure triangle path.
    pub fn is_triangles(&self) -> bool {
        matches!(self.kind, Kind::Triangles(..))
    }

    /// The scene object primitive `prim` came from.
    pub fn object_of(&self, prim: u32) -> u32 {
        self.owner[prim as usize]
    }

    /// Shading normal at a hit (see [`Prim::normal`]).
    pub fn normal(&self, ray: &Ray, hit: &Hit) -> Vec3A {
        let th = TriHit {
            t: hit.t,
            u: hit.u,
            v: hit.v,
        };
        match &self.kind {
            Kind::Triangles(_, tris, normals) => {
                let tri = tris[hit.prim as usize];
                match normals[hit.prim as usize] {
                    Some(normals) => Prim::Patch(PatchTriangle { tri, normals }).normal(ray, &th),
                    None => Prim::Triangle(tri).normal(ray, &th),
                }
            }
            Kind::Mixed(_, prims) => prims[hit.prim as usize].normal(ray, &th),
        }
    }

    /// Node slots.
    pub fn nodes(&self) -> usize {
        each!(self, b => b.nodes())
    }

    /// Bytes of the node array.
    pub fn node_bytes(&self) -> usize {
        each!(self, b => b.node_bytes())
    }

    /// Bytes of node and leaf data.
    pub fn bytes(&self) -> usize {
        each!(self, b => b.bytes())
    }

    /// Nearest hit.
    pub fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        each!(self, b => b.closest_hit(ray))
    }

    /// Whether anything is hit.
    pub fn any_hit(&self, ray: &Ray) -> bool {
        each!(self, b => b.any_hit(ray))
    }

    /// Nearest hit, counting.
    pub fn closest_hit_counted(&self, ray: &Ray, c: &mut Counters) -> Option<Hit> {
        each!(self, b => b.closest_hit_counted(ray, c))
    }

    /// Any hit, counting.
    pub fn any_hit_counted(&self, ray: &Ray, c: &mut Counters) -> bool {
        each!(self, b => b.any_hit_counted(ray, c))
    }

    /// Nearest hits of `rays` in packets (see [`Bvh::closest_hit_packet_with`]); only rays
    /// flagged in `active` are traced.
    ///
    /// # Panics
    /// When `hits` or `active` differ in length from `rays`.
    pub fn closest_hit_packet_with<S: Stats>(
        &self,
        rays: &[Ray],
        active: Option<&[bool]>,
        mode: PacketMode,
        hits: &mut [Option<Hit>],
        stats: &mut S,
    ) {
        each!(self, b => b.closest_hit_packet_with::<ConservativeBoxes, S>(rays, active, mode, hits, stats))
    }

    /// Any-hit answers of `rays` in packets (see [`Bvh::any_hit_packet_with`]).
    ///
    /// # Panics
    /// When `occluded` or `active` differ in length from `rays`.
    pub fn any_hit_packet_with<S: Stats>(
        &self,
        rays: &[Ray],
        active: Option<&[bool]>,
        mode: PacketMode,
        occluded: &mut [bool],
        stats: &mut S,
    ) {
        each!(self, b => b.any_hit_packet_with::<ConservativeBoxes, S>(rays, active, mode, occluded, stats))
    }
}
