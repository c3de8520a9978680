//! The recursion both builders share: leaf-or-split decision, depth guard, median fallback,
//! node slots and vertical (task) parallelism. A builder only supplies how to find and apply
//! the best SAH split of one node. Primitives travel as [`Ref`]s (box and index in one
//! 32-byte record) between two buffers: a split partitions a node's references from one
//! into the other, so no pass gathers through an index and none copies back.

use super::{split_beats_leaf, widest_axis, BuildConfig, BuildNode, NodeKind, MEDIAN_DEPTH};
use crate::geometry::Aabb;
use glam::{BVec4A, Vec3A, Vec4};
use rayon::prelude::*;

/// Below this many primitives a subtree is built on the current thread: a rayon task costs
/// more than the work it would share.
const TASK_CUTOFF: usize = 512;

/// Chunk size for the horizontal (data-parallel) passes over one node's primitives.
pub(crate) const CHUNK: usize = 16 * 1024;

/// A primitive as the top-down builders move it: its box, with its index in the input kept
/// in the otherwise unused fourth lane of the lower corner. Splitting moves these 32-byte
/// records through two buffers, so binning and partitioning read memory in order instead of
/// gathering each primitive's box and centroid through an index.
#[derive(Clone, Copy, bytemuck::Zeroable)]
#[repr(C)]
pub(crate) struct Ref {
    lo: Vec4,
    hi: Vec4,
}

impl Ref {
    pub fn new(b: &Aabb, id: u32) -> Ref {
        Ref {
            lo: b.min.extend(f32::from_bits(id)),
            hi: b.max.extend(0.0),
        }
    }

    #[inline(always)]
    pub fn bounds(&self) -> Aabb {
        Aabb {
            min: self.min(),
            max: Vec3A::from_vec4(self.hi),
        }
    }

    /// The lower corner with the index's lane zeroed. The index's bits read as a float are a
    /// subnormal for every index below 2^23, and arithmetic on subnormals takes a slow
    /// microcoded path: left in the lane, every centroid of the build paid it (the binned
    /// build ran several times slower).
    #[inline(always)]
    fn min(&self) -> Vec3A {
        const XYZ: BVec4A = BVec4A::new(true, true, true, false);
        Vec3A::from_vec4(Vec4::select(XYZ, self.lo, Vec4::ZERO))
    }

    /// The box's centre, exactly as [`Aabb::center`] computes it.
    #[inline(always)]
    pub fn center(&self) -> Vec3A {
        (self.min() + Vec3A::from_vec4(self.hi)) * 0.5
    }

    /// The primitive's index in the input.
    #[inline(always)]
    pub fn id(&self) -> u32 {
        self.lo.w.to_bits()
    }
}

/// Bounds and centroid bounds of a run of references.
pub(crate) fn refs_bounds(refs: &[Ref]) -> (Aabb, Aabb) {
    let mut b = Aabb::EMPTY;
    let mut c = Aabb::EMPTY;
    for r in refs {
        b = b.union(&r.bounds());
        c.grow(r.center());
    }
    (b, c)
}

/// Everything a node's split needs to read.
pub(crate) struct Ctx<'a> {
    pub config: &'a BuildConfig,
    /// Each primitive's surface area by input index, for cost models other than the SAH
    /// (`None` for it).
    pub areas: Option<&'a [f32]>,
}

/// A node's primitives after a split: the first `left_len` go left.
pub(crate) struct Partition {
    pub left_len: usize,
    /// Bounds and centroid bounds of the left side.
    pub left: (Aabb, Aabb),
    /// Bounds and centroid bounds of the right side.
    pub right: (Aabb, Aabb),
    /// Whether the partitioned references were written to `spare` (else they are in place).
    pub moved: bool,
}

/// How a builder splits one node.
pub(crate) trait Splitter: Sync {
    /// Finds the cheapest SAH split of `refs` and, if it beats a leaf (or `refs` is too large
    /// for a leaf), partitions them, in place or into `spare` (of equal length), and describes
    /// the halves. Returns `None` when no split separates the primitives or a leaf is cheaper.
    fn split(
        &self,
        ctx: &Ctx,
        refs: &mut [Ref],
        spare: &mut [Ref],
        node: &Aabb,
        centroids: &Aabb,
    ) -> Option<Partition>;
}

