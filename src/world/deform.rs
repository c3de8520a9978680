//! [`MovingTriangles`]: a deforming triangle mesh, its vertices given at two or more evenly
//! spaced times over the shutter (the same triangles in the same order at every step), and
//! one 8-wide BVH per time segment whose boxes move linearly over it (Embree's linear bounds).
//!
//! A ray at time `t` (clamped as [`Ray::shutter_time`] clamps it) falls in segment
//! `k = floor(t * (S - 1))` (the last for `t = 1`) at local time `u = t * (S - 1) - k`, and
//! meets each triangle at `u` between steps `k` and `k + 1`: every vertex `a * (1 - u) + b * u`
//! in f32 ([`MovingTriangles::triangle_at`]), tested as a static triangle is. Each node's
//! child boxes are taken where they are at `u` ([`Bvh8Ends`]): a triangle's box at step `k`
//! and at `k + 1`, padded for rounding, hold it at every time between, since its vertices
//! move on straight lines.

use super::error::WorldError;
use crate::builders::{build, BuildConfig, Builder};
use crate::geometry::{shutter, Aabb, Hit, PrimHit, Ray, Triangle};
use crate::isa::{Isa, Kernels};
use crate::layout::ends::{node_ends, pad_ends, Bvh8Ends};
use crate::layout::{bvh2::leaf_order, Bvh8, Footprint, Inputs};
use crate::primitive::Primitive;
use crate::traverse::bvh8::{walk, Ray8At};
use crate::traverse::dispatch::{self, LaneKernel};
use crate::traverse::lane8::F8;
use crate::traverse::query::ray_by_ray;
use crate::traverse::search::{offer, prim_hit};
use crate::traverse::{Ask, BoxTest, Filter, PacketQuery, RayQuery, Stats};
use glam::Vec3A;
use std::marker::PhantomData;

/// A deforming triangle mesh in a [`World`](super::World) (added by
/// [`WorldBuilder::add_moving_triangles`](super::WorldBuilder::add_moving_triangles)): its
/// triangles at `S >= 2` evenly spaced times, step `j` at time `j / (S - 1)`. A ray at time
/// `t` meets the triangles interpolated to `t` ([`MovingTriangles::triangle_at`]).
///
/// ```
/// use quiver_rt::glam::Vec3A;
/// use quiver_rt::{BuildOptions, Instance, Ray, RayQuery, Triangle, World};
/// let tri = |z: f32| Triangle::new(Vec3A::new(0.0, 0.0, z), Vec3A::new(1.0, 0.0, z), Vec3A::new(0.0, 1.0, z));
/// let mut b = World::builder();
/// // Sinks from z = 0 to z = -2 and comes back up to z = -1.
/// let g = b.add_moving_triangles(vec![vec![tri(0.0)], vec![tri(-2.0)], vec![tri(-1.0)]])?;
/// b.add_instance(Instance::of(g));
/// let world = b.build(&BuildOptions::default())?;
/// let ray = Ray::new(Vec3A::new(0.2, 0.2, 1.0), -Vec3A::Z);
/// let t_at = |time: f32| world.closest_hit(&ray.with_time(time)).map(|h| h.t);
/// assert_eq!((t_at(0.0), t_at(0.25), t_at(0.5), t_at(1.0)), (Some(1.0), Some(2.0), Some(3.0), Some(2.0)));
/// // Out of the shutter is its nearest end; NaN is time 0.
/// assert_eq!((t_at(-3.0), t_at(9.0), t_at(f32::NAN)), (Some(1.0), Some(2.0), Some(1.0)));
/// # Ok::<(), quiver_rt::WorldError>(())
/// ```
#[derive(Clone, Debug)]
pub struct MovingTriangles {
    /// `steps[j]`: the triangles at time `j / (S - 1)`, in input order.
    steps: Vec<Vec<Triangle>>,
    /// `segments[k]`: the BVH over the triangles between steps `k` and `k + 1`.
    segments: Vec<Segment>,
    /// The box around every step.
    bounds: Aabb,
}

