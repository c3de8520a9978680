//! The layout a [`super::Bvh`] holds, chosen at run time: [`AnyLayout`], one variant per
//! layout family, built from a [`Layout`] name by [`lay_out`]; and the queries of a BVH built
//! in a scaled frame ([`super::Bvh`]'s rays brought into it and its hits back). The one place
//! the layout choice lives.

use crate::builders::{BuildConfig, BuildTree};
use crate::frame::{Back, Frame};
use crate::geometry::{Hit, Ray};
use crate::isa::{Isa, Kernels};
use crate::layout::walk::{NodeVisit, WalkNodes};
use crate::layout::{
    Bvh2, Bvh2Mapping, Bvh4, Bvh4Mapping, Bvh8, Footprint, Inputs, Layout, LeafPrims, QBvh4,
};
use crate::primitive::Primitive;
use crate::traverse::lane8::F8;
use crate::traverse::packet::{InLanes, RayPacket};
use crate::traverse::query::ray_by_ray;
use crate::traverse::{Ask, BoxTest, Filter, PacketQuery, RayQuery, Stats};

/// The nodes and leaves of one [`Layout`].
#[derive(Clone, Debug)]
pub(crate) enum AnyLayout<P> {
    /// Binary nodes.
    Bvh2(Bvh2<P>),
    /// 4-wide exact nodes.
    Bvh4(Bvh4<P>),
    /// 4-wide quantized nodes.
    QBvh4(QBvh4<P>),
    /// 8-wide exact nodes.
    Bvh8(Bvh8<P>),
}

impl<P: Primitive> AnyLayout<P> {
    pub(crate) fn isa(&self) -> Isa {
        match self {
            AnyLayout::Bvh8(b) => b.isa(),
            AnyLayout::Bvh4(b) => b.isa(),
            AnyLayout::QBvh4(b) => b.isa(),
            AnyLayout::Bvh2(_) => Isa::Portable,
        }
    }

    pub(crate) fn with_isa(self, isa: Isa) -> Self {
        match self {
            AnyLayout::Bvh8(b) => AnyLayout::Bvh8(b.with_isa(isa)),
            AnyLayout::Bvh4(b) => AnyLayout::Bvh4(b.with_isa(isa)),
            AnyLayout::QBvh4(b) => AnyLayout::QBvh4(b.with_isa(isa)),
            other => other,
        }
    }

    pub(crate) fn footprint(&self) -> Footprint {
        match self {
            AnyLayout::Bvh2(b) => b.footprint(),
            AnyLayout::Bvh4(b) => b.footprint(),
            AnyLayout::QBvh4(b) => b.footprint(),
            AnyLayout::Bvh8(b) => b.footprint(),
        }
    }

    /// The query `A` of one ray (in the layout's units) on the caller's lanes (see
    /// [`Bvh8::one_ray`]): the 8-wide layout; false, with nothing done, for the others (asked
    /// the usual way).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn one_ray<V: F8, A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        kernels: Kernels,
        cpu: V::Cpu,
        ray: &Ray,
        best: &mut Hit,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        match self {
            AnyLayout::Bvh8(b) => {
                b.one_ray::<V, A, B, S, F>(kernels, cpu, ray, best, stats, filter)
            }
            _ => false,
        }
    }

    /// The query `A` of a packet already in lanes (in the layout's units; see
    /// [`Bvh8::in_lanes`]): the wide layouts; false, with nothing done, for binary nodes or
    /// other kernels.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn in_lanes<V: F8, A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        kernels: Kernels,
        cpu: V::Cpu,
        pk: &mut RayPacket,
        best: InLanes<'_>,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        match self {
            AnyLayout::Bvh8(b) => {
                b.in_lanes::<V, A, B, S, F>(kernels, cpu, pk, best, stats, filter)
            }
            AnyLayout::Bvh4(b) => {
                b.in_lanes::<V, A, B, S, F>(kernels, cpu, pk, best, stats, filter)
            }
            AnyLayout::QBvh4(b) => {
                b.in_lanes::<V, A, B, S, F>(kernels, cpu, pk, best, stats, filter)
            }
            AnyLayout::Bvh2(_) => false,
        }
    }
}

