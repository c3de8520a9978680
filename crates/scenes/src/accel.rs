//! A scene's BVH with the right primitive type: all-triangle scenes take the pure triangle
//! path, scenes with analytic shapes (SPD curve mode) the mixed [`Prim`] path. Hits report
//! the primitive; [`SceneBvh::object_of`] maps it back to the scene object (and material).
//!
//! ```
//! use quiver_rt::{BuildOptions, RayQuery};
//! use quiver_scenes::{accel::SceneBvh, Scene};
//! let scene = Scene::load("tetra3").unwrap();
//! let bvh = SceneBvh::build(&scene, &BuildOptions::default()).unwrap();
//! let hit = bvh.closest_hit(&scene.camera.ray(0.0, 0.0)).unwrap();
//! assert!((bvh.object_of(hit.prim) as usize) < scene.objects.len());
//! ```

use crate::instanced::Instanced;
use crate::primitive::{PatchTriangle, Prim};
use crate::scene::Scene;
use glam::Vec3A;
use quiver_rt::builders::BuildTree;
use quiver_rt::layout::Footprint;
use quiver_rt::predict::{NodeVisit, WalkNodes};
use quiver_rt::traverse::NoStats;
use quiver_rt::traverse::{Ask, BoxTest, ClosestHit, Filter, PacketQuery, RayQuery, Stats};
use quiver_rt::{BuildError, BuildOptions, Bvh, Hit, PrimHit, Primitive, Ray, Triangle};
use std::sync::Mutex;

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
    /// Spheres and cones as instances of unit shapes (see [`Instanced`]).
    Instanced(Box<Instanced>),
    /// A BVH that also records every query it answers (see [`SceneBvh::recording`]).
    Record(Box<SceneBvh>, Recording),
}

/// The queries recorded so far; a clone copies them.
#[derive(Debug, Default)]
struct Recording(Mutex<Vec<(usize, Traced)>>);

impl Recording {
    fn list(&self) -> std::sync::MutexGuard<'_, Vec<(usize, Traced)>> {
        // A panic while recording leaves whole entries behind: the list is usable.
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }
}

impl Clone for Recording {
    fn clone(&self) -> Self {
        Recording(Mutex::new(self.list().clone()))
    }
}

/// One query a recording BVH answered, for timing the same rays apart from the application
/// that asked for them (Havran's split of the running time, see [`SceneBvh::recording`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Traced {
    /// The ray.
    pub ray: Ray,
    /// Whether it was an any-hit (shadow) query; closest hit otherwise.
    pub any: bool,
    /// The answer: a hit (closest hit) or an occluder (any hit) was found.
    pub found: bool,
    /// The primitive hit (any hit: the nearest blocker, which a closest-hit search may round
    /// away where the any-hit walk still admits one), if any.
    pub hit: Option<u32>,
}

impl SceneBvh {
    /// Builds over the scene's primitives: triangles when every object is one, the mixed
    /// path otherwise.
    ///
    /// # Errors
    /// [`BuildError`] for a setting of `options` out of range.
    pub fn build(scene: &Scene, options: &BuildOptions) -> Result<SceneBvh, BuildError> {
        Ok(Self::build_with_tree(scene, options)?.0)
    }

    /// [`SceneBvh::build`], also returning the build tree.
    ///
    /// # Errors
    /// As [`SceneBvh::build`].
    pub fn build_with_tree(
        scene: &Scene,
        options: &BuildOptions,
    ) -> Result<(SceneBvh, BuildTree), BuildError> {
        if scene.is_all_triangles() {
            Self::build_triangles_with_tree(scene, options)
        } else {
            let (prims, owner) = scene.prims();
            let (bvh, tree) = Bvh::build_with_tree(&prims, options)?;
            let kind = Kind::Mixed(bvh, prims);
            Ok((SceneBvh { kind, owner }, tree))
        }
    }

    /// Builds over triangles only (patch mode): polygons triangulated, patches kept as
    /// triangles with their vertex normals for smooth shading, spheres and cones tessellated.
    ///
    /// # Errors
    /// As [`SceneBvh::build`].
    pub fn build_triangles(scene: &Scene, options: &BuildOptions) -> Result<SceneBvh, BuildError> {
        Ok(Self::build_triangles_with_tree(scene, options)?.0)
    }