/// One time segment's BVH: its tree over the triangles' boxes over the segment (what a
/// census of its nodes reads), and each node's child boxes at both of its ends (what the walk
/// reads).
#[derive(Clone, Debug)]
struct Segment {
    /// Nodes and the triangles' input indices in leaf order (`prim_ids`).
    bvh: Bvh8<TriIndex>,
    /// One per node: its children's boxes at the segment's start and their change to its end.
    ends: Vec<Bvh8Ends>,
    /// Each leaf slot's triangle at the segment's two steps, in leaf order: a leaf's
    /// triangles are read from one run of memory, not gathered from two input-order arrays.
    tris: Vec<[Triangle; 2]>,
}

/// A leaf slot of a segment's BVH, holding nothing: its triangle's input index is the
/// layout's `prim_ids` entry. The layout's own queries are never run on it (the walk is
/// [`MovingTriangles`]'), nor are its boxes asked for: the build takes them from the steps.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TriIndex;

impl Primitive for TriIndex {
    fn bounds(&self) -> Aabb {
        unreachable!("a moving triangle's box comes from its steps")
    }
    fn intersect(&self, _: &Ray) -> Option<PrimHit> {
        None
    }
}

/// Why `steps` cannot be a moving mesh, and the step at fault, if one is.
pub(super) fn check_steps(steps: &[Vec<Triangle>]) -> Result<(), (Option<usize>, &'static str)> {
    if steps.len() < 2 {
        return Err((None, "fewer than two time steps"));
    }
    if steps.len() > u32::MAX as usize || steps[0].len() >= u32::MAX as usize {
        return Err((None, "more than 2^32 - 2 steps or triangles"));
    }
    for (j, s) in steps.iter().enumerate() {
        if s.len() != steps[0].len() {
            return Err((Some(j), "a different number of triangles than step 0"));
        }
        if !s.iter().all(Triangle::is_finite) {
            return Err((Some(j), "a vertex that is not finite"));
        }
    }
    Ok(())
}

/// The segment a shutter time (in `[0, 1]`) falls in among `segments`, and the time in it.
#[inline(always)]
fn segment_at(segments: usize, time: f32) -> (usize, f32) {
    let x = time * segments as f32;
    // Through u32, as `Motion`'s segment (a cheaper conversion): `x` lies in [0, segments],
    // and `check_steps` keeps `segments` below 2^32.
    let k = (x as u32 as usize).min(segments - 1);
    (k, x - k as f32)
}

/// `a` and `b` interpolated to `u`, vertex by vertex: `a * (1 - u) + b * u`.
#[inline(always)]
fn lerp(a: &Triangle, b: &Triangle, u: f32) -> Triangle {
    let at = |p: Vec3A, q: Vec3A| p * (1.0 - u) + q * u;
    Triangle {
        v: [at(a.v[0], b.v[0]), at(a.v[1], b.v[1]), at(a.v[2], b.v[2])],
    }
}

impl MovingTriangles {
    /// The moving mesh of `steps` (checked by the caller, [`check_steps`]): one BVH per
    /// segment, on instruction set `isa`.
    pub(super) fn new(steps: Vec<Vec<Triangle>>, isa: Isa) -> MovingTriangles {
        let segments = (0..steps.len() - 1)
            .map(|k| Segment::new(&steps[k], &steps[k + 1], isa))
            .collect();
        MovingTriangles {
            bounds: bounds_of(&steps),
            steps,
            segments,
        }
    }

    /// The triangles at every step: `steps()[j]` at time `j / (steps().len() - 1)`.
    ///
    /// ```
    /// use quiver_rt::glam::Vec3A;
    /// use quiver_rt::world::Geometry;
    /// use quiver_rt::{BuildOptions, Triangle, World};
    /// let tri = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
    /// let mut b = World::builder();
    /// b.add_moving_triangles(vec![vec![tri], vec![tri]])?;
    /// let world = b.build(&BuildOptions::default())?;
    /// let Geometry::MovingTriangles(m) = &world.geometries()[0] else { unreachable!() };
    /// assert_eq!(m.steps(), &[vec![tri], vec![tri]]);
    /// # Ok::<(), quiver_rt::WorldError>(())
    /// ```
    pub fn steps(&self) -> &[Vec<Triangle>] {
        &self.steps
    }

