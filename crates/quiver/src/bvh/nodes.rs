//! The layout a [`super::Bvh`] holds, chosen at run time: [`Nodes`], one variant per layout
//! family plus [`Scaled`] for a BVH built in a scaled frame; built from a [`Layout`] name by
//! [`lay_out`], queried through one `match` per method. The one place the choice lives.

use crate::builders::{BuildConfig, BuildTree};
use crate::frame::{Back, Frame};
use crate::geometry::{Aabb, Hit, Ray};
use crate::isa::Isa;
use crate::layout::{Bvh2, Bvh2Mapping, Bvh4, Bvh4Mapping, Bvh8, Footprint, Layout, QBvh4};
use crate::primitive::Primitive;
use crate::traverse::{BoxTest, PacketQuery, RayQuery, Stats};

/// The nodes and leaves of one [`Layout`].
#[derive(Clone, Debug)]
pub(crate) enum Nodes<P> {
    /// Binary nodes.
    Bvh2(Bvh2<P>),
    /// 4-wide exact nodes.
    Bvh4(Bvh4<P>),
    /// 4-wide quantized nodes.
    QBvh4(QBvh4<P>),
    /// 8-wide exact nodes.
    Bvh8(Bvh8<P>),
    /// Nodes built in a scaled frame, for a scene far from unit size (see
    /// [`Primitive::scaled`]). A variant of its own, so that unscaled BVHs pay nothing for it.
    Scaled(Box<Scaled<P>>),
}

/// Nodes and primitives in a frame scaled by a power of two, and the frame.
#[derive(Clone, Debug)]
pub(crate) struct Scaled<P> {
    pub(crate) frame: Frame,
    pub(crate) nodes: Nodes<P>,
}

impl<P> Nodes<P> {
    /// The nodes of the layout itself, out of any scaled frame, and `b` (world units) in
    /// their frame.
    pub(crate) fn unframed(&self, b: &Aabb) -> (&Nodes<P>, Aabb) {
        match self {
            Nodes::Scaled(s) => (&s.nodes, s.frame.aabb(b)),
            other => (other, *b),
        }
    }

    /// These nodes, built in `frame`.
    pub(crate) fn framed(self, frame: Frame) -> Nodes<P> {
        if frame.is_identity() {
            self
        } else {
            Nodes::Scaled(Box::new(Scaled { frame, nodes: self }))
        }
    }
}

impl<P: Primitive> Nodes<P> {
    pub(crate) fn isa(&self) -> Isa {
        match self {
            Nodes::Bvh8(b) => b.isa(),
            Nodes::Bvh4(b) => b.isa(),
            Nodes::QBvh4(b) => b.isa(),
            Nodes::Scaled(s) => s.nodes.isa(),
            _ => Isa::Portable,
        }
    }

    pub(crate) fn with_isa(self, isa: Isa) -> Self {
        match self {
            Nodes::Bvh8(b) => Nodes::Bvh8(b.with_isa(isa)),
            Nodes::Bvh4(b) => Nodes::Bvh4(b.with_isa(isa)),
            Nodes::QBvh4(b) => Nodes::QBvh4(b.with_isa(isa)),
            Nodes::Scaled(s) => {
                let Scaled { frame, nodes } = *s;
                nodes.with_isa(isa).framed(frame)
            }
            other => other,
        }
    }

    pub(crate) fn footprint(&self) -> Footprint {
        match self {
            Nodes::Bvh2(b) => b.footprint(),
            Nodes::Bvh4(b) => b.footprint(),
            Nodes::QBvh4(b) => b.footprint(),
            Nodes::Bvh8(b) => b.footprint(),
            Nodes::Scaled(s) => s.nodes.footprint(),
        }
    }
}

/// Lays out a checked `tree` as `layout`, with `prims` already in the tree's leaf order: the
/// one place a layout name becomes nodes.
pub(crate) fn lay_out<P: Primitive>(
    layout: Layout,
    tree: &BuildTree,
    prims: Vec<P>,
    isa: Isa,
    config: &BuildConfig,
) -> Nodes<P> {
    let bvh2 = match layout {
        Layout::Bvh2Dfs => Bvh2Mapping::DepthFirst,
        Layout::Bvh2Bfs => Bvh2Mapping::BreadthFirst,
        Layout::Bvh2Shuffled => Bvh2Mapping::Shuffled,
        Layout::Bvh2Subtree => Bvh2Mapping::Subtree,
        Layout::Bvh2SubtreePage => Bvh2Mapping::SubtreePage,
        Layout::Bvh2Compact => Bvh2Mapping::Compact,
        Layout::Bvh2CompactPage => Bvh2Mapping::CompactPage,
        Layout::Bvh4Dfs => {
            return Nodes::Bvh4(Bvh4::from_leaf_prims(
                tree,
                prims,
                Bvh4Mapping::DepthFirst,
                isa,
            ))
        }
        Layout::Bvh4Subtree => {
            return Nodes::Bvh4(Bvh4::from_leaf_prims(
                tree,
                prims,
                Bvh4Mapping::Subtree,
                isa,
            ))
        }
        Layout::Bvh4Quant => {
            return Nodes::QBvh4(QBvh4::from_leaf_prims(
                tree,
                prims,
                Bvh4Mapping::DepthFirst,
                isa,
            ))
        }
        Layout::Bvh8Dfs => return Nodes::Bvh8(Bvh8::from_leaf_prims(tree, prims, isa, config)),
    };
    Nodes::Bvh2(Bvh2::from_leaf_prims(tree, prims, bvh2))
}

