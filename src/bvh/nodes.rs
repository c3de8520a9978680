//! The layout a [`super::Bvh`] holds, chosen at run time: [`Laid`], one variant per layout
//! family, inside [`Nodes`], which adds [`Scaled`] for a BVH built in a scaled frame; built
//! from a [`Layout`] name by [`lay_out`], queried through one `match` per method. The one place
//! the choice lives.

use crate::builders::{BuildConfig, BuildTree};
use crate::frame::{Back, Frame};
use crate::geometry::{Aabb, Hit, Ray};
use crate::isa::{Isa, Kernels};
use crate::layout::{
    Bvh2, Bvh2Mapping, Bvh4, Bvh4Mapping, Bvh8, Footprint, Layout, LeafPrims, QBvh4,
};
use crate::primitive::Primitive;
use crate::traverse::lane8::F8;
use crate::traverse::packet::{InLanes, RayPacket};
use crate::traverse::wide::OneRay;
use crate::traverse::{BoxTest, Filter, PacketQuery, RayQuery, Stats};

/// The nodes and leaves of one [`Layout`].
#[derive(Clone, Debug)]
pub(crate) enum Laid<P> {
    /// Binary nodes.
    Bvh2(Bvh2<P>),
    /// 4-wide exact nodes.
    Bvh4(Bvh4<P>),
    /// 4-wide quantized nodes.
    QBvh4(QBvh4<P>),
    /// 8-wide exact nodes.
    Bvh8(Bvh8<P>),
}

/// A BVH's layout as built: in the caller's units, or in a frame scaled by a power of two for
/// a scene far from unit size (see [`Primitive::scaled`]). Scaled is a variant of its own, so
/// that unscaled BVHs pay nothing for it, and holds a [`Laid`], never another frame.
#[derive(Clone, Debug)]
pub(crate) enum Nodes<P> {
    /// In the caller's units.
    Plain(Laid<P>),
    /// In a scaled frame.
    Scaled(Box<Scaled<P>>),
}

/// Nodes and primitives in a frame scaled by a power of two, and the frame.
#[derive(Clone, Debug)]
pub(crate) struct Scaled<P> {
    pub(crate) frame: Frame,
    pub(crate) nodes: Laid<P>,
}

impl<P> Nodes<P> {
    /// The nodes of the layout itself, out of any scaled frame, and `b` (world units) in
    /// their frame.
    pub(crate) fn unframed(&self, b: &Aabb) -> (&Laid<P>, Aabb) {
        match self {
            Nodes::Scaled(s) => (&s.nodes, s.frame.aabb(b)),
            Nodes::Plain(l) => (l, *b),
        }
    }
}

impl<P> Laid<P> {
    /// These nodes, built in `frame`.
    pub(crate) fn framed(self, frame: Frame) -> Nodes<P> {
        if frame.is_identity() {
            Nodes::Plain(self)
        } else {
            Nodes::Scaled(Box::new(Scaled { frame, nodes: self }))
        }
    }
}

impl<P: Primitive> Laid<P> {
    fn isa(&self) -> Isa {
        match self {
            Laid::Bvh8(b) => b.isa(),
            Laid::Bvh4(b) => b.isa(),
            Laid::QBvh4(b) => b.isa(),
            Laid::Bvh2(_) => Isa::Portable,
        }
    }

    fn with_isa(self, isa: Isa) -> Self {
        match self {
            Laid::Bvh8(b) => Laid::Bvh8(b.with_isa(isa)),
            Laid::Bvh4(b) => Laid::Bvh4(b.with_isa(isa)),
            Laid::QBvh4(b) => Laid::QBvh4(b.with_isa(isa)),
            other => other,
        }
    }

    fn footprint(&self) -> Footprint {
        match self {
            Laid::Bvh2(b) => b.footprint(),
            Laid::Bvh4(b) => b.footprint(),
            Laid::QBvh4(b) => b.footprint(),
            Laid::Bvh8(b) => b.footprint(),
        }
    }
}

impl<P: Primitive> Nodes<P> {
    pub(crate) fn isa(&self) -> Isa {
        self.unframed(&Aabb::EMPTY).0.isa()
    }

    pub(crate) fn with_isa(self, isa: Isa) -> Self {
        match self {
            Nodes::Plain(l) => Nodes::Plain(l.with_isa(isa)),
            Nodes::Scaled(s) => {
                let Scaled { frame, nodes } = *s;
                nodes.with_isa(isa).framed(frame)
            }
        }
    }

    pub(crate) fn footprint(&self) -> Footprint {
        self.unframed(&Aabb::EMPTY).0.footprint()
    }
}