/// Lays out a checked `tree` as `layout` over `prims` (in the tree's leaf order, or read
/// through it): the one place a layout name becomes nodes.
pub(crate) fn lay_out<P: Primitive>(
    layout: Layout,
    tree: &BuildTree,
    prims: LeafPrims<P>,
    inputs: Inputs,
    isa: Isa,
    config: &BuildConfig,
) -> AnyLayout<P> {
    let bvh2 = match layout {
        Layout::Bvh2Dfs => Bvh2Mapping::DepthFirst,
        Layout::Bvh2Bfs => Bvh2Mapping::BreadthFirst,
        Layout::Bvh2Shuffled => Bvh2Mapping::Shuffled,
        Layout::Bvh2Subtree => Bvh2Mapping::Subtree,
        Layout::Bvh2SubtreePage => Bvh2Mapping::SubtreePage,
        Layout::Bvh2Compact => Bvh2Mapping::Compact,
        Layout::Bvh2CompactPage => Bvh2Mapping::CompactPage,
        Layout::Bvh4Dfs => {
            return AnyLayout::Bvh4(Bvh4::from_leaf_prims(
                tree,
                prims,
                Bvh4Mapping::DepthFirst,
                inputs,
                isa,
            ))
        }
        Layout::Bvh4Subtree => {
            return AnyLayout::Bvh4(Bvh4::from_leaf_prims(
                tree,
                prims,
                Bvh4Mapping::Subtree,
                inputs,
                isa,
            ))
        }
        Layout::Bvh4Quant => {
            return AnyLayout::QBvh4(QBvh4::from_leaf_prims(
                tree,
                prims,
                Bvh4Mapping::DepthFirst,
                inputs,
                isa,
            ))
        }
        Layout::Bvh8Dfs => {
            return AnyLayout::Bvh8(Bvh8::from_leaf_prims(tree, prims, inputs, isa, config))
        }
    };
    AnyLayout::Bvh2(Bvh2::from_leaf_prims(
        tree,
        prims.into_ordered(&tree.prim_indices),
        bvh2,
        inputs,
    ))
}

impl<P: Primitive> RayQuery for AnyLayout<P> {
    type Hit = Hit;

    #[inline(always)]
    fn trace_with<A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> A::Answer<Hit> {
        match self {
            AnyLayout::Bvh2(b) => b.trace_with::<A, B, S, F>(ray, stats, filter),
            AnyLayout::Bvh4(b) => b.trace_with::<A, B, S, F>(ray, stats, filter),
            AnyLayout::QBvh4(b) => b.trace_with::<A, B, S, F>(ray, stats, filter),
            AnyLayout::Bvh8(b) => b.trace_with::<A, B, S, F>(ray, stats, filter),
        }
    }

