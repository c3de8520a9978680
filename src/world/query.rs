//! A world's single-ray queries: the 8-wide walk over the top level, and at each instance it
//! enters (its mask shares a bit with the ray's), the ray brought into object space and the
//! instance's geometry asked with the nearest hit so far as its limit.

use super::filter::Both;
use super::{Geometry, GeometryId, InstanceId, InstanceLeaf, World, WorldHit};
use crate::geometry::{Hit, Ray};
use crate::isa::Kernels;
use crate::primitive::Primitive;
use crate::traverse::bvh8::{walk, Enter8, Ray8, Ray8At};
use crate::traverse::dispatch::{self, LaneKernel};
use crate::traverse::lane8::F8;
use crate::traverse::{Ask, BoxTest, Filter, PacketQuery, RayQuery, Stats};
use glam::Affine3A;
use std::marker::PhantomData;

/// The caller's filter, asked about a geometry's candidates as world hits of one instance.
pub(super) struct InInstance<'f, F> {
    pub(super) filter: &'f mut F,
    pub(super) instance: u32,
    pub(super) geometry: u32,
}

impl<F: Filter<WorldHit>> Filter<Hit> for InInstance<'_, F> {
    const ACTIVE: bool = F::ACTIVE;
    #[inline(always)]
    fn accept(&mut self, h: &Hit) -> bool {
        self.filter.accept(&self.hit(h))
    }
}

impl<F> InInstance<'_, F> {
    /// A geometry's hit as this instance's world hit.
    #[inline(always)]
    pub(super) fn hit(&self, h: &Hit) -> WorldHit {
        WorldHit {
            t: h.t,
            instance: InstanceId(self.instance),
            geometry: GeometryId(self.geometry),
            prim: h.prim,
            u: h.u,
            v: h.v,
        }
    }

    /// Makes the geometry's hit `h` the world's `best` where the search `A` keeps it (any
    /// hit: always; closest hit: where it beats `best`, see [`WorldHit::is_beaten_by`]); says
    /// whether it did.
    #[inline(always)]
    pub(super) fn improve<A: Ask>(&self, best: &mut WorldHit, h: &Hit) -> bool {
        let better = A::ANY || best.is_beaten_by(h.t, self.instance);
        if better {
            *best = self.hit(h);
        }
        better
    }
}

impl<P: Primitive> RayQuery for Geometry<P> {
    type Hit = Hit;

    #[inline]
    fn trace_with<A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> A::Answer<Hit> {
        match self {
            Geometry::Triangles(b, _) => b.trace_with::<A, B, S, F>(ray, stats, filter),
            Geometry::Prims(b, _) => b.trace_with::<A, B, S, F>(ray, stats, filter),
            Geometry::MovingTriangles(m) => m.trace_with::<A, B, S, F>(ray, stats, filter),
        }
    }

    fn trace_packet_with<A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        query: PacketQuery<'_>,
        hits: &mut [A::Answer<Hit>],
        stats: &mut S,
        filter: &mut F,
    ) {
        match self {
            Geometry::Triangles(b, _) => {
                b.trace_packet_with::<A, B, S, F>(query, hits, stats, filter)
            }
            Geometry::Prims(b, _) => b.trace_packet_with::<A, B, S, F>(query, hits, stats, filter),
            Geometry::MovingTriangles(m) => {
                m.trace_packet_with::<A, B, S, F>(query, hits, stats, filter)
            }
        }
    }
}

impl<P: Primitive> Geometry<P> {
    /// The search `A` of one ray in object space on the world's lanes (see [`crate::Bvh`]'s
    /// `one_ray`): false, with nothing done, where the geometry's layout takes the ray the
    /// usual way.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn one_ray<V: F8, A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        kernels: Kernels,
        cpu: V::Cpu,
        ray: &Ray,
        best: &mut Hit,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        match self {
            Geometry::Triangles(b, _) => {
                b.one_ray::<V, A, B, S, F>(kernels, cpu, ray, best, stats, filter)
            }
            Geometry::Prims(b, _) => {
                b.one_ray::<V, A, B, S, F>(kernels, cpu, ray, best, stats, filter)
            }
            // Through its own query, at the ray's time.
            Geometry::MovingTriangles(_) => false,
        }
    }
}

