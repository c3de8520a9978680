//! A world's single-ray queries: the 8-wide walk over the top level, and at each instance it
//! enters (its mask shares a bit with the ray's), the ray brought into object space and the
//! instance's geometry asked with the nearest hit so far as its limit.

use super::{Geometry, Placed, World, WorldHit};
use crate::geometry::{Hit, Ray};
use crate::isa::Kernels;
use crate::primitive::Primitive;
use crate::traverse::bvh8::{walk, Ray8};
use crate::traverse::lane8::F8;
use crate::traverse::wide::OneRay;
use crate::traverse::{BoxTest, Filter, PacketQuery, RayQuery, Stats};
use wide::f32x8;

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
            instance: self.instance,
            geometry: self.geometry,
            prim: h.prim,
            u: h.u,
            v: h.v,
        }
    }

    /// Makes the geometry's hit `h` the world's `best` where it beats it (see
    /// [`WorldHit::is_beaten_by`]); says whether it did.
    #[inline(always)]
    pub(super) fn improve(&self, best: &mut WorldHit, h: &Hit) -> bool {
        let better = best.is_beaten_by(h.t, self.instance);
        if better {
            *best = self.hit(h);
        }
        better
    }
}

impl<P: Primitive> RayQuery for Geometry<P> {
    type Hit = Hit;

    #[inline]
    fn closest_hit_with<B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> Option<Hit> {
        match self {
            Geometry::Triangles(b, _) => b.closest_hit_with::<B, S, F>(ray, stats, filter),
            Geometry::Prims(b, _) => b.closest_hit_with::<B, S, F>(ray, stats, filter),
        }
    }

    #[inline]
    fn any_hit_with<B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        match self {
            Geometry::Triangles(b, _) => b.any_hit_with::<B, S, F>(ray, stats, filter),
            Geometry::Prims(b, _) => b.any_hit_with::<B, S, F>(ray, stats, filter),
        }
    }

    fn closest_hit_packet_with<B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        query: PacketQuery<'_>,
        hits: &mut [Option<Hit>],
        stats: &mut S,
        filter: &mut F,
    ) {
        match self {
            Geometry::Triangles(b, _) => {
                b.closest_hit_packet_with::<B, S, F>(query, hits, stats, filter)
            }
            Geometry::Prims(b, _) => {
                b.closest_hit_packet_with::<B, S, F>(query, hits, stats, filter)
            }
        }
    }

    fn any_hit_packet_with<B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        query: PacketQuery<'_>,
        occluded: &mut [bool],
        stats: &mut S,
        filter: &mut F,
    ) {
        match self {
            Geometry::Triangles(b, _) => {
                b.any_hit_packet_with::<B, S, F>(query, occluded, stats, filter)
            }
            Geometry::Prims(b, _) => {
                b.any_hit_packet_with::<B, S, F>(query, occluded, stats, filter)
            }
        }
    }
}

impl<P: Primitive> Geometry<P> {
    /// `ask` of one ray in object space on the world's lanes (see [`crate::Bvh`]'s
    /// `one_ray`): false, with nothing done, where the geometry's layout takes the ray the
    /// usual way.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn one_ray<V: F8, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        kernels: Kernels,
        cpu: V::Cpu,
        ray: &Ray,
        ask: OneRay<'_>,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        match self {
            Geometry::Triangles(b, _) => {
                b.one_ray::<V, B, S, F>(kernels, cpu, ray, ask, stats, filter)
            }
            Geometry::Prims(b, _) => b.one_ray::<V, B, S, F>(kernels, cpu, ray, ask, stats, filter),
        }
    }
}