    #[inline(always)]
    fn trace_packet_with<A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        query: PacketQuery<'_>,
        hits: &mut [A::Answer<Hit>],
        stats: &mut S,
        filter: &mut F,
    ) {
        match self {
            AnyLayout::Bvh2(b) => b.trace_packet_with::<A, B, S, F>(query, hits, stats, filter),
            AnyLayout::Bvh4(b) => b.trace_packet_with::<A, B, S, F>(query, hits, stats, filter),
            AnyLayout::QBvh4(b) => b.trace_packet_with::<A, B, S, F>(query, hits, stats, filter),
            AnyLayout::Bvh8(b) => b.trace_packet_with::<A, B, S, F>(query, hits, stats, filter),
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

/// The queries of a layout built in the scaled `frame` (the caller's rays brought into it,
/// hits and filter candidates back to the caller's units): out of the unscaled queries' line.
#[cold]
#[inline(never)]
pub(crate) fn trace_scaled<P, A, B, S, F>(
    layout: &AnyLayout<P>,
    frame: Frame,
    ray: &Ray,
    stats: &mut S,
    filter: &mut F,
) -> A::Answer<Hit>
where
    P: Primitive,
    A: Ask,
    B: BoxTest,
    S: Stats,
    F: Filter<Hit>,
{
    let (local, back) = frame.ray(ray);
    let mut filter = InWorld { filter, back };
    let hit = layout.trace_with::<A, B, S, _>(&local, stats, &mut filter);
    A::map(hit, |h| back.hit(h))
}

/// [`trace_scaled`] for packets.
#[cold]
#[inline(never)]
pub(crate) fn trace_packet_scaled<P, A, B, S, F>(
    layout: &AnyLayout<P>,
    frame: Frame,
    query: PacketQuery<'_>,
    hits: &mut [A::Answer<Hit>],
    stats: &mut S,
    filter: &mut F,
) where
    P: Primitive,
    A: Ask,
    B: BoxTest,
    S: Stats,
    F: Filter<Hit>,
{
    // Each ray comes back to world units by its own factor, which a filter shared by a
    // packet cannot know: filtered queries go ray by ray here.
    if F::ACTIVE {
        let scaled = Scaled { layout, frame };
        return ray_by_ray::<_, A, B, S, F>(&scaled, query, hits, stats, filter);
    }
    assert_eq!(hits.len(), query.rays.len(), "one hit slot per ray");
    in_frame(frame, query, |local, backs, at| {
        let hits = &mut hits[at..at + local.rays.len()];
        layout.trace_packet_with::<A, B, S, F>(local, hits, stats, filter);
        for (h, back) in hits.iter_mut().zip(backs) {
            *h = A::map(*h, |h| back.hit(h));
        }
    });
}

/// A layout in a scaled frame, answering single rays in the caller's units (the ray-by-ray
/// packet query of a filtered packet).
struct Scaled<'a, P> {
    layout: &'a AnyLayout<P>,
    frame: Frame,
}

impl<P: Primitive> RayQuery for Scaled<'_, P> {
    type Hit = Hit;

    fn trace_with<A: Ask, B: BoxTest, S: Stats, F: Filter<Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> A::Answer<Hit> {
        trace_scaled::<P, A, B, S, F>(self.layout, self.frame, ray, stats, filter)
    }
}

/// Calls `f(the query for the local rays, their ways back, index of the first)` batch by
/// batch with the rays brought into `frame`, on the stack.
fn in_frame(
    frame: Frame,
    query: PacketQuery<'_>,
    mut f: impl FnMut(PacketQuery<'_>, &[Back], usize),
) {
    let PacketQuery { rays, active, mode } = query;
    if let Some(a) = active {
        assert_eq!(a.len(), rays.len(), "one active flag per ray");
    }
    let mut local = [Ray::new(glam::Vec3A::ZERO, glam::Vec3A::ZERO); FRAME_BATCH];
    let mut backs = [Back::default(); FRAME_BATCH];
    for (n, batch) in rays.chunks(FRAME_BATCH).enumerate() {
        let at = n * FRAME_BATCH;
        for ((l, b), r) in local.iter_mut().zip(&mut backs).zip(batch) {
            (*l, *b) = frame.ray(r);
        }
        let local = PacketQuery {
            rays: &local[..batch.len()],
            active: active.map(|a| &a[at..at + batch.len()]),
            mode,
        };
        f(local, &backs[..batch.len()], at);
    }
}

impl<P: Primitive> WalkNodes for AnyLayout<P> {
    fn walk_nodes(&self, f: &mut dyn FnMut(NodeVisit)) {
        match self {
            AnyLayout::Bvh2(b) => b.walk_nodes(f),
            AnyLayout::Bvh4(b) => b.walk_nodes(f),
            AnyLayout::QBvh4(b) => b.walk_nodes(f),
            AnyLayout::Bvh8(b) => b.walk_nodes(f),
        }
    }
}