    /// Triangles in the mesh (at each step).
    ///
    /// ```
    /// use quiver_rt::glam::Vec3A;
    /// use quiver_rt::world::Geometry;
    /// use quiver_rt::{Aabb, BuildOptions, Triangle, World};
    /// let tri = |z: f32| Triangle::new(Vec3A::new(0.0, 0.0, z), Vec3A::new(1.0, 0.0, z), Vec3A::new(0.0, 1.0, z));
    /// let mut b = World::builder();
    /// b.add_moving_triangles(vec![vec![tri(0.0); 3], vec![tri(-2.0); 3]])?;
    /// let world = b.build(&BuildOptions::default())?;
    /// let Geometry::MovingTriangles(m) = &world.geometries()[0] else { unreachable!() };
    /// assert_eq!((m.len(), m.is_empty()), (3, false));
    /// // Its box holds it all shutter long.
    /// assert_eq!(m.bounds(), Aabb::new(Vec3A::new(0.0, 0.0, -2.0), Vec3A::new(1.0, 1.0, 0.0)));
    /// // Its footprint counts both steps' triangles and its segment's nodes and ends.
    /// assert!(m.footprint().bytes > 2 * 3 * std::mem::size_of::<Triangle>() + 384);
    /// # Ok::<(), quiver_rt::WorldError>(())
    /// ```
    pub fn len(&self) -> usize {
        self.steps[0].len()
    }

    /// True for a mesh of no triangles (see [`MovingTriangles::len`]).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The box around every step's triangles, so around the mesh at every time (see
    /// [`MovingTriangles::len`]).
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Triangle `prim` at shutter time `time` (clamped as [`Ray::shutter_time`] clamps it):
    /// in segment `k = floor(t * (S - 1))` (the last for `t = 1`), at `u = t * (S - 1) - k`,
    /// each vertex `a * (1 - u) + b * u` of its vertices `a` at step `k` and `b` at `k + 1`,
    /// in f32. What a ray at that time is tested against. `None` for no such triangle.
    ///
    /// ```
    /// use quiver_rt::glam::Vec3A;
    /// use quiver_rt::world::Geometry;
    /// use quiver_rt::{BuildOptions, Triangle, World};
    /// let tri = |x: f32| Triangle::new(Vec3A::new(x, 0.0, 0.0), Vec3A::new(x + 1.0, 0.0, 0.0), Vec3A::new(x, 1.0, 0.0));
    /// let mut b = World::builder();
    /// b.add_moving_triangles(vec![vec![tri(0.0)], vec![tri(4.0)], vec![tri(0.0)]])?;
    /// let world = b.build(&BuildOptions::default())?;
    /// let Geometry::MovingTriangles(m) = &world.geometries()[0] else { unreachable!() };
    /// assert_eq!(m.triangle_at(0, 0.25), Some(tri(2.0)));
    /// assert_eq!(m.triangle_at(0, 0.5), Some(tri(4.0)));
    /// assert_eq!(m.triangle_at(0, 2.0), Some(tri(0.0)));
    /// assert_eq!(m.triangle_at(1, 0.5), None);
    /// # Ok::<(), quiver_rt::WorldError>(())
    /// ```
    pub fn triangle_at(&self, prim: u32, time: f32) -> Option<Triangle> {
        let (k, u) = segment_at(self.segments.len(), shutter(time));
        let (a, b) = (
            self.steps[k].get(prim as usize)?,
            &self.steps[k + 1][prim as usize],
        );
        Some(lerp(a, b, u))
    }

    /// The tree of the segment shutter time `time` (clamped as [`MovingTriangles::triangle_at`]
    /// clamps it) falls in: its nodes' boxes hold each triangle all segment long (they are
    /// the unions of its boxes at both ends), what a point query walks.
    pub(super) fn tree_at(&self, time: f32) -> &Bvh8<TriIndex> {
        &self.segments[segment_at(self.segments.len(), shutter(time)).0].bvh
    }

    /// The same mesh at new `steps` (checked by the caller: as many as it has, each of as
    /// many triangles): each segment's tree kept, its boxes at both ends computed afresh.
    pub(super) fn refit(&mut self, steps: Vec<Vec<Triangle>>) {
        for (k, s) in self.segments.iter_mut().enumerate() {
            s.refit(&steps[k], &steps[k + 1]);
        }
        self.bounds = bounds_of(&steps);
        self.steps = steps;
    }