impl<P: Primitive> RayQuery for Nodes<P> {
    #[inline(always)]
    fn closest_hit_with<B: BoxTest, S: Stats>(&self, ray: &Ray, stats: &mut S) -> Option<Hit> {
        match self {
            Nodes::Bvh2(b) => b.closest_hit_with::<B, S>(ray, stats),
            Nodes::Bvh4(b) => b.closest_hit_with::<B, S>(ray, stats),
            Nodes::QBvh4(b) => b.closest_hit_with::<B, S>(ray, stats),
            Nodes::Bvh8(b) => b.closest_hit_with::<B, S>(ray, stats),
            Nodes::Scaled(s) => s.closest_hit_with::<B, S>(ray, stats),
        }
    }

    #[inline(always)]
    fn any_hit_with<B: BoxTest, S: Stats>(&self, ray: &Ray, stats: &mut S) -> bool {
        match self {
            Nodes::Bvh2(b) => b.any_hit_with::<B, S>(ray, stats),
            Nodes::Bvh4(b) => b.any_hit_with::<B, S>(ray, stats),
            Nodes::QBvh4(b) => b.any_hit_with::<B, S>(ray, stats),
            Nodes::Bvh8(b) => b.any_hit_with::<B, S>(ray, stats),
            Nodes::Scaled(s) => s.any_hit_with::<B, S>(ray, stats),
        }
    }

    fn closest_hit_packet_with<B: BoxTest, S: Stats>(
        &self,
        query: PacketQuery<'_>,
        hits: &mut [Option<Hit>],
        stats: &mut S,
    ) {
        match self {
            Nodes::Bvh2(b) => b.closest_hit_packet_with::<B, S>(query, hits, stats),
            Nodes::Bvh4(b) => b.closest_hit_packet_with::<B, S>(query, hits, stats),
            Nodes::QBvh4(b) => b.closest_hit_packet_with::<B, S>(query, hits, stats),
            Nodes::Bvh8(b) => b.closest_hit_packet_with::<B, S>(query, hits, stats),
            Nodes::Scaled(s) => s.closest_hit_packet_with::<B, S>(query, hits, stats),
        }
    }

    fn any_hit_packet_with<B: BoxTest, S: Stats>(
        &self,
        query: PacketQuery<'_>,
        occluded: &mut [bool],
        stats: &mut S,
    ) {
        match self {
            Nodes::Bvh2(b) => b.any_hit_packet_with::<B, S>(query, occluded, stats),
            Nodes::Bvh4(b) => b.any_hit_packet_with::<B, S>(query, occluded, stats),
            Nodes::QBvh4(b) => b.any_hit_packet_with::<B, S>(query, occluded, stats),
            Nodes::Bvh8(b) => b.any_hit_packet_with::<B, S>(query, occluded, stats),
            Nodes::Scaled(s) => s.any_hit_packet_with::<B, S>(query, occluded, stats),
        }
    }
}

/// Rays per batch brought into a scaled BVH's frame for a packet query: a whole number of
/// packets, so the packets are the ones an unscaled BVH would form.
const FRAME_BATCH: usize = 4 * crate::traverse::PACKET_RAYS;

impl<P: Primitive> RayQuery for Scaled<P> {
    fn closest_hit_with<B: BoxTest, S: Stats>(&self, ray: &Ray, stats: &mut S) -> Option<Hit> {
        let (local, back) = self.frame.ray(ray);
        let hit = self.nodes.closest_hit_with::<B, S>(&local, stats);
        hit.map(|h| back.hit(h))
    }

    fn any_hit_with<B: BoxTest, S: Stats>(&self, ray: &Ray, stats: &mut S) -> bool {
        self.nodes
            .any_hit_with::<B, S>(&self.frame.ray(ray).0, stats)
    }

    fn closest_hit_packet_with<B: BoxTest, S: Stats>(
        &self,
        query: PacketQuery<'_>,
        hits: &mut [Option<Hit>],
        stats: &mut S,
    ) {
        assert_eq!(hits.len(), query.rays.len(), "one hit slot per ray");
        self.in_frame(query, |local, backs, at| {
            let hits = &mut hits[at..at + local.rays.len()];
            self.nodes
                .closest_hit_packet_with::<B, S>(local, hits, stats);
            for (h, back) in hits.iter_mut().zip(backs) {
                *h = h.map(|h| back.hit(h));
            }
        });
    }

    fn any_hit_packet_with<B: BoxTest, S: Stats>(
        &self,
        query: PacketQuery<'_>,
        occluded: &mut [bool],
        stats: &mut S,
    ) {
        assert_eq!(occluded.len(), query.rays.len(), "one flag per ray");
        self.in_frame(query, |local, _, at| {
            let occluded = &mut occluded[at..at + local.rays.len()];
            self.nodes
                .any_hit_packet_with::<B, S>(local, occluded, stats);
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