/// True when a split with weighted child cost `weighted` should be taken for a node of `n`.
pub(crate) fn take_split(config: &BuildConfig, node_area: f32, weighted: f32, n: usize) -> bool {
    n > config.max_leaf_size || split_beats_leaf(config, node_area, weighted, n)
}

/// Builds the tree over `idx` (finite primitives only, at least one) and returns the nodes in
/// preorder together with `idx` reordered into leaf order.
pub(crate) fn build_tree<S: Splitter>(
    splitter: &S,
    bounds: &[Aabb],
    areas: Option<&[f32]>,
    idx: Vec<u32>,
    config: &BuildConfig,
) -> (Vec<BuildNode>, Vec<u32>) {
    assert!(
        idx.len() < (u32::MAX / 2) as usize,
        "too many primitives for 32-bit node indices"
    );
    let ctx = Ctx { config, areas };
    let mut refs: Vec<Ref> = crate::mem::with_capacity(idx.len());
    refs.par_extend(idx.par_iter().map(|&i| Ref::new(&bounds[i as usize], i)));
    let (node, cent) = refs.par_chunks(CHUNK).map(refs_bounds).reduce(
        || (Aabb::EMPTY, Aabb::EMPTY),
        |a, b| (a.0.union(&b.0), a.1.union(&b.1)),
    );
    // Every node writes its part of the spare buffer before reading it: zeroed pages from
    // the OS, not a copy of `refs`.
    let mut spare: Vec<Ref> = crate::mem::zeroed_vec(refs.len());
    let mut order = idx;
    let job = Job {
        splitter,
        ctx: &ctx,
    };
    let piece = job.node(Work {
        refs: &mut refs,
        spare: &mut spare,
        order: &mut order,
        first: 0,
        bounds: node,
        centroids: cent,
        depth: 0,
    });
    let mut nodes = Vec::with_capacity(piece.len());
    piece.flatten(&mut nodes);
    (nodes, order)
}

/// Appends the subtree over `refs` (box `bounds`, centroid box `centroids`, at `depth` below
/// the root), as `splitter` builds it on this thread, to `nodes` (in preorder, links as
/// positions in `nodes`) and its leaf order to `ids` (leaf ranges as positions in `ids`). For a
/// builder that hands its small nodes to a cheaper one.
pub(crate) fn serial_subtree<S: Splitter>(
    splitter: &S,
    config: &BuildConfig,
    refs: &mut [Ref],
    (bounds, centroids): (Aabb, Aabb),
    depth: usize,
    nodes: &mut Vec<BuildNode>,
    ids: &mut Vec<u32>,
) {
    let ctx = Ctx {
        config,
        areas: None,
    };
    let job = Job {
        splitter,
        ctx: &ctx,
    };
    let first = ids.len();
    ids.resize(first + refs.len(), 0);
    // As in `build_tree`: every node writes its part of the spare buffer before reading it.
    let mut spare: Vec<Ref> = crate::mem::zeroed_vec(refs.len());
    nodes.reserve(2 * refs.len());
    job.serial(
        Work {
            refs,
            spare: &mut spare,
            order: &mut ids[first..],
            first: first as u32,
            bounds,
            centroids,
            depth,
        },
        nodes,
    );
}

/// A subtree as the recursion returns it. Each task below [`TASK_CUTOFF`] writes its nodes
/// densely into a vector of its own, and the joins above them are kept apart until one pass
/// lays all of it out in preorder; the result depends on the input alone, however the tasks
/// ran. (Writing every node into a preassigned position of a 2n - 1 slot array touched a
/// fresh page of that array for nearly every few nodes.) The linear builder shares it.
pub(crate) enum Piece {
    /// Nodes in preorder, child links counted from the first of them.
    Nodes(Vec<BuildNode>),
    /// An inner node whose children were built as tasks of their own.
    Join {
        bounds: Aabb,
        left: Box<Piece>,
        right: Box<Piece>,
        len: usize,
    },
}

impl Piece {
    pub(crate) fn len(&self) -> usize {
        match self {
            Piece::Nodes(v) => v.len(),
            Piece::Join { len, .. } => *len,
        }
    }

