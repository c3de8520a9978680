//! [`RayQuery`] for the wide layouts: each query picks its kernel here, the single-ray walks
//! (`bvh4`, `bvh8`) or the packet kernel (`packet`), on the BVH's instruction set. Above both,
//! so neither kernel imports the other's entry points.

use super::lane8::F8;
use super::packet::{any_rays_on, closest_rays_on, in_lanes, InLanes, PacketQuery, RayPacket};
use super::query::RayQuery;
use super::{bvh4, bvh8, BoxTest, Filter, Stats};
use crate::geometry::{Hit, Ray};
use crate::isa::Kernels;
use crate::layout::{Bvh4, Bvh8, Bvh8Node, Node4};
use crate::primitive::Primitive;

impl<P: Primitive, N: Node4> RayQuery for Bvh4<P, N> {
    type Hit = Hit;

    fn closest_hit_with<B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> Option<Hit> {
        if self.far.any() {
            return closest4_far::<N, B, P, S, F>(self, ray, stats, filter);
        }
        closest4::<N, B, P, S, F>(self, ray, stats, filter)
    }

    fn any_hit_with<B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        if self.far.any() {
            return any4_far::<N, B, P, S, F>(self, ray, stats, filter);
        }
        any4::<N, B, P, S, F>(self, ray, stats, filter)
    }

    fn closest_hit_packet_with<B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        query: PacketQuery<'_>,
        hits: &mut [Option<Hit>],
        stats: &mut S,
        filter: &mut F,
    ) {
        let leaves = self.leaves();
        closest_rays_on::<N, B, P, S, F>(
            self.kernels,
            &self.nodes,
            &leaves,
            query,
            hits,
            stats,
            filter,
        )
    }

    fn any_hit_packet_with<B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        query: PacketQuery<'_>,
        occluded: &mut [bool],
        stats: &mut S,
        filter: &mut F,
    ) {
        let leaves = self.leaves();
        any_rays_on::<N, B, P, S, F>(
            self.kernels,
            &self.nodes,
            &leaves,
            query,
            occluded,
            stats,
            filter,
        )
    }
}

impl<P: Primitive> RayQuery for Bvh8<P> {
    type Hit = Hit;

    fn closest_hit_with<B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> Option<Hit> {
        bvh8::closest_on::<B, P, S, F>(self.kernels, self, ray, stats, filter)
    }

    fn any_hit_with<B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        bvh8::any_on::<B, P, S, F>(self.kernels, self, ray, stats, filter)
    }

    fn closest_hit_packet_with<B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        query: PacketQuery<'_>,
        hits: &mut [Option<Hit>],
        stats: &mut S,
        filter: &mut F,
    ) {
        let leaves = self.leaves();
        closest_rays_on::<Bvh8Node, B, P, S, F>(
            self.kernels,
            &self.nodes,
            &leaves,
            query,
            hits,
            stats,
            filter,
        )
    }

    fn any_hit_packet_with<B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        query: PacketQuery<'_>,
        occluded: &mut [bool],
        stats: &mut S,
        filter: &mut F,
    ) {
        let leaves = self.leaves();
        any_rays_on::<Bvh8Node, B, P, S, F>(
            self.kernels,
            &self.nodes,
            &leaves,
            query,
            occluded,
            stats,
            filter,
        )
    }
}

impl<P: Primitive, N: Node4> Bvh4<P, N> {
    /// `ask` of a packet already in lanes, on the caller's lanes `V`, which run `kernels`:
    /// false, with nothing done, where this BVH runs other kernels (ask it the usual way).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn in_lanes<V: F8, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        kernels: Kernels,
        cpu: V::Cpu,
        pk: &mut RayPacket,
        ask: InLanes<'_>,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        let ours = self.kernels == kernels;
        if ours {
            let leaves = self.leaves();
            in_lanes::<N, V, B, P, S, F>(cpu, &self.nodes, &leaves, pk, ask, stats, filter);
        }
        ours
    }
}

