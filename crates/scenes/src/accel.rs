//! A scene's BVH with the right primitive type: all-triangle scenes take the pure triangle
//! path, scenes with analytic shapes (SPD curve mode) the mixed [`Prim`] path. Hits report
//! the primitive; [`SceneBvh::object_of`] maps it back to the scene object (and material).
//!
//! ```
//! use quiver::{BuildOptions, RayQuery};
//! use quiver_scenes::{accel::SceneBvh, Scene};
//! let scene = Scene::load("tetra3").unwrap();
//! let bvh = SceneBvh::build(&scene, &BuildOptions::default());
//! let hit = bvh.closest_hit(&scene.camera.ray(0.0, 0.0)).unwrap();
//! assert!((bvh.object_of(hit.prim) as usize) < scene.objects.len());
//! ```

use crate::primitive::{PatchTriangle, Prim};
use crate::scene::Scene;
use glam::Vec3A;
use quiver::build::BuildTree;
use quiver::layout::Footprint;
use quiver::traverse::{BoxTest, PacketMode, RayQuery, Stats};
use quiver::{BuildOptions, Bvh, Hit, PrimHit, Ray, Triangle};

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

impl SceneBvh {
    /// Builds over the scene's primitives: triangles when every object is one, the mixed
    /// path otherwise.
    pub fn build(scene: &Scene, options: &BuildOptions) -> SceneBvh {
        Self::build_with_tree(scene, options).0
    }

    /// [`SceneBvh::build`], also returning the build tree.
    pub fn build_with_tree(scene: &Scene, options: &BuildOptions) -> (SceneBvh, BuildTree) {
        if scene.is_all_triangles() {
            Self::build_triangles_with_tree(scene, options)
        } else {
            let (prims, owner) = scene.prims();
            let (bvh, tree) = options.build_with_tree(&prims);
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
    pub fn build_triangles(scene: &Scene, options: &BuildOptions) -> SceneBvh {
        Self::build_triangles_with_tree(scene, options).0
    }

    /// [`SceneBvh::build_triangles`], also returning the build tree.
    pub fn build_triangles_with_tree(
        scene: &Scene,
        options: &BuildOptions,
    ) -> (SceneBvh, BuildTree) {
        let (tris, owner, normals) = scene.triangles_with_normals();
        let (bvh, tree) = options.build_with_tree(&tris);
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
        let th = PrimHit {
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

    /// What the nodes and leaves occupy.
    pub fn footprint(&self) -> Footprint {
        match &self.kind {
            Kind::Triangles(b, ..) => b.footprint(),
            Kind::Mixed(b, _) => b.footprint(),
        }
    }
}

impl RayQuery for SceneBvh {
    #[inline]
    fn closest_hit_with<B: BoxTest, S: Stats>(&self, ray: &Ray, stats: &mut S) -> Option<Hit> {
        match &self.kind {
            Kind::Triangles(b, ..) => b.closest_hit_with::<B, S>(ray, stats),
            Kind::Mixed(b, _) => b.closest_hit_with::<B, S>(ray, stats),
        }
    }

    #[inline]
    fn any_hit_with<B: BoxTest, S: Stats>(&self, ray: &Ray, stats: &mut S) -> bool {
        match &self.kind {
            Kind::Triangles(b, ..) => b.any_hit_with::<B, S>(ray, stats),
            Kind::Mixed(b, _) => b.any_hit_with::<B, S>(ray, stats),
        }
    }

    fn closest_hit_packet_with<B: BoxTest, S: Stats>(
        &self,
        rays: &[Ray],
        active: Option<&[bool]>,
        mode: PacketMode,
        hits: &mut [Option<Hit>],
        stats: &mut S,
    ) {
        match &self.kind {
            Kind::Triangles(b, ..) => {
                b.closest_hit_packet_with::<B, S>(rays, active, mode, hits, stats)
            }
            Kind::Mixed(b, _) => b.closest_hit_packet_with::<B, S>(rays, active, mode, hits, stats),
        }
    }

    fn any_hit_packet_with<B: BoxTest, S: Stats>(
        &self,
        rays: &[Ray],
        active: Option<&[bool]>,
        mode: PacketMode,
        occluded: &mut [bool],
        stats: &mut S,
    ) {
        match &self.kind {
            Kind::Triangles(b, ..) => {
                b.any_hit_packet_with::<B, S>(rays, active, mode, occluded, stats)
            }
            Kind::Mixed(b, _) => b.any_hit_packet_with::<B, S>(rays, active, mode, occluded, stats),
        }
    }
}