    pub(crate) fn join(bounds: Aabb, left: Piece, right: Piece) -> Piece {
        Piece::Join {
            len: 1 + left.len() + right.len(),
            bounds,
            left: Box::new(left),
            right: Box::new(right),
        }
    }

    /// Appends the subtree to `out` in preorder, its links shifted to their place there.
    pub(crate) fn flatten(self, out: &mut Vec<BuildNode>) {
        match self {
            Piece::Nodes(v) => {
                let base = out.len() as u32;
                out.extend(v.into_iter().map(|mut n| {
                    if let NodeKind::Inner { left, right } = &mut n.kind {
                        *left += base;
                        *right += base;
                    }
                    n
                }));
            }
            Piece::Join {
                bounds,
                left,
                right,
                ..
            } => {
                let me = out.len();
                out.push(BuildNode {
                    bounds,
                    kind: NodeKind::Inner {
                        left: me as u32 + 1,
                        right: (me + 1 + left.len()) as u32,
                    },
                });
                left.flatten(out);
                right.flatten(out);
            }
        }
    }
}

struct Job<'a, S> {
    splitter: &'a S,
    ctx: &'a Ctx<'a>,
}

/// One node's share of the build: its references (with `spare` of equal length to partition
/// into), its run of the leaf order (positions `first..`), its bounds and centroid bounds.
struct Work<'r> {
    refs: &'r mut [Ref],
    spare: &'r mut [Ref],
    order: &'r mut [u32],
    first: u32,
    bounds: Aabb,
    centroids: Aabb,
    depth: usize,
}

impl<'r> Work<'r> {
    /// The two children's shares after `split`.
    fn halves(self, split: Partition) -> (Work<'r>, Work<'r>) {
        let nl = split.left_len;
        let (data, other) = if split.moved {
            (self.spare, self.refs)
        } else {
            (self.refs, self.spare)
        };
        let (l_refs, r_refs) = data.split_at_mut(nl);
        let (l_spare, r_spare) = other.split_at_mut(nl);
        let (l_order, r_order) = self.order.split_at_mut(nl);
        let side = |refs, spare, order, first, (bounds, centroids)| Work {
            refs,
            spare,
            order,
            first,
            bounds,
            centroids,
            depth: self.depth + 1,
        };
        (
            side(l_refs, l_spare, l_order, self.first, split.left),
            side(
                r_refs,
                r_spare,
                r_order,
                self.first + nl as u32,
                split.right,
            ),
        )
    }
}

impl<S: Splitter> Job<'_, S> {
    /// Builds the subtree of `w`, its large children as tasks of their own.
    fn node(&self, mut w: Work) -> Piece {
        let n = w.refs.len();
        if n < TASK_CUTOFF {
            let mut nodes = Vec::with_capacity(2 * n - 1);
            self.serial(w, &mut nodes);
            return Piece::Nodes(nodes);
        }
        let split = match self.split_or_leaf(&mut w) {
            Ok(s) => s,
            Err(leaf) => return Piece::Nodes(vec![leaf]),
        };
        let bounds = w.bounds;
        let (l, r) = w.halves(split);
        let (left, right) = rayon::join(|| self.node(l), || self.node(r));
        Piece::join(bounds, left, right)
    }

    /// [`Job::node`] on this thread, appending the subtree's nodes to `out` in preorder.
    fn serial(&self, mut w: Work, out: &mut Vec<BuildNode>) {
        let split = match self.split_or_leaf(&mut w) {
            Ok(s) => s,
            Err(leaf) => return out.push(leaf),
        };
        let me = out.len();
        out.push(BuildNode {
            bounds: w.bounds,
            kind: NodeKind::Inner {
                left: me as u32 + 1,
                right: 0,
            },
        });
        let (l, r) = w.halves(split);
        self.serial(l, out);
        let right = out.len() as u32;
        if let NodeKind::Inner { right: at, .. } = &mut out[me].kind {
            *at = right;
        }
        self.serial(r, out);
    }

    /// The node's split, or (having written its primitives to the leaf order) its leaf.
    fn split_or_leaf(&self, w: &mut Work) -> Result<Partition, BuildNode> {
        let n = w.refs.len();
        let split = if n > 1 && w.depth < MEDIAN_DEPTH {
            self.splitter
                .split(self.ctx, w.refs, w.spare, &w.bounds, &w.centroids)
        } else {
            None
        };
        let split = match split {
            Some(s) => s,
            None if n <= self.ctx.config.max_leaf_size => {
                for (o, r) in w.order.iter_mut().zip(w.refs.iter()) {
                    *o = r.id();
                }
                return Err(BuildNode {
                    bounds: w.bounds,
                    kind: NodeKind::Leaf {
                        first: w.first,
                        count: n as u32,
                    },
                });
            }
            None => {
                let nl = median_split(w.refs, &w.centroids);
                Partition {
                    left_len: nl,
                    left: refs_bounds(&w.refs[..nl]),
                    right: refs_bounds(&w.refs[nl..]),
                    moved: false,
                }
            }
        };
        debug_assert!(split.left_len > 0 && split.left_len < n);
        Ok(split)
    }
}