impl<P: Primitive> World<P> {
    /// Instance `p`'s closest hit along `ray`, improving `best`: the geometry's walk inlined
    /// on the world's lanes where its layout allows (an 8-wide BVH on the world's kernels),
    /// else through its query.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn closest_in<V: F8, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        &self,
        cpu: V::Cpu,
        p: &Placed,
        ray: &Ray,
        best: &mut WorldHit,
        stats: &mut S,
        filter: &mut F,
    ) {
        if ray.mask & p.mask == 0 {
            return;
        }
        let local = p.local(ray, best.t);
        let g = &self.geometries[p.geometry as usize];
        let mut f = InInstance {
            filter,
            instance: p.instance,
            geometry: p.geometry,
        };
        let mut h = Hit::none(local.t_max);
        let ask = OneRay::Closest(&mut h);
        let found = if g.one_ray::<V, B, S, _>(self.top.kernels, cpu, &local, ask, stats, &mut f) {
            h.found()
        } else {
            g.closest_hit_with::<B, S, _>(&local, stats, &mut f)
        };
        if let Some(h) = found {
            f.improve(best, &h);
        }
    }

    /// Whether instance `p` blocks `ray` (the geometry's walk inlined as in
    /// [`World::closest_in`]).
    #[inline(always)]
    pub(super) fn any_in<V: F8, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        &self,
        cpu: V::Cpu,
        p: &Placed,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        if ray.mask & p.mask == 0 {
            return false;
        }
        let local = p.local(ray, ray.t_max);
        let g = &self.geometries[p.geometry as usize];
        let mut f = InInstance {
            filter,
            instance: p.instance,
            geometry: p.geometry,
        };
        let mut hit = false;
        let ask = OneRay::Any(&mut hit);
        if g.one_ray::<V, B, S, _>(self.top.kernels, cpu, &local, ask, stats, &mut f) {
            return hit;
        }
        g.any_hit_with::<B, S, _>(&local, stats, &mut f)
    }

    /// The closest hit in the top-level subtree of inner node `root`, improving `best`.
    #[inline(always)]
    pub(super) fn closest_from<V: F8, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        &self,
        cpu: V::Cpu,
        ray: &Ray,
        root: usize,
        best: &mut WorldHit,
        stats: &mut S,
        filter: &mut F,
    ) {
        let top = &self.top;
        let r8 = Ray8::<V>::new(cpu, ray);
        walk::<V, B, S, _, true>(
            &top.nodes,
            &r8,
            root,
            best.t,
            stats,
            #[inline(always)]
            |first, count, limit, stats| {
                stats.prims(count);
                for p in &top.prims[first..first + count as usize] {
                    self.closest_in::<V, B, S, F>(cpu, p, ray, best, stats, filter);
                }
                *limit = best.t;
                false
            },
            |_, _| {},
        );
    }

    /// Whether anything in the top-level subtree of inner node `root` blocks `ray`.
    #[inline(always)]
    pub(super) fn any_from<V: F8, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        &self,
        cpu: V::Cpu,
        ray: &Ray,
        root: usize,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        let top = &self.top;
        let r8 = Ray8::<V>::new(cpu, ray);
        let mut hit = false;
        walk::<V, B, S, _, false>(
            &top.nodes,
            &r8,
            root,
            ray.t_max,
            stats,
            #[inline(always)]
            |first, count, _, stats| {
                stats.prims(count);
                let leaf = &top.prims[first..first + count as usize];
                hit = leaf
                    .iter()
                    .any(|p| self.any_in::<V, B, S, F>(cpu, p, ray, stats, filter));
                hit
            },
            |_, _| {},
        );
        hit
    }

    /// Whether the top level has a root node to walk (an empty world has none worth it).
    #[inline(always)]
    fn walkable(&self) -> bool {
        !self.top.prims.is_empty()
    }

    #[inline(always)]
    fn closest<V: F8, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        &self,
        cpu: V::Cpu,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> Option<WorldHit> {
        let ray = &ray.raised_t_min();
        let mut best = WorldHit::none(ray.t_max);
        if self.walkable() {
            self.closest_from::<V, B, S, F>(cpu, ray, 0, &mut best, stats, filter);
        }
        best.found()
    }

    #[inline(always)]
    fn any<V: F8, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        &self,
        cpu: V::Cpu,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        self.walkable() && self.any_from::<V, B, S, F>(cpu, &ray.raised_t_min(), 0, stats, filter)
    }
}

impl<P: Primitive> RayQuery for World<P> {
    type Hit = WorldHit;

    fn closest_hit_with<B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> Option<WorldHit> {
        match self.top.kernels {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `cpu` proves the CPU has AVX2 and FMA (only detection makes one).
            Kernels::Avx2(cpu) => unsafe {
                avx2::closest::<P, B, S, F>(self, cpu, ray, stats, filter)
            },
            _ => self.closest::<f32x8, B, S, F>((), ray, stats, filter),
        }
    }

    fn any_hit_with<B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        match self.top.kernels {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as above.
            Kernels::Avx2(cpu) => unsafe { avx2::any::<P, B, S, F>(self, cpu, ray, stats, filter) },
            _ => self.any::<f32x8, B, S, F>((), ray, stats, filter),
        }
    }

    fn closest_hit_packet_with<B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        &self,
        query: PacketQuery<'_>,
        hits: &mut [Option<WorldHit>],
        stats: &mut S,
        filter: &mut F,
    ) {
        super::packet::closest_rays::<P, B, S, F>(self, query, hits, stats, filter)
    }

    fn any_hit_packet_with<B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        &self,
        query: PacketQuery<'_>,
        occluded: &mut [bool],
        stats: &mut S,
        filter: &mut F,
    ) {
        super::packet::any_rays::<P, B, S, F>(self, query, occluded, stats, filter)
    }
}

/// The top-level walks on AVX2 lanes (the geometries' own queries pick their kernels).
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::*;
    use crate::isa::Avx2Cpu;
    use crate::traverse::lane8::Avx;

    /// # Safety
    /// The CPU must support AVX2 and FMA (as `cpu` proves).
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn closest<P: Primitive, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        world: &World<P>,
        cpu: Avx2Cpu,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> Option<WorldHit> {
        world.closest::<Avx, B, S, F>(cpu, ray, stats, filter)
    }

    /// # Safety
    /// The CPU must support AVX2 and FMA (as `cpu` proves).
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn any<P: Primitive, B: BoxTest, S: Stats, F: Filter<WorldHit>>(
        world: &World<P>,
        cpu: Avx2Cpu,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        world.any::<Avx, B, S, F>(cpu, ray, stats, filter)
    }
}