    /// [`SceneBvh::build_triangles`], also returning the build tree.
    ///
    /// # Errors
    /// As [`SceneBvh::build`].
    pub fn build_triangles_with_tree(
        scene: &Scene,
        options: &BuildOptions,
    ) -> Result<(SceneBvh, BuildTree), BuildError> {
        let (tris, owner, normals) = scene.triangles_with_normals();
        let (bvh, tree) = Bvh::build_with_tree(&tris, options)?;
        let kind = Kind::Triangles(bvh, tris, normals);
        Ok((SceneBvh { kind, owner }, tree))
    }

    /// The scene (in curve mode) in patch mode at `resolution`, with its spheres and cones
    /// as instances of unit shapes ([`Instanced`]): the same surfaces as
    /// [`SceneBvh::build_triangles`] over [`Scene::into_patches`] (up to the placements'
    /// rounding), with hits numbered alike.
    ///
    /// # Errors
    /// As [`Instanced::build`].
    pub fn build_instanced(
        scene: &Scene,
        resolution: u32,
        options: &BuildOptions,
    ) -> Result<SceneBvh, quiver_rt::WorldError> {
        Ok(SceneBvh {
            kind: Kind::Instanced(Box::new(Instanced::build(scene, resolution, options)?)),
            owner: Vec::new(),
        })
    }

    /// [`SceneBvh::build_instanced`] with every placed sphere and cone moving by `motion`
    /// ([`Instanced::build_moving`]): a scene for motion blur, whose rays see the shapes where
    /// they are at each ray's time.
    ///
    /// # Errors
    /// As [`Instanced::build_moving`].
    pub fn build_instanced_moving(
        scene: &Scene,
        resolution: u32,
        options: &BuildOptions,
        motion: &dyn Fn(u32, glam::Affine3A) -> quiver_rt::Motion,
    ) -> Result<SceneBvh, quiver_rt::WorldError> {
        let moving = Instanced::build_moving(scene, resolution, options, motion)?;
        Ok(SceneBvh {
            kind: Kind::Instanced(Box::new(moving)),
            owner: Vec::new(),
        })
    }

    /// Primitives in the BVH (the flattened count for an instanced scene).
    pub fn primitives(&self) -> usize {
        match &self.kind {
            Kind::Instanced(i) => i.primitives() as usize,
            Kind::Record(inner, _) => inner.primitives(),
            _ => self.owner.len(),
        }
    }

    /// True for the pure triangle path.
    pub fn is_triangles(&self) -> bool {
        match &self.kind {
            Kind::Record(inner, _) => inner.is_triangles(),
            kind => matches!(kind, Kind::Triangles(..)),
        }
    }

    /// The scene object primitive `prim` came from.
    pub fn object_of(&self, prim: u32) -> u32 {
        match &self.kind {
            Kind::Instanced(i) => i.object_of(prim),
            Kind::Record(inner, _) => inner.object_of(prim),
            _ => self.owner[prim as usize],
        }
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
            Kind::Instanced(i) => i.normal(ray, hit),
            Kind::Record(inner, _) => inner.normal(ray, hit),
        }
    }

    /// What the nodes and leaves occupy.
    pub fn footprint(&self) -> Footprint {
        match &self.kind {
            Kind::Triangles(b, ..) => b.footprint(),
            Kind::Mixed(b, _) => b.footprint(),
            Kind::Instanced(i) => i.footprint(),
            Kind::Record(inner, _) => inner.footprint(),
        }
    }

    /// This BVH, also recording every query it answers, each worker thread's in the order it
    /// asked them (so a render band's rays stay in the band's order): Havran's ideal algorithm reads stored answers in
    /// sequence, and the recorded rays traced on their own time the ray shooting apart from
    /// the application. Queries go ray by ray and take a lock each: a recording run is for
    /// counting, not for timing.
    ///
    /// ```
    /// use quiver_rt::{BuildOptions, RayQuery};
    /// use quiver_scenes::{accel::SceneBvh, Scene};
    /// let scene = Scene::load("tetra3").unwrap();
    /// let rec = SceneBvh::build(&scene, &BuildOptions::default()).unwrap().recording();
    /// let ray = scene.camera.ray(0.0, 0.0);
    /// let hit = rec.closest_hit(&ray);
    /// let traced = rec.recorded();
    /// assert_eq!(traced.len(), 1);
    /// assert_eq!(traced[0].hit, hit.map(|h| h.prim));
    /// // The ideal algorithm's one test finds the same hit.
    /// assert_eq!(rec.intersect_one(&ray, traced[0].hit.unwrap()).map(|h| h.t), hit.map(|h| h.t));
    /// ```
    pub fn recording(self) -> SceneBvh {
        let owner = self.owner.clone();
        SceneBvh {
            kind: Kind::Record(Box::new(self), Recording::default()),
            owner,
        }
    }

    /// The queries a [`SceneBvh::recording`] answered so far, in order; empty for other BVHs.
    pub fn recorded(&self) -> Vec<Traced> {
        match &self.kind {
            Kind::Record(_, rec) => {
                // Each worker's queries together, in the order it asked them: threads record
                // into one list, and interleaved they would lose the coherence of a band.
                let mut list = rec.list().clone();
                list.sort_by_key(|&(thread, _)| thread);
                list.into_iter().map(|(_, t)| t).collect()
            }
            _ => Vec::new(),
        }
    }

    /// The BVH a recording wraps (itself for others): the one to time the recorded rays on.
    pub fn unrecorded(&self) -> &SceneBvh {
        match &self.kind {
            Kind::Record(inner, _) => inner,
            _ => self,
        }
    }

    /// Primitive `prim`'s own test against `ray`: the one test Havran's ideal algorithm makes
    /// for a ray that hits.
    pub fn intersect_one(&self, ray: &Ray, prim: u32) -> Option<PrimHit> {
        match &self.kind {
            Kind::Triangles(_, tris, _) => tris[prim as usize].intersect(ray),
            Kind::Mixed(_, prims) => prims[prim as usize].intersect(ray),
            Kind::Instanced(i) => i.intersect_one(ray, prim),
            Kind::Record(inner, _) => inner.intersect_one(ray, prim),
        }
    }

    fn record(&self, t: Traced) {
        if let Kind::Record(_, rec) = &self.kind {
            rec.list()
                .push((rayon::current_thread_index().unwrap_or(0), t));
        }
    }
}