    /// The same triangles with fresh trees (on instruction set `isa`).
    pub(super) fn rebuilt(&self, isa: Isa) -> MovingTriangles {
        MovingTriangles::new(self.steps.clone(), isa)
    }

    /// The instruction set its walks run on.
    fn kernels(&self) -> Kernels {
        self.segments[0].bvh.kernels
    }

    /// What its segments' nodes, ends and leaf-order triangles occupy, and the steps (kept
    /// for normals, refits and saving; see [`MovingTriangles::len`]). The ends count as node
    /// bytes.
    pub fn footprint(&self) -> Footprint {
        let steps: usize = self
            .steps
            .iter()
            .map(|s| std::mem::size_of_val(s.as_slice()))
            .sum();
        self.segments.iter().fold(
            Footprint {
                nodes: 0,
                node_bytes: 0,
                bytes: steps,
                kept: steps,
            },
            |f, s| {
                let b = s.bvh.footprint();
                let ends = std::mem::size_of_val(s.ends.as_slice());
                let tris = std::mem::size_of_val(s.tris.as_slice());
                Footprint {
                    nodes: f.nodes + b.nodes,
                    node_bytes: f.node_bytes + b.node_bytes + ends,
                    bytes: f.bytes + b.bytes + ends + tris,
                    kept: f.kept + b.kept,
                }
            },
        )
    }

    /// The segments' trees, for a census of the nodes walks can enter.
    pub(super) fn segment_trees(&self) -> impl Iterator<Item = &Bvh8<TriIndex>> {
        self.segments.iter().map(|s| &s.bvh)
    }

    /// The search `A` of `ray` (its `t_min` raised) in the mesh at the ray's time, improving
    /// `best`, on lanes `V`.
    #[inline(always)]
    fn search<V: F8, A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        cpu: V::Cpu,
        ray: &Ray,
        best: &mut Hit,
        stats: &mut S,
        filter: &mut F,
    ) {
        let (k, u) = segment_at(self.segments.len(), ray.shutter_time());
        let seg = &self.segments[k];
        if seg.bvh.prim_ids.is_empty() {
            return;
        }
        let boxes = Ray8At::<V>::new(cpu, &Ray { time: u, ..*ray }, &seg.ends);
        walk::<V, A, B, S, _>(
            &seg.bvh.nodes,
            &boxes,
            0,
            best.t,
            stats,
            #[inline(always)]
            |first, count, limit, stats| {
                let slots = first..first + count as usize;
                let (ids, tris) = (&seg.bvh.prim_ids[slots.clone()], &seg.tris[slots]);
                let found = test_leaf::<A, S, F>(ids, tris, u, ray, best, stats, filter);
                if A::ANY {
                    return found;
                }
                *limit = best.t;
                false
            },
            #[inline(always)]
            |_, _| {},
        );
    }
}

/// Tests the triangles `ids` (input indices; `tris` holds each at the segment's two steps) at
/// `u` for the search `A` at `best`, as a static leaf's are ([`prim_hit`], [`offer`]).
/// Returns true when `best` changed.
#[inline(always)]
fn test_leaf<A: Ask, S: Stats, F: Filter<Hit>>(
    ids: &[u32],
    tris: &[[Triangle; 2]],
    u: f32,
    ray: &Ray,
    best: &mut Hit,
    stats: &mut S,
    filter: &mut F,
) -> bool {
    let mut found = false;
    for (j, (&i, [a, b])) in ids.iter().zip(tris).enumerate() {
        let tri = lerp(a, b, u);
        // The interval up to the best hit so far (any hit searches the whole ray).
        let r = Ray {
            t_max: if A::ANY { ray.t_max } else { best.t },
            ..*ray
        };
        if let Some(h) = prim_hit(&tri, &r) {
            if offer::<A, F>(best, i, h, filter) {
                found = true;
                if A::ANY {
                    stats.prims(j as u32 + 1);
                    return true;
                }
            }
        }
    }
    stats.prims(ids.len() as u32);
    if !found {
        stats.empty_leaf();
    }
    found
}