impl<P: Primitive> Nodes<P> {
    /// `ask` of one ray on the caller's lanes (see [`Bvh8::one_ray`]): the 8-wide layout in
    /// the caller's units; false, with nothing done, for the others (asked the usual way).
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
        match self {
            Nodes::Plain(Laid::Bvh8(b)) => {
                b.one_ray::<V, B, S, F>(kernels, cpu, ray, ask, stats, filter)
            }
            _ => false,
        }
    }

    /// `ask` of a packet already in lanes (see [`Bvh8::in_lanes`]): the wide layouts in the
    /// caller's units; false, with nothing done, for binary nodes, a scaled frame (whose rays
    /// must be brought into it first) or other kernels.
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
        match self {
            Nodes::Plain(Laid::Bvh8(b)) => {
                b.in_lanes::<V, B, S, F>(kernels, cpu, pk, ask, stats, filter)
            }
            Nodes::Plain(Laid::Bvh4(b)) => {
                b.in_lanes::<V, B, S, F>(kernels, cpu, pk, ask, stats, filter)
            }
            Nodes::Plain(Laid::QBvh4(b)) => {
                b.in_lanes::<V, B, S, F>(kernels, cpu, pk, ask, stats, filter)
            }
            Nodes::Plain(Laid::Bvh2(_)) | Nodes::Scaled(_) => false,
        }
    }
}

/// Lays out a checked `tree` as `layout` over `prims` (in the tree's leaf order, or read
/// through it): the one place a layout name becomes nodes.
pub(crate) fn lay_out<P: Primitive>(
    layout: Layout,
    tree: &BuildTree,
    prims: LeafPrims<P>,
    isa: Isa,
    config: &BuildConfig,
) -> Laid<P> {
    let bvh2 = match layout {
        Layout::Bvh2Dfs => Bvh2Mapping::DepthFirst,
        Layout::Bvh2Bfs => Bvh2Mapping::BreadthFirst,
        Layout::Bvh2Shuffled => Bvh2Mapping::Shuffled,
        Layout::Bvh2Subtree => Bvh2Mapping::Subtree,
        Layout::Bvh2SubtreePage => Bvh2Mapping::SubtreePage,
        Layout::Bvh2Compact => Bvh2Mapping::Compact,
        Layout::Bvh2CompactPage => Bvh2Mapping::CompactPage,
        Layout::Bvh4Dfs => {
            return Laid::Bvh4(Bvh4::from_leaf_prims(
                tree,
                prims,
                Bvh4Mapping::DepthFirst,
                isa,
            ))
        }
        Layout::Bvh4Subtree => {
            return Laid::Bvh4(Bvh4::from_leaf_prims(
                tree,
                prims,
                Bvh4Mapping::Subtree,
                isa,
            ))
        }
        Layout::Bvh4Quant => {
            return Laid::QBvh4(QBvh4::from_leaf_prims(
                tree,
                prims,
                Bvh4Mapping::DepthFirst,
                isa,
            ))
        }
        Layout::Bvh8Dfs => return Laid::Bvh8(Bvh8::from_leaf_prims(tree, prims, isa, config)),
    };
    Laid::Bvh2(Bvh2::from_leaf_prims(
        tree,
        prims.into_ordered(&tree.prim_indices),
        bvh2,
    ))
}

impl<P: Primitive> RayQuery for Laid<P> {
    type Hit = Hit;

    #[inline(always)]
    fn closest_hit_with<B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> Option<Hit> {
        match self {
            Laid::Bvh2(b) => b.closest_hit_with::<B, S, F>(ray, stats, filter),
            Laid::Bvh4(b) => b.closest_hit_with::<B, S, F>(ray, stats, filter),
            Laid::QBvh4(b) => b.closest_hit_with::<B, S, F>(ray, stats, filter),
            Laid::Bvh8(b) => b.closest_hit_with::<B, S, F>(ray, stats, filter),
        }
    }

    #[inline(always)]
    fn any_hit_with<B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        match self {
            Laid::Bvh2(b) => b.any_hit_with::<B, S, F>(ray, stats, filter),
            Laid::Bvh4(b) => b.any_hit_with::<B, S, F>(ray, stats, filter),
            Laid::QBvh4(b) => b.any_hit_with::<B, S, F>(ray, stats, filter),
            Laid::Bvh8(b) => b.any_hit_with::<B, S, F>(ray, stats, filter),
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
            Laid::Bvh2(b) => b.closest_hit_packet_with::<B, S, F>(query, hits, stats, filter),
            Laid::Bvh4(b) => b.closest_hit_packet_with::<B, S, F>(query, hits, stats, filter),
            Laid::QBvh4(b) => b.closest_hit_packet_with::<B, S, F>(query, hits, stats, filter),
            Laid::Bvh8(b) => b.closest_hit_packet_with::<B, S, F>(query, hits, stats, filter),
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
            Laid::Bvh2(b) => b.any_hit_packet_with::<B, S, F>(query, occluded, stats, filter),
            Laid::Bvh4(b) => b.any_hit_packet_with::<B, S, F>(query, occluded, stats, filter),
            Laid::QBvh4(b) => b.any_hit_packet_with::<B, S, F>(query, occluded, stats, filter),
            Laid::Bvh8(b) => b.any_hit_packet_with::<B, S, F>(query, occluded, stats, filter),
        }
    }
}

impl<P: Primitive> RayQuery for Nodes<P> {
    type Hit = Hit;