/// Splits `refs` at the median along the widest centroid axis (ties broken by input index, so
/// the result is a function of the input alone). Returns the size of the left half.
fn median_split(refs: &mut [Ref], centroid_bounds: &Aabb) -> usize {
    sort_on(refs, widest_axis(centroid_bounds.extent()));
    refs.len() / 2
}

/// Sorts by centroid on `axis`, ties by input index (so the order is a function of the input).
pub(crate) fn sort_on(refs: &mut [Ref], axis: usize) {
    refs.sort_unstable_by(|a, b| {
        let (ca, cb) = (a.center()[axis], b.center()[axis]);
        ca.total_cmp(&cb).then(a.id().cmp(&b.id()))
    });
}

/// Stable partition of `src` into `dst` by `goes_left` (called with each centroid), given
/// how many go left: those fill `dst[..n_left]`, the rest `dst[n_left..]`, each side in its
/// order in `src`. Returns the centroid bounds of both sides.
pub(crate) fn partition_into<F>(
    src: &[Ref],
    dst: &mut [Ref],
    n_left: usize,
    goes_left: F,
) -> (Aabb, Aabb)
where
    F: Fn(Vec3A) -> bool,
{
    let (l, r) = dst.split_at_mut(n_left);
    scatter(src, l, r, &goes_left)
}

/// [`partition_into`] by all threads, given how many of each [`CHUNK`] of `src` go left:
/// every chunk writes its own ranges of both sides, so the output is the serial one.
pub(crate) fn par_partition_into<F>(
    src: &[Ref],
    dst: &mut [Ref],
    chunk_left: &[usize],
    goes_left: F,
) -> (Aabb, Aabb)
where
    F: Fn(Vec3A) -> bool + Sync,
{
    let n_left: usize = chunk_left.iter().sum();
    let (mut ls, mut rs) = dst.split_at_mut(n_left);
    let mut parts = Vec::with_capacity(chunk_left.len());
    for (ch, &c) in src.chunks(CHUNK).zip(chunk_left) {
        let (l, lrest) = std::mem::take(&mut ls).split_at_mut(c);
        let (r, rrest) = std::mem::take(&mut rs).split_at_mut(ch.len() - c);
        ls = lrest;
        rs = rrest;
        parts.push((ch, l, r));
    }
    parts
        .into_par_iter()
        .map(|(ch, l, r)| scatter(ch, l, r, &goes_left))
        .reduce(
            || (Aabb::EMPTY, Aabb::EMPTY),
            |a, b| (a.0.union(&b.0), a.1.union(&b.1)),
        )
}

/// Writes the references of `src` that go left to `l`, the others to `r`, in order; the
/// lengths of `l` and `r` are the counts (a mismatch panics on the index).
fn scatter<F>(src: &[Ref], l: &mut [Ref], r: &mut [Ref], goes_left: &F) -> (Aabb, Aabb)
where
    F: Fn(Vec3A) -> bool,
{
    let mut sides = [Side::new(l), Side::new(r)];
    by_side(
        src,
        |x| goes_left(x.center()),
        |left, x| sides[!left as usize].push(x),
    );
    let [l, r] = sides;
    debug_assert_eq!(
        (l.at, r.at),
        (l.out.len(), r.out.len()),
        "the counts must match the partition"
    );
    (l.centroids, r.centroids)
}