impl<P: Primitive> World<P> {
    /// The search `A` of `ray` in instance `p`, improving `best`: the geometry's walk inlined
    /// on the world's lanes where its layout allows (an 8-wide BVH on the world's kernels),
    /// else through its query. Returns true when `best` changed.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn search_in<V, A, B, S, F, const MOVING: bool>(
        &self,
        cpu: V::Cpu,
        p: &InstanceLeaf,
        ray: &Ray,
        best: &mut WorldHit,
        stats: &mut S,
        filter: &mut F,
    ) -> bool
    where
        V: F8,
        A: Ask,
        B: BoxTest,
        S: Stats,
        F: Filter<WorldHit>,
    {
        if ray.mask & p.mask == 0 {
            return false;
        }
        // A moving instance's transform at the ray's time is made out of line; its geometry
        // is then walked as a static instance's is.
        let local = match MOVING && p.moving {
            true => match self.moving_local(p, ray, best.t) {
                Some(local) => local,
                None => return false,
            },
            false => p.local(ray, best.t),
        };
        if self.own_filter(p.geometry).is_some() {
            return self.search_local::<A, B, S, F>(p, &local, best, stats, filter);
        }
        let g = &self.geometries[p.geometry as usize];
        let mut f = InInstance {
            filter,
            instance: p.instance,
            geometry: p.geometry,
        };
        let mut h = Hit::none(local.t_max);
        let kernels = self.top.kernels;
        let found = if g.one_ray::<V, A, B, S, _>(kernels, cpu, &local, &mut h, stats, &mut f) {
            h.found()
        } else {
            // Any hit keeps no record of the hit, so a stand-in marks the instance's.
            let stand_in = Hit { prim: 0, ..h };
            A::into_hit(g.trace_with::<A, B, S, _>(&local, stats, &mut f), stand_in)
        };
        match found {
            Some(h) => f.improve::<A>(best, &h),
            None => false,
        }
    }

    /// `ray` in moving instance `p`'s object space at the ray's time, searching up to
    /// `t_max`; `None` where the motion's transform then has no inverse.
    #[inline(always)]
    pub(super) fn moving_local(&self, p: &InstanceLeaf, ray: &Ray, t_max: f32) -> Option<Ray> {
        let to_object = self.moving_to_object(p.instance, ray.shutter_time())?;
        Some(super::top::into_object(&to_object, ray, t_max))
    }

    /// Moving instance `instance`'s world-to-object transform at `time`. Inlined: only the
    /// single-ray walks of a world with moving instances hold it (`MOVING`), and there it
    /// runs on the kernels' instruction set with the transform kept in registers (3.6% fewer
    /// instructions on lattice6's moving rays than the call out of line).
    #[inline(always)]
    fn moving_to_object(&self, instance: u32, time: f32) -> Option<Affine3A> {
        super::instance::motion_of(&self.motions, instance as usize)?.to_object(time)
    }

    /// `ray` in instance `p`'s object space (at the ray's time, if `p` moves), searching up
    /// to `t_max`. For the paths that test `p.moving` as they run (packets, whose code also
    /// serves worlds where nothing moves): a moving instance's transform is made out of line
    /// there, so it costs their static instances nothing.
    #[inline(always)]
    pub(super) fn local_ray(&self, p: &InstanceLeaf, ray: &Ray, t_max: f32) -> Option<Ray> {
        match p.moving {
            true => self.moving_local_cold(p, ray, t_max),
            false => Some(p.local(ray, t_max)),
        }
    }

    /// [`World::moving_local`], out of line and cold (see [`World::local_ray`]).
    #[cold]
    #[inline(never)]
    fn moving_local_cold(&self, p: &InstanceLeaf, ray: &Ray, t_max: f32) -> Option<Ray> {
        self.moving_local(p, ray, t_max)
    }

    /// The search `A` of `local` (a ray in instance `p`'s object space) in `p`'s geometry
    /// through the geometry's query, not inlined here: for an instance that moves, or whose
    /// geometry has its own filter (asked after the caller's), so the inlined walks of the
    /// rest are not compiled twice. Improves `best`; returns true when it did.
    #[inline(always)]
    pub(super) fn search_local<A: Ask, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        &self,
        p: &InstanceLeaf,
        local: &Ray,
        best: &mut WorldHit,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        match self.own_filter(p.geometry) {
            Some(own) => {
                let mut both = Both { query: filter, own };
                self.search_through::<A, B, S, _>(p, local, best, stats, &mut both)
            }
            None => self.search_through::<A, B, S, F>(p, local, best, stats, filter),
        }
    }

    /// [`World::search_local`] with the filter `filter` (the caller's, or both).
    #[inline(always)]
    fn search_through<A: Ask, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        &self,
        p: &InstanceLeaf,
        local: &Ray,
        best: &mut WorldHit,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        let g = &self.geometries[p.geometry as usize];
        let mut f = InInstance {
            filter,
            instance: p.instance,
            geometry: p.geometry,
        };
        // Any hit keeps no record of the hit, so a stand-in marks the instance's.
        let stand_in = Hit {
            prim: 0,
            ..Hit::none(local.t_max)
        };
        match A::into_hit(g.trace_with::<A, B, S, _>(local, stats, &mut f), stand_in) {
            Some(h) => f.improve::<A>(best, &h),
            None => false,
        }
    }

    /// The search `A` in the instances of top-level leaf `first..first + count`, improving
    /// `best`; any hit stops at the first instance that keeps one. Returns true when `best`
    /// changed.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn search_leaf<V, A, B, S, F, const MOVING: bool>(
        &self,
        cpu: V::Cpu,
        first: usize,
        count: usize,
        ray: &Ray,
        best: &mut WorldHit,
        stats: &mut S,
        filter: &mut F,
    ) -> bool
    where
        V: F8,
        A: Ask,
        B: BoxTest,
        S: Stats,
        F: Filter<WorldHit>,
    {
        let mut found = false;
        for i in first..first + count {
            let p = &self.top.prims[i];
            found |= self.search_in::<V, A, B, S, F, MOVING>(cpu, p, ray, best, stats, filter);
            if A::ANY && found {
                break;
            }
        }
        found
    }

    /// The search `A` in the top-level subtree of inner node `root`, improving `best`.
    #[inline(always)]
    pub(super) fn search_from<V: F8, A: Ask, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        &self,
        cpu: V::Cpu,
        ray: &Ray,
        root: usize,
        best: &mut WorldHit,
        stats: &mut S,
        filter: &mut F,
    ) {
        // As `trace_with` picks it (the packets' rays that go alone come here).
        match self.motions.is_empty() {
            true => self.walk_at::<V, A, B, S, F, false>(cpu, ray, root, best, stats, filter),
            false => self.walk_at::<V, A, B, S, F, true>(cpu, ray, root, best, stats, filter),
        }
    }

    /// [`World::search_from`] in a world with moving instances if `MOVING`: its walk then
    /// meets the nodes' boxes where they are at the ray's time.
    #[inline(always)]
    fn walk_at<V, A, B, S, F, const MOVING: bool>(
        &self,
        cpu: V::Cpu,
        ray: &Ray,
        root: usize,
        best: &mut WorldHit,
        stats: &mut S,
        filter: &mut F,
    ) where
        V: F8,
        A: Ask,
        B: BoxTest,
        S: Stats,
        F: Filter<WorldHit>,
    {
        match MOVING {
            true => {
                let boxes = Ray8At::<V>::new(cpu, ray, &self.ends.nodes);
                self.walk_top::<V, A, B, S, F, true>(cpu, &boxes, ray, root, best, stats, filter)
            }
            false => {
                let boxes = Ray8::<V>::new(cpu, ray);
                self.walk_top::<V, A, B, S, F, false>(cpu, &boxes, ray, root, best, stats, filter)
            }
        }
    }

    /// [`World::search_from`] meeting the nodes' boxes through `boxes`, testing for moving
    /// instances if `MOVING`.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn walk_top<V, A, B, S, F, const MOVING: bool>(
        &self,
        cpu: V::Cpu,
        boxes: &impl Enter8<V>,
        ray: &Ray,
        root: usize,
        best: &mut WorldHit,
        stats: &mut S,
        filter: &mut F,
    ) where
        V: F8,
        A: Ask,
        B: BoxTest,
        S: Stats,
        F: Filter<WorldHit>,
    {
        walk::<V, A, B, S, _>(
            &self.top.nodes,
            boxes,
            root,
            best.t,
            stats,
            #[inline(always)]
            |first, count, limit, stats| {
                stats.prims(count);
                let found = self.search_leaf::<V, A, B, S, F, MOVING>(
                    cpu,
                    first,
                    count as usize,
                    ray,
                    best,
                    stats,
                    filter,
                );
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

    /// Whether the top level has a root node to walk (an empty world has none worth it).
    #[inline(always)]
    pub(super) fn walkable(&self) -> bool {
        !self.top.prims.is_empty()
    }
}

/// One ray's query of a [`World`], as the kernel [`dispatch`] runs on the top level's lanes
/// (the geometries' own queries pick their kernels), testing for moving instances if `MOVING`.
struct Trace<'a, P, A, B, S, F, const MOVING: bool> {
    world: &'a World<P>,
    ray: &'a Ray,
    stats: &'a mut S,
    filter: &'a mut F,
    ask: PhantomData<(A, B)>,
}

impl<P, A, B, S, F, const MOVING: bool> LaneKernel for Trace<'_, P, A, B, S, F, MOVING>
where
    P: Primitive,
    A: Ask,
    B: BoxTest,
    S: Stats,
    F: Filter<WorldHit>,
{
    type Out = A::Answer<WorldHit>;

    #[inline(always)]
    fn run<V: F8, const FAR: bool>(self, cpu: V::Cpu) -> A::Answer<WorldHit> {
        let ray = &self.ray.raised_t_min();
        let mut best = WorldHit::none(ray.t_max);
        if self.world.walkable() {
            self.world.walk_at::<V, A, B, S, F, MOVING>(
                cpu,
                ray,
                0,
                &mut best,
                self.stats,
                self.filter,
            );
        }
        A::answer(best.found())
    }
}

impl<P: Primitive> World<P> {
    /// One ray's query on the top level's kernels, testing for moving instances if `MOVING`.
    #[inline(always)]
    fn trace_on<A: Ask, B: BoxTest, S: Stats, F: Filter<WorldHit>, const MOVING: bool>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> A::Answer<WorldHit> {
        let kernel = Trace::<P, A, B, S, F, MOVING> {
            world: self,
            ray,
            stats,
            filter,
            ask: PhantomData,
        };
        dispatch::run(self.top.kernels, false, kernel)
    }
}

impl<P: Primitive> RayQuery for World<P> {
    type Hit = WorldHit;

    fn trace_with<A: Ask, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> A::Answer<WorldHit> {
        // Picked before the kernels: a world where nothing moves runs code with no motion in
        // it, not even the test of each instance's flag (a world that once had a moving
        // instance keeps the test).
        match self.motions.is_empty() {
            true => self.trace_on::<A, B, S, F, false>(ray, stats, filter),
            false => self.trace_on::<A, B, S, F, true>(ray, stats, filter),
        }
    }

    fn trace_packet_with<A: Ask, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        &self,
        query: PacketQuery<'_>,
        hits: &mut [A::Answer<WorldHit>],
        stats: &mut S,
        filter: &mut F,
    ) {
        super::packet::trace_rays::<P, A, B, S, F>(self, query, hits, stats, filter)
    }
}