/// What one ray already in a BVH's units asks of it on the caller's lanes (a world's ray
/// entering an instance): its closest hit, improving the record (whose `t` is the limit), or
/// whether it hits anything (setting the flag).
pub(crate) enum OneRay<'a> {
    Closest(&'a mut Hit),
    Any(&'a mut bool),
}

impl<P: Primitive> Bvh8<P> {
    /// `ask` of `ray` (its `t_min` raised already) on the caller's lanes `V`, which run
    /// `kernels`: the 8-wide walk inlined into the caller's, without this BVH's dispatch and
    /// call. False, with nothing done, where this BVH runs other kernels. (Kept apart from
    /// `in_lanes`: one method over both asks measured 3% more instructions on instanced
    /// single rays.)
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn one_ray<V: F8, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        kernels: Kernels,
        cpu: V::Cpu,
        ray: &Ray,
        ask: OneRay<'_>,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        let ours = self.kernels == kernels;
        if ours && !self.nodes.is_empty() {
            let leaves = self.leaves();
            match ask {
                OneRay::Closest(best) => bvh8::closest_from::<V, B, P, S, F>(
                    cpu,
                    &self.nodes,
                    &leaves,
                    ray,
                    0,
                    best,
                    stats,
                    filter,
                ),
                OneRay::Any(hit) => {
                    *hit = bvh8::any_from::<V, B, P, S, F>(
                        cpu,
                        &self.nodes,
                        &leaves,
                        ray,
                        0,
                        stats,
                        filter,
                    )
                }
            }
        }
        ours
    }

    /// As [`Bvh4::in_lanes`].
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn in_lanes<V: F8, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        kernels: Kernels,
        cpu: V::Cpu,
        pk: &mut RayPacket,
        ask: InLanes<'_>,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        let ours = self.kernels == kernels;
        if ours {
            let leaves = self.leaves();
            in_lanes::<Bvh8Node, V, B, P, S, F>(cpu, &self.nodes, &leaves, pk, ask, stats, filter);
        }
        ours
    }
}

/// The 4-wide walks over a layout without far groups, in functions of their own: with the far
/// path's call beside it, the inlined walk kept its SIMD state across that call (5% more
/// instructions on teapot12's closest-hit rays under callgrind).
#[inline(never)]
fn closest4<N: Node4, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    bvh: &Bvh4<P, N>,
    ray: &Ray,
    stats: &mut S,
    filter: &mut F,
) -> Option<Hit> {
    bvh4::closest::<N, B, P, S, F, false>(&bvh.nodes, &bvh.leaves(), ray, stats, filter)
}

#[inline(never)]
fn any4<N: Node4, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    bvh: &Bvh4<P, N>,
    ray: &Ray,
    stats: &mut S,
    filter: &mut F,
) -> bool {
    bvh4::any::<N, B, P, S, F, false>(&bvh.nodes, &bvh.leaves(), ray, stats, filter)
}

/// The 4-wide walks over a layout holding far groups ([`crate::layout::Tri4`]): their own
/// functions, so the other layouts' walks carry no trace of that path.
#[cold]
#[inline(never)]
fn closest4_far<N: Node4, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    bvh: &Bvh4<P, N>,
    ray: &Ray,
    stats: &mut S,
    filter: &mut F,
) -> Option<Hit> {
    bvh4::closest::<N, B, P, S, F, true>(&bvh.nodes, &bvh.leaves(), ray, stats, filter)
}

#[cold]
#[inline(never)]
fn any4_far<N: Node4, B: BoxTest, P: Primitive, S: Stats, F: Filter<Hit>>(
    bvh: &Bvh4<P, N>,
    ray: &Ray,
    stats: &mut S,
    filter: &mut F,
) -> bool {
    bvh4::any::<N, B, P, S, F, true>(&bvh.nodes, &bvh.leaves(), ray, stats, filter)
}