/// Hands every reference of `refs` to `sink` with the side it goes to (`true`: left), each
/// side's references in their order in `refs`; what a stable partition needs.
///
/// Which side a reference goes to follows the input's order, and in many inputs no branch
/// predictor learns it: on the snowden scan a partition loop branching on it mispredicted so
/// often that the whole tree built 1.4 times slower (1 thread, `build_phases`). So each block
/// of 64 is decided first into a bit mask, without branches, and then each side's references
/// go out by walking its bits (the branches left are the loops' exits, a few per block).
#[inline(always)]
pub(crate) fn by_side(
    refs: &[Ref],
    goes_left: impl Fn(&Ref) -> bool,
    mut sink: impl FnMut(bool, &Ref),
) {
    for block in refs.chunks(BLOCK) {
        let mut left = 0u64;
        for (i, x) in block.iter().enumerate() {
            left |= (goes_left(x) as u64) << i;
        }
        let mut bits = left;
        while bits != 0 {
            sink(true, &block[bits.trailing_zeros() as usize]);
            bits &= bits - 1;
        }
        let mut bits = !left & (u64::MAX >> (BLOCK - block.len()));
        while bits != 0 {
            sink(false, &block[bits.trailing_zeros() as usize]);
            bits &= bits - 1;
        }
    }
}

/// References [`by_side`] decides at once (one bit each of a `u64`).
const BLOCK: usize = 64;

/// One side of a partition being written: its output, how much is written, and the
/// centroid bounds of what is.
struct Side<'a> {
    out: &'a mut [Ref],
    at: usize,
    centroids: Aabb,
}

impl<'a> Side<'a> {
    fn new(out: &'a mut [Ref]) -> Self {
        Side {
            out,
            at: 0,
            centroids: Aabb::EMPTY,
        }
    }

    /// Appends `x`.
    #[inline(always)]
    fn push(&mut self, x: &Ref) {
        self.out[self.at] = *x;
        self.at += 1;
        self.centroids.grow(x.center());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `partition_into` against the stable partition written out plainly, over lengths
    /// around the block size and sides in random order, in runs, and all on one side.
    #[test]
    fn partition_is_the_stable_one_with_each_sides_centroid_bounds() {
        let boxes = crate::testing::soup_bounds(700, 7);
        let refs: Vec<Ref> = boxes.iter().zip(0..).map(|(b, i)| Ref::new(b, i)).collect();
        let mut rng = crate::rng::Rng::new(3);
        let random: Vec<bool> = (0..refs.len()).map(|_| rng.next_u64() & 1 == 0).collect();
        let patterns: [&dyn Fn(usize) -> bool; 4] =
            [&|i| random[i], &|i| (i / 37) % 2 == 0, &|_| true, &|_| {
                false
            }];
        for n in [0, 1, 5, 63, 64, 65, 128, 129, 700] {
            let src = &refs[..n];
            for side in patterns {
                // The side is a function of the centroid here, as the builders' planes are.
                let left_ids: Vec<u32> = src
                    .iter()
                    .map(|r| r.id())
                    .filter(|&i| side(i as usize))
                    .collect();
                let goes_left = |c: Vec3A| {
                    let i = src.iter().position(|r| r.center() == c).unwrap();
                    side(src[i].id() as usize)
                };
                let mut dst = vec![Ref::new(&Aabb::EMPTY, u32::MAX); n];
                let (cl, cr) = partition_into(src, &mut dst, left_ids.len(), goes_left);
                let want: Vec<u32> = left_ids
                    .iter()
                    .copied()
                    .chain(src.iter().map(|r| r.id()).filter(|&i| !side(i as usize)))
                    .collect();
                let got: Vec<u32> = dst.iter().map(|r| r.id()).collect();
                assert_eq!(got, want, "n {n}");
                let (l, r) = dst.split_at(left_ids.len());
                assert_eq!(refs_bounds(l).1, cl, "n {n}");
                assert_eq!(refs_bounds(r).1, cr, "n {n}");
            }
        }
    }
}