    #[inline(always)]
    fn closest_hit_with<B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> Option<Hit> {
        match self {
            Nodes::Plain(l) => l.closest_hit_with::<B, S, F>(ray, stats, filter),
            Nodes::Scaled(s) => s.closest_hit_with::<B, S, F>(ray, stats, filter),
        }
    }

    #[inline(always)]
    fn any_hit_with<B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        match self {
            Nodes::Plain(l) => l.any_hit_with::<B, S, F>(ray, stats, filter),
            Nodes::Scaled(s) => s.any_hit_with::<B, S, F>(ray, stats, filter),
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
            Nodes::Plain(l) => l.closest_hit_packet_with::<B, S, F>(query, hits, stats, filter),
            Nodes::Scaled(s) => s.closest_hit_packet_with::<B, S, F>(query, hits, stats, filter),
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
            Nodes::Plain(l) => l.any_hit_packet_with::<B, S, F>(query, occluded, stats, filter),
            Nodes::Scaled(s) => s.any_hit_packet_with::<B, S, F>(query, occluded, stats, filter),
        }
    }
}

/// Rays per batch brought into a scaled BVH's frame for a packet query: a whole number of
/// packets, so the packets are the ones an unscaled BVH would form.
const FRAME_BATCH: usize = 4 * crate::traverse::PACKET_RAYS;

/// A filter that sees a scaled BVH's candidates in world units.
struct InWorld<'f, F> {
    filter: &'f mut F,
    back: Back,
}

impl<F: Filter<Hit>> Filter<Hit> for InWorld<'_, F> {
    const ACTIVE: bool = F::ACTIVE;
    #[inline(always)]
    fn accept(&mut self, candidate: &Hit) -> bool {
        self.filter.accept(&self.back.hit(*candidate))
    }
}

impl<P: Primitive> RayQuery for Scaled<P> {
    type Hit = Hit;

    fn closest_hit_with<B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> Option<Hit> {
        let (local, back) = self.frame.ray(ray);
        let mut filter = InWorld { filter, back };
        let hit = self
            .nodes
            .closest_hit_with::<B, S, _>(&local, stats, &mut filter);
        hit.map(|h| back.hit(h))
    }

    fn any_hit_with<B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        let (local, back) = self.frame.ray(ray);
        self.nodes
            .any_hit_with::<B, S, _>(&local, stats, &mut InWorld { filter, back })
    }

    fn closest_hit_packet_with<B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        query: PacketQuery<'_>,
        hits: &mut [Option<Hit>],
        stats: &mut S,
        filter: &mut F,
    ) {
        // Each ray comes back to world units by its own factor, which a filter shared by a
        // packet cannot know: filtered queries go ray by ray here.
        if F::ACTIVE {
            return crate::traverse::query::closest_ray_by_ray::<_, B, S, F>(
                self, query, hits, stats, filter,
            );
        }
        assert_eq!(hits.len(), query.rays.len(), "one hit slot per ray");
        self.in_frame(query, |local, backs, at| {
            let hits = &mut hits[at..at + local.rays.len()];
            self.nodes
                .closest_hit_packet_with::<B, S, F>(local, hits, stats, filter);
            for (h, back) in hits.iter_mut().zip(backs) {
                *h = h.map(|h| back.hit(h));
            }
        });
    }

    fn any_hit_packet_with<B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        query: PacketQuery<'_>,
        occluded: &mut [bool],
        stats: &mut S,
        filter: &mut F,
    ) {
        if F::ACTIVE {
            return crate::traverse::query::any_ray_by_ray::<_, B, S, F>(
                self, query, occluded, stats, filter,
            );
        }
        assert_eq!(occluded.len(), query.rays.len(), "one flag per ray");
        self.in_frame(query, |local, _, at| {
            let occluded = &mut occluded[at..at + local.rays.len()];
            self.nodes
                .any_hit_packet_with::<B, S, F>(local, occluded, stats, filter);
        });
    }
}

impl<P: Primitive> Scaled<P> {
    /// Calls `f(the query for the local rays, their ways back, index of the first)` batch by
    /// batch with the rays brought into the frame, on the stack.
    fn in_frame(&self, query: PacketQuery<'_>, mut f: impl FnMut(PacketQuery<'_>, &[Back], usize)) {
        let PacketQuery { rays, active, mode } = query;
        if let Some(a) = active {
            assert_eq!(a.len(), rays.len(), "one active flag per ray");
        }
        let mut local = [Ray::new(glam::Vec3A::ZERO, glam::Vec3A::ZERO); FRAME_BATCH];
        let mut backs = [Back::default(); FRAME_BATCH];
        for (n, batch) in rays.chunks(FRAME_BATCH).enumerate() {
            let at = n * FRAME_BATCH;
            for ((l, b), r) in local.iter_mut().zip(&mut backs).zip(batch) {
                (*l, *b) = self.frame.ray(r);
            }
            let local = PacketQuery {
                rays: &local[..batch.len()],
                active: active.map(|a| &a[at..at + batch.len()]),
                mode,
            };
            f(local, &backs[..batch.len()], at);
        }
    }
}