impl WalkNodes for SceneBvh {
    /// The traversed layout's nodes (see `quiver_rt::predict`).
    fn walk_nodes(&self, f: &mut dyn FnMut(NodeVisit)) {
        match &self.kind {
            Kind::Triangles(b, ..) => b.walk_nodes(f),
            Kind::Mixed(b, _) => b.walk_nodes(f),
            Kind::Instanced(i) => i.world().walk_nodes(f),
            Kind::Record(inner, _) => inner.walk_nodes(f),
        }
    }
}

impl RayQuery for SceneBvh {
    type Hit = Hit;

    #[inline]
    fn trace_with<A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> A::Answer<Hit> {
        match &self.kind {
            Kind::Triangles(b, ..) => b.trace_with::<A, B, S, F>(ray, stats, filter),
            Kind::Mixed(b, _) => b.trace_with::<A, B, S, F>(ray, stats, filter),
            Kind::Instanced(i) => i.trace_with::<A, B, S, F>(ray, stats, filter),
            Kind::Record(inner, _) => {
                let answer = inner.trace_with::<A, B, S, F>(ray, stats, filter);
                let found = A::is_hit(&answer);
                // The ideal algorithm tests one blocker: the nearest, found without counting
                // (and a closest hit is its own nearest).
                let nearest = if !found {
                    None
                } else if A::ANY {
                    inner.trace_with::<ClosestHit, B, _, F>(ray, &mut NoStats, filter)
                } else {
                    // A closest-hit answer names its hit; the stand-in is never used.
                    let stand_in = Hit {
                        t: 0.0,
                        prim: u32::MAX,
                        u: 0.0,
                        v: 0.0,
                    };
                    A::into_hit(answer, stand_in)
                };
                self.record(Traced {
                    ray: *ray,
                    any: A::ANY,
                    found,
                    hit: nearest.map(|h| h.prim),
                });
                answer
            }
        }
    }

    fn trace_packet_with<A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        query: PacketQuery<'_>,
        hits: &mut [A::Answer<Hit>],
        stats: &mut S,
        filter: &mut F,
    ) {
        match &self.kind {
            Kind::Triangles(b, ..) => b.trace_packet_with::<A, B, S, F>(query, hits, stats, filter),
            Kind::Mixed(b, _) => b.trace_packet_with::<A, B, S, F>(query, hits, stats, filter),
            Kind::Instanced(i) => i.trace_packet_with::<A, B, S, F>(query, hits, stats, filter),
            Kind::Record(..) => {
                for (i, (r, h)) in query.rays.iter().zip(hits.iter_mut()).enumerate() {
                    if query.active.is_none_or(|a| a[i]) {
                        *h = self.trace_with::<A, B, S, F>(r, stats, filter);
                    }
                }
            }
        }
    }
}