/// The box around every triangle of every step.
fn bounds_of(steps: &[Vec<Triangle>]) -> Aabb {
    steps
        .iter()
        .flatten()
        .fold(Aabb::EMPTY, |b, t| b.union(&t.bounds()))
}

impl Segment {
    /// The BVH over the triangles moving from `from` to `to`: built over each one's box over
    /// the segment, its nodes' ends from each one's boxes at both steps.
    fn new(from: &[Triangle], to: &[Triangle], isa: Isa) -> Segment {
        let boxes: Vec<Aabb> = from
            .iter()
            .zip(to)
            .map(|(a, b)| a.bounds().union(&b.bounds()))
            .collect();
        let config = BuildConfig::default();
        let tree =
            build(&boxes, &config, Builder::Binned).expect("the default settings are in range");
        let indices = vec![TriIndex; from.len()];
        let inputs = Inputs::of(&tree, indices.len());
        let leaves = leaf_order(&tree, &indices).into();
        let bvh = Bvh8::from_leaf_prims(&tree, leaves, inputs, isa, &config);
        let mut s = Segment {
            bvh,
            ends: Vec::new(),
            tris: Vec::new(),
        };
        s.refit(from, to);
        s
    }

    /// Its nodes' ends computed for the triangles moving from `from` to `to` (the tree kept),
    /// and each node's boxes made the union of its ends' (which hold the triangles at every
    /// time of the segment), for the walks that read a node's static boxes (point queries, a
    /// census of the nodes).
    fn refit(&mut self, from: &[Triangle], to: &[Triangle]) {
        let ids = &self.bvh.prim_ids;
        self.tris = ids
            .iter()
            .map(|&i| [from[i as usize], to[i as usize]])
            .collect();
        self.ends = node_ends(&self.bvh.nodes, |slot| {
            let i = ids[slot] as usize;
            pad_ends([from[i].bounds(), to[i].bounds()])
        });
        for (n, e) in self.bvh.nodes.iter_mut().zip(&self.ends) {
            for r in 0..6 {
                for i in 0..8 {
                    let (a, d) = (e.start[r][i], e.delta[r][i]);
                    // An unused slot has no change: its inverted box stays.
                    n.planes[r][i] = match r < 3 {
                        true => a.min(a + d),
                        false => a.max(a + d),
                    };
                }
            }
        }
    }
}

/// One ray's query of a [`MovingTriangles`], as the kernel [`dispatch`] runs.
struct Trace<'a, A, B, S, F> {
    mesh: &'a MovingTriangles,
    ray: &'a Ray,
    stats: &'a mut S,
    filter: &'a mut F,
    ask: PhantomData<(A, B)>,
}

impl<A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>> LaneKernel for Trace<'_, A, B, S, F> {
    type Out = A::Answer<Hit>;

    #[inline(always)]
    fn run<V: F8, const FAR: bool>(self, cpu: V::Cpu) -> A::Answer<Hit> {
        let ray = &self.ray.raised_t_min();
        let mut best = Hit::none(ray.t_max);
        self.mesh
            .search::<V, A, B, S, F>(cpu, ray, &mut best, self.stats, self.filter);
        A::answer(best.found())
    }
}

/// Queried at each ray's time ([`Ray::shutter_time`]); packets ray by ray through the
/// single-ray walk (correct, not SIMD across rays).
impl RayQuery for MovingTriangles {
    type Hit = Hit;

    fn trace_with<A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> A::Answer<Hit> {
        let kernel = Trace::<A, B, S, F> {
            mesh: self,
            ray,
            stats,
            filter,
            ask: PhantomData,
        };
        dispatch::run(self.kernels(), false, kernel)
    }

    fn trace_packet_with<A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        query: PacketQuery<'_>,
        hits: &mut [A::Answer<Hit>],
        stats: &mut S,
        filter: &mut F,
    ) {
        ray_by_ray::<Self, A, B, S, F>(self, query, hits, stats, filter)
    }
}

impl WorldError {
    /// The error for geometry `geometry`'s steps, from [`check_steps`]'s answer.
    pub(super) fn steps(geometry: usize, (step, why): (Option<usize>, &'static str)) -> Self {
        WorldError::Steps {
            geometry,
            step,
            why,
        }
    }
}
