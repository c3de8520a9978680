//! [`RayQuery`] for the wide layouts: each query picks its kernel here, the single-ray walks
//! (`bvh4`, `bvh8`) or the packet kernel (`packet`), on the BVH's instruction set. Above both,
//! so neither kernel imports the other's entry points.

use super::packet::PacketQuery;
use super::packet::{any_rays_on, closest_rays_on};
use super::query::RayQuery;
use super::{bvh4, bvh8, BoxTest, Filter, Stats};
use crate::geometry::{Hit, Ray};
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
