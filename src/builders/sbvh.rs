//! Spatial-split BVH (Stich, Friedrich and Dietrich 2009): a top-down SAH build whose nodes
//! choose between the best binned object split (references partitioned by centroid) and,
//! where the object split's children overlap, the best binned spatial split (references cut
//! at a plane, a straddling one going to both sides as two clipped references).
//!
//! - Object splits: `config.bins` bins per axis over the centroids, as the binned builder.
//! - Spatial splits: [`SPATIAL_BINS`] bins along one axis, the best object split's (the
//!   widest if there is none), tried only in nodes of at least [`MIN_SPATIAL`] references
//!   whose object split's children overlap by more than [`ALPHA`] × the root's surface
//!   area. Each reference is clipped into every bin it straddles; entry and exit counts per
//!   bin give each plane's child counts. The bins only rank the planes, so
//!   they are filled in plain f32 (each plane a triangle crosses is cut once); the chosen
//!   plane's straddling references are then clipped exactly, and only those pieces reach the
//!   tree. The axis, the bin counts and the smallest node were chosen by build time against
//!   tree quality (README, "Spatial splits"): 32 bins on all three axes in every node cost 9
//!   to 18 times the default build even with this binning.
//! - Reference unsplitting (Stich §4.3): a straddling reference goes wholly to one side when
//!   that is cheaper than duplicating it.
//! - Budget: the tree holds at most `n + floor(BUDGET × n)` references. A node may take only
//!   a spatial split that duplicates no more references than its share of the budget, and
//!   what is left is shared by its children in proportion to their reference counts (floor
//!   to the left, the rest to the right), so it depends on nothing but the input.
//! - Clipping ([`Clip`]): a reference's box is cut at the plane; for triangles, the box of
//!   the triangle's part on each side (vertices on that side and the edges' crossings with
//!   the plane, rounded outwards) is intersected with it, which is tighter.
//!
//! Deterministic for any thread count: bins are merged by exact min/max and integer sums,
//! partitions and unsplitting walk references in their order, subtrees are built by
//! `rayon::join` and concatenated left then right.
//!
//! Splits are scored by the plain SAH whatever `config.cost_model` says.

use super::binned::Binned;
use super::recurse::{by_side, serial_subtree, take_split, Ref};
use super::{widest_axis, BuildConfig, BuildNode, NodeKind, MEDIAN_DEPTH};
use crate::geometry::{Aabb, Triangle};
use glam::{BVec3A, Vec3A};
use rayon::prelude::*;

/// Spatial bins along the one axis a node's spatial pass tries. A long triangle is clipped
/// at nearly every plane of every node it reaches, so the pass costs about this many
/// clippings per reference: with 16 (and 8 below 256 references) the high-quality build of
/// long, crossing triangles took 4.8 times the default build's instructions, with 8 3.95
/// times, for trees of 0.2-0.6% higher SAH cost (README, "Spatial splits").
pub(crate) const SPATIAL_BINS: usize = 8;

/// Nodes of fewer references try no spatial split (and go to the binned builder's
/// recursion). From 64 to 128 took a twelfth of the high-quality build's instructions on
/// long, crossing triangles; of the trees measured only that scene's changed (SAH 7472.4 ->
/// 7488.7; gears, rings and snowden the same trees).
const MIN_SPATIAL: usize = 128;

/// Spatial splits are tried where the object split's children overlap by more than this
/// share of the root's surface area (Stich's α).
pub(crate) const ALPHA: f32 = 1e-5;

/// Extra references the whole tree may hold, per primitive: at most `1.3 n` in all.
pub(crate) const BUDGET: f64 = 0.3;

/// Below this many references a subtree is built on the current thread.
const TASK_CUTOFF: usize = 2048;

/// From this many references a node's bins are filled chunk by chunk on all threads.
const PAR_BINNING: usize = 32 * 1024;
const CHUNK: usize = 8 * 1024;

/// How many references ahead the spatial pass asks for a triangle's memory.
const AHEAD: usize = 8;

/// The geometry a spatial split clips: primitive boxes only, or triangles by input index
/// (`None` for a primitive without one: its box is clipped).
#[derive(Clone, Copy)]
pub(crate) enum Clip<'a> {
    /// Clip the reference's box (valid for any primitive).
    Boxes,
    /// Clip the triangle, then intersect with the reference's box.
    Triangles(super::Triangles<'a>),
}

impl Clip<'_> {
    /// The parts of reference `id` (current box `cur`) below and above the plane
    /// `x[axis] = p`; either may be empty.
    fn split(&self, id: u32, cur: &Aabb, axis: usize, p: f32) -> (Aabb, Aabb) {
        let mut l = *cur;
        let mut r = *cur;
        l.max[axis] = l.max[axis].min(p);
        r.min[axis] = r.min[axis].max(p);
        if let Clip::Triangles(tris) = self {
            if let Some(t) = (tris.get)(id) {
                let (tl, tr) = clip_triangle(&t, axis, p);
                l = intersect(&l, &tl);
                r = intersect(&r, &tr);
            }
        }
        (l, r)
    }
}

/// The common part of two boxes (empty when they do not meet).
fn intersect(a: &Aabb, b: &Aabb) -> Aabb {
    Aabb {
        min: a.min.max(b.min),
        max: a.max.min(b.max),
    }
}

/// Boxes around the parts of `t` with `x[axis] <= p` and `x[axis] >= p`: the vertices on each
/// side (a vertex on the plane on both) and every edge's crossing with the plane. The
/// crossing is computed in f64 and its off-axis coordinates widened by a bound on that
/// computation's error, then rounded outwards to f32 and kept within the edge's own range, so
/// each box contains its part of the exact triangle; on the axis itself the crossing is `p`.
pub(crate) fn clip_triangle(t: &Triangle, axis: usize, p: f32) -> (Aabb, Aabb) {
    let mut l = Aabb::EMPTY;
    let mut r = Aabb::EMPTY;
    for i in 0..3 {
        let (a, b) = (t.v[i], t.v[(i + 1) % 3]);
        if a[axis] <= p {
            l.grow(a);
        }
        if a[axis] >= p {
            r.grow(a);
        }
        if (a[axis] < p && b[axis] > p) || (a[axis] > p && b[axis] < p) {
            let (lo, hi) = crossing(a, b, axis, p);
            for c in [lo, hi] {
                l.grow(c);
                r.grow(c);
            }
        }
    }
    (l, r)
}

/// Lower and upper corners of a box around the point where segment `a`–`b` (one end strictly
/// on each side) crosses `x[axis] = p`.
fn crossing(a: Vec3A, b: Vec3A, axis: usize, p: f32) -> (Vec3A, Vec3A) {
    let (a0, b0, p) = (a[axis] as f64, b[axis] as f64, p as f64);
    let s = (p - a0) / (b0 - a0);
    let mut lo = Vec3A::ZERO;
    let mut hi = Vec3A::ZERO;
    for k in 0..3 {
        if k == axis {
            lo[k] = p as f32;
            hi[k] = p as f32;
            continue;
        }
        let (ak, bk) = (a[k] as f64, b[k] as f64);
        let x = ak + s * (bk - ak);
        // A few roundings of at most 2^-53 relative each, on terms no larger than |a| + |b|.
        let err = 16.0 * f64::EPSILON * (ak.abs() + bk.abs());
        let (emin, emax) = (a[k].min(b[k]), a[k].max(b[k]));
        lo[k] = down(x - err).max(emin);
        hi[k] = up(x + err).min(emax);
    }
    (lo, hi)
}

/// The largest f32 at or below `x`.
fn down(x: f64) -> f32 {
    let f = x as f32;
    if f as f64 > x {
        f.next_down()
    } else {
        f
    }
}

/// The smallest f32 at or above `x`.
fn up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x {
        f.next_up()
    } else {
        f
    }
}

/// Builds the tree over `idx` (finite primitives, at least one); returns the nodes in preorder
/// and the leaves' primitive indices in order (a spatially split primitive appears once in
/// each leaf that holds a piece of it).
pub(crate) fn build(
    bounds: &[Aabb],
    idx: Vec<u32>,
    config: &BuildConfig,
    clip: Clip<'_>,
) -> (Vec<BuildNode>, Vec<u32>) {
    let n = idx.len();
    assert!(
        ((n as f64) * (1.0 + BUDGET)) < (u32::MAX / 2) as f64,
        "too many primitives for 32-bit node indices"
    );
    let refs: Vec<Ref> = idx
        .par_iter()
        .map(|&i| Ref::new(&bounds[i as usize], i))
        .collect();
    let root = union_par(&refs);
    let job = Job {
        config,
        clip,
        min_overlap: ALPHA * root.half_area(),
    };
    let budget = (n as f64 * BUDGET).floor() as usize;
    let mut out = Out::default();
    let cent = centroids(&refs);
    let side = Side {
        refs,
        bounds: root,
        cent,
    };
    job.node(side, budget, 0, &mut out);
    (out.nodes, out.ids)
}

/// A subtree's nodes (links and leaf ranges relative to its own arrays) and leaf order.
#[derive(Default)]
struct Out {
    nodes: Vec<BuildNode>,
    ids: Vec<u32>,
}

impl Out {
    /// Appends `o`, moving its links and leaf ranges to where it now lies.
    fn append(&mut self, o: Out) {
        let (dn, di) = (self.nodes.len() as u32, self.ids.len() as u32);
        self.nodes.extend(o.nodes.into_iter().map(|mut n| {
            n.kind = match n.kind {
                NodeKind::Inner { left, right } => NodeKind::Inner {
                    left: left + dn,
                    right: right + dn,
                },
                NodeKind::Leaf { first, count } => NodeKind::Leaf {
                    first: first + di,
                    count,
                },
            };
            n
        }));
        self.ids.extend(o.ids);
    }

    fn leaf(&mut self, bounds: Aabb, refs: &[Ref]) {
        self.nodes.push(BuildNode {
            bounds,
            kind: NodeKind::Leaf {
                first: self.ids.len() as u32,
                count: refs.len() as u32,
            },
        });
        self.ids.extend(refs.iter().map(Ref::id));
    }
}

fn union(refs: &[Ref]) -> Aabb {
    refs.iter().fold(Aabb::EMPTY, |b, r| b.union(&r.bounds()))
}

fn union_par(refs: &[Ref]) -> Aabb {
    refs.par_chunks(CHUNK)
        .map(union)
        .reduce(|| Aabb::EMPTY, |a, b| a.union(&b))
}

fn centroids(refs: &[Ref]) -> Aabb {
    let one = |ch: &[Ref]| {
        let mut c = Aabb::EMPTY;
        ch.iter().for_each(|r| c.grow(r.center()));
        c
    };
    if refs.len() >= PAR_BINNING {
        refs.par_chunks(CHUNK)
            .map(one)
            .reduce(|| Aabb::EMPTY, |a, b| a.union(&b))
    } else {
        one(refs)
    }
}

/// A node's references with their box and centroid box. A split grows its sides' boxes as
/// it pushes the references, so no pass over a child's references recomputes them.
struct Side {
    refs: Vec<Ref>,
    bounds: Aabb,
    cent: Aabb,
}

impl Side {
    fn with_capacity(n: usize) -> Side {
        Side {
            refs: Vec::with_capacity(n),
            bounds: Aabb::EMPTY,
            cent: Aabb::EMPTY,
        }
    }

    /// `refs` with their boxes computed by a pass over them.
    fn of(refs: Vec<Ref>) -> Side {
        let (bounds, cent) = (union(&refs), centroids(&refs));
        Side { refs, bounds, cent }
    }

    #[inline]
    fn push(&mut self, r: Ref) {
        self.bounds = self.bounds.union(&r.bounds());
        self.cent.grow(r.center());
        self.refs.push(r);
    }

    fn len(&self) -> usize {
        self.refs.len()
    }
}

/// A node's two sides after a split.
struct Children {
    left: Side,
    right: Side,
    /// References made by duplication (`left.len() + right.len() - n`).
    dups: usize,
}

struct Job<'a> {
    config: &'a BuildConfig,
    clip: Clip<'a>,
    /// `ALPHA` × the root's half area.
    min_overlap: f32,
}

impl Job<'_> {
    /// Builds the subtree over `side` (`budget` extra references allowed).
    fn node(&self, side: Side, budget: usize, depth: usize, out: &mut Out) {
        let Side {
            mut refs,
            bounds,
            cent,
        } = side;
        let n = refs.len();
        if n < MIN_SPATIAL || (budget == 0 && n < TASK_CUTOFF) {
            // No spatial split can be tried below here, and the object splits are the binned
            // builder's: its recursion builds the same subtree without a vector per node. It
            // runs on this thread, so a large node out of budget first splits on here, as tasks.
            let (nodes, ids) = (&mut out.nodes, &mut out.ids);
            let subtree = (bounds, cent);
            return serial_subtree(&Binned, self.config, &mut refs, subtree, depth, nodes, ids);
        }
        let split = if n == 1 || depth >= MEDIAN_DEPTH {
            None
        } else {
            self.split(&refs, &bounds, &cent, budget)
        };
        let split = match split {
            Some(s) => s,
            None if n <= self.config.max_leaf_size => return out.leaf(bounds, &refs),
            None => median(&mut refs),
        };
        let Children { left, right, dups } = split;
        let rest = budget - dups;
        let lb = (rest as u128 * left.len() as u128 / (left.len() + right.len()) as u128) as usize;
        let rb = rest - lb;
        let me = out.nodes.len();
        out.nodes.push(BuildNode {
            bounds,
            kind: NodeKind::Inner {
                left: me as u32 + 1,
                right: 0,
            },
        });
        let depth = depth + 1;
        let right_at = if n >= TASK_CUTOFF {
            let (lo, ro) = rayon::join(
                || {
                    let mut o = Out::default();
                    self.node(left, lb, depth, &mut o);
                    o
                },
                || {
                    let mut o = Out::default();
                    self.node(right, rb, depth, &mut o);
                    o
                },
            );
            out.append(lo);
            let at = out.nodes.len();
            out.append(ro);
            at
        } else {
            self.node(left, lb, depth, out);
            let at = out.nodes.len();
            self.node(right, rb, depth, out);
            at
        };
        out.nodes[me].kind = NodeKind::Inner {
            left: me as u32 + 1,
            right: right_at as u32,
        };
    }

    /// The cheaper of the best object and (where called for) spatial split, if it beats a
    /// leaf or `refs` is too many for one.
    fn split(&self, refs: &[Ref], node: &Aabb, cent: &Aabb, budget: usize) -> Option<Children> {
        let n = refs.len();
        let object = object_split(self.config, refs, cent);
        let overlapping = object.as_ref().is_none_or(|o| {
            let common = intersect(&o.lbox, &o.rbox);
            !common.is_empty() && common.half_area() > self.min_overlap
        });
        let spatial = if budget > 0 && n >= MIN_SPATIAL && overlapping {
            self.spatial_split(refs, node, budget, object.as_ref().map(|o| o.axis))
        } else {
            None
        };
        let object_cost = object.as_ref().map_or(f32::INFINITY, |o| o.cost);
        match spatial {
            Some(s) if s.cost < object_cost => {
                if !take_split(self.config, node.half_area(), s.cost, n) {
                    return None;
                }
                Some(self.spatial_partition(refs, &s))
            }
            _ => {
                let o = object?;
                if !take_split(self.config, node.half_area(), o.cost, n) {
                    return None;
                }
                let mut sides = [Side::with_capacity(o.nl), Side::with_capacity(n - o.nl)];
                let goes_left = |r: &Ref| o.map.bin(r.center()[o.axis], o.axis) < o.bin;
                by_side(refs, goes_left, |l, r| sides[!l as usize].push(*r));
                let [left, right] = sides;
                Some(Children {
                    left,
                    right,
                    dups: 0,
                })
            }
        }
    }

    /// The best spatial split of `refs` over `node` along `object_axis` (the best object
    /// split's, if any) that duplicates at most `budget` references.
    fn spatial_split(
        &self,
        refs: &[Ref],
        node: &Aabb,
        budget: usize,
        object_axis: Option<usize>,
    ) -> Option<SpatialPlane> {
        let n = refs.len();
        let k = SPATIAL_BINS;
        let tests = |n| self.config.tests(n);
        let ext = node.extent();
        // One axis: the object split's (where the references are spread, so a plane there
        // separates most of them), or the widest when there is none. Binning all three cost
        // about three times as much for trees of about the same SAH (README).
        let axis = object_axis.unwrap_or_else(|| widest_axis(ext));
        if ext[axis] <= 0.0 {
            return None;
        }
        let grid = Grid::new(node, axis);
        let fill = |ch: &[Ref]| {
            let mut bins = [SBin::EMPTY; SPATIAL_BINS];
            for (i, r) in ch.iter().enumerate() {
                if let (Clip::Triangles(tris), Some(ahead)) = (self.clip, ch.get(i + AHEAD)) {
                    (tris.soon)(ahead.id());
                }
                let b = r.bounds();
                let span = (grid.bin(b.min[axis]), grid.bin(b.max[axis]));
                // A reference within one slab needs no triangle (a gather from the input)
                // and no clipping.
                let tri = match self.clip {
                    Clip::Triangles(tris) if span.0 != span.1 => (tris.get)(r.id()),
                    _ => None,
                };
                bin_pieces(&mut bins, &grid, span, &b, tri.as_ref());
            }
            bins
        };
        let merge = |a: [SBin; SPATIAL_BINS], b: [SBin; SPATIAL_BINS]| {
            std::array::from_fn(|j| a[j].merge(&b[j]))
        };
        let bins = if n >= PAR_BINNING {
            refs.par_chunks(CHUNK)
                .map(fill)
                .reduce(|| [SBin::EMPTY; SPATIAL_BINS], merge)
        } else {
            fill(refs)
        };
        let bin = |j: usize| {
            let b = &bins[j];
            (b.bounds, b.enter as usize, b.exit as usize)
        };
        let mut best: Option<SpatialPlane> = None;
        planes(k, bin, |j, (lbox, nl), (rbox, nr)| {
            if nl == 0 || nr == 0 || nl + nr - n > budget {
                return;
            }
            let cost = lbox.half_area() * tests(nl) + rbox.half_area() * tests(nr);
            if best.as_ref().is_none_or(|b| cost < b.cost) {
                best = Some(SpatialPlane {
                    grid,
                    bin: j,
                    cost,
                    lbox,
                    rbox,
                    nl,
                    nr,
                });
            }
        });
        best
    }

    /// Splits `refs` at `s`'s plane: references wholly on one side go there, straddling ones
    /// go to both sides clipped, or wholly to one side where that costs less (unsplitting).
    fn spatial_partition(&self, refs: &[Ref], s: &SpatialPlane) -> Children {
        let (axis, p) = (s.grid.axis, s.grid.plane(s.bin));
        let (mut lbox, mut rbox) = (s.lbox, s.rbox);
        let (mut nl, mut nr) = (s.nl as f32, s.nr as f32);
        let mut left = Side::with_capacity(s.nl);
        let mut right = Side::with_capacity(s.nr);
        for r in refs {
            let b = r.bounds();
            let (first, last) = (s.grid.bin(b.min[axis]), s.grid.bin(b.max[axis]));
            if last < s.bin {
                left.push(*r);
            } else if first >= s.bin {
                right.push(*r);
            } else {
                let (l, rr) = self.clip.split(r.id(), &b, axis, p);
                if rr.is_empty() {
                    left.push(*r);
                    nr -= 1.0;
                    continue;
                }
                if l.is_empty() {
                    right.push(*r);
                    nl -= 1.0;
                    continue;
                }
                let (la, ra) = (lbox.half_area(), rbox.half_area());
                let split = la * nl + ra * nr;
                let all_left = lbox.union(&b).half_area() * nl + ra * (nr - 1.0);
                let all_right = la * (nl - 1.0) + rbox.union(&b).half_area() * nr;
                if all_left < split && all_left <= all_right {
                    left.push(*r);
                    lbox = lbox.union(&b);
                    nr -= 1.0;
                } else if all_right < split {
                    right.push(*r);
                    rbox = rbox.union(&b);
                    nl -= 1.0;
                } else {
                    left.push(Ref::new(&l, r.id()));
                    right.push(Ref::new(&rr, r.id()));
                }
            }
        }
        // Unsplitting or an empty piece can leave a side empty: then split by the object
        // median instead (no duplication).
        if left.refs.is_empty() || right.refs.is_empty() {
            let mut all = refs.to_vec();
            return median(&mut all);
        }
        let dups = left.len() + right.len() - refs.len();
        Children { left, right, dups }
    }
}

/// Adds reference `b` (of triangle `tri`, if it has one) to the spatial bins `row` of `grid`:
/// one entry where it starts, one exit where it ends, and its piece in each slab it spans
/// grown into that slab's box.
///
/// The pieces only rank the planes; the chosen plane's children are clipped again exactly
/// (`Clip::split`, in f64, rounded outwards), and only those boxes reach the tree. So this
/// clips in plain f32: each plane the triangle crosses is cut once (its edges' crossings),
/// and a slab's piece is the crossings at its two planes and the vertices between them.
#[inline]
fn bin_pieces(
    row: &mut [SBin],
    grid: &Grid,
    (first, last): (usize, usize),
    b: &Aabb,
    tri: Option<&Triangle>,
) {
    let axis = grid.axis;
    row[first].enter += 1;
    row[last].exit += 1;
    if first == last {
        row[first].bounds = row[first].bounds.union(b);
        return;
    }
    // Writing one lane of a vector at a run-time index goes through memory and stalls the
    // load that follows, so the slab's planes are set by a lane mask instead.
    let on_axis = Vec3A::AXES[axis].cmpne(Vec3A::ZERO);
    let at = |x: Vec3A, p: f32| Vec3A::select(on_axis, Vec3A::splat(p), x);
    // The slab of bin `j` intersected with `b`: the first and last slabs keep `b`'s ends.
    let slab = |j: usize, lo: f32, hi: f32| Aabb {
        min: if j > first { at(b.min, lo) } else { b.min },
        max: if j < last { at(b.max, hi) } else { b.max },
    };
    let Some(t) = tri else {
        let mut lo = grid.plane(first);
        for (j, bin) in row.iter_mut().enumerate().take(last + 1).skip(first) {
            let hi = grid.plane(j + 1);
            bin.bounds = bin.bounds.union(&slab(j, lo, hi));
            lo = hi;
        }
        return;
    };
    // The vertices in order along the axis: a plane strictly between the lowest and the
    // highest crosses the long edge and one of the two short ones, at points that move
    // linearly with the plane, so each edge needs one division per triangle, not per plane.
    let mut v = t.v;
    if v[0][axis] > v[1][axis] {
        v.swap(0, 1);
    }
    if v[1][axis] > v[2][axis] {
        v.swap(1, 2);
    }
    if v[0][axis] > v[1][axis] {
        v.swap(0, 1);
    }
    let [lo, mid, hi] = v;
    let (x_lo, x_mid, x_hi) = (lo[axis], mid[axis], hi[axis]);
    let slope = |p: Vec3A, q: Vec3A, d: f32| if d > 0.0 { (q - p) / d } else { Vec3A::ZERO };
    let long = slope(lo, hi, x_hi - x_lo);
    let low = slope(lo, mid, x_mid - x_lo);
    let high = slope(mid, hi, x_hi - x_mid);
    let cut = |p: f32| {
        if p > x_lo && p < x_hi {
            let a = lo + long * (p - x_lo);
            let c = if p < x_mid {
                lo + low * (p - x_lo)
            } else {
                mid + high * (p - x_mid)
            };
            Aabb {
                min: at(a.min(c), p),
                max: at(a.max(c), p),
            }
        } else {
            Aabb::EMPTY
        }
    };
    // A vertex outside the reference's range (the reference is a piece already) counts in
    // its end slab, as clipping at the planes inside the range would count it; the
    // intersection with `b` then trims it.
    let vb = |x: f32| grid.bin(x).clamp(first, last);
    let vbin = [vb(x_lo), vb(x_mid), vb(x_hi)];
    let mut below = Aabb::EMPTY;
    let mut p_lo = grid.plane(first);
    for (j, slot) in row.iter_mut().enumerate().take(last + 1).skip(first) {
        let mut piece = below;
        for (&vj, &x) in vbin.iter().zip(&v) {
            if vj == j {
                piece.grow(x);
            }
        }
        let p_hi = grid.plane(j + 1);
        if j < last {
            below = cut(p_hi);
            piece = piece.union(&below);
        }
        let piece = intersect(&piece, &slab(j, p_lo, p_hi));
        // An empty piece (its corners crossed) must not widen the bin; selected rather than
        // branched on, as whether a piece is empty is hard to predict.
        let keep = BVec3A::splat(!piece.is_empty());
        let bin = &mut slot.bounds;
        bin.min = Vec3A::select(keep, bin.min.min(piece.min), bin.min);
        bin.max = Vec3A::select(keep, bin.max.max(piece.max), bin.max);
        p_lo = p_hi;
    }
}

/// Splits at the median along the widest centroid axis (ties by input index).
fn median(refs: &mut Vec<Ref>) -> Children {
    let axis = widest_axis(centroids(refs).extent());
    refs.sort_unstable_by(|a, b| {
        let (ca, cb) = (a.center()[axis], b.center()[axis]);
        ca.total_cmp(&cb).then(a.id().cmp(&b.id()))
    });
    let right = refs.split_off(refs.len() / 2);
    Children {
        left: Side::of(std::mem::take(refs)),
        right: Side::of(right),
        dups: 0,
    }
}

/// Object bins on all axes over the centroid box.
struct Mapper {
    origin: Vec3A,
    scale: Vec3A,
    k: usize,
}

impl Mapper {
    #[inline]
    fn bin(&self, c: f32, axis: usize) -> usize {
        bin_of((c - self.origin[axis]) * self.scale[axis], self.k)
    }
}

#[derive(Clone, Copy)]
struct OBin {
    bounds: Aabb,
    count: u32,
}

struct ObjectPlane {
    map: Mapper,
    axis: usize,
    /// First bin of the right side.
    bin: usize,
    cost: f32,
    lbox: Aabb,
    rbox: Aabb,
    nl: usize,
}

/// The cheapest binned object split of `refs` (centroid box `cent`, `config.bins` bins per
/// axis), or `None` when every centroid is in one place.
fn object_split(config: &BuildConfig, refs: &[Ref], cent: &Aabb) -> Option<ObjectPlane> {
    let (k, tests) = (config.bins, |n| config.tests(n));
    let e = cent.extent();
    let scale = Vec3A::select(
        e.cmpgt(Vec3A::ZERO),
        Vec3A::splat(k as f32 * (1.0 - 1e-6)) / e,
        Vec3A::ZERO,
    );
    let map = Mapper {
        origin: cent.min,
        scale,
        k,
    };
    let empty = OBin {
        bounds: Aabb::EMPTY,
        count: 0,
    };
    let fill = |ch: &[Ref]| {
        let mut bins = vec![empty; 3 * k];
        for r in ch {
            let (b, c) = (r.bounds(), r.center());
            for axis in 0..3 {
                let bin = &mut bins[axis * k + map.bin(c[axis], axis)];
                bin.bounds = bin.bounds.union(&b);
                bin.count += 1;
            }
        }
        bins
    };
    let merge = |a: Vec<OBin>, b: Vec<OBin>| -> Vec<OBin> {
        a.iter()
            .zip(&b)
            .map(|(x, y)| OBin {
                bounds: x.bounds.union(&y.bounds),
                count: x.count + y.count,
            })
            .collect()
    };
    let bins = if refs.len() >= PAR_BINNING {
        refs.par_chunks(CHUNK)
            .map(fill)
            .reduce(|| vec![empty; 3 * k], merge)
    } else {
        fill(refs)
    };
    let mut best: Option<(usize, usize, f32, Aabb, Aabb, usize)> = None;
    for axis in 0..3 {
        if scale[axis] == 0.0 {
            continue;
        }
        let row = &bins[axis * k..(axis + 1) * k];
        let bin = |j: usize| (row[j].bounds, row[j].count as usize, row[j].count as usize);
        planes(k, bin, |j, (lbox, nl), (rbox, nr)| {
            if nl == 0 || nr == 0 {
                return;
            }
            let cost = lbox.half_area() * tests(nl) + rbox.half_area() * tests(nr);
            if best.is_none_or(|b| cost < b.2) {
                best = Some((axis, j, cost, lbox, rbox, nl));
            }
        });
    }
    let (axis, bin, cost, lbox, rbox, nl) = best?;
    Some(ObjectPlane {
        map,
        axis,
        bin,
        cost,
        lbox,
        rbox,
        nl,
    })
}

/// Every plane between bins `j - 1` and `j` of `k` (left to right), handed to `each` with
/// the box and reference count of its left and right side. `bin(j)` gives bin `j`'s box and
/// how many references it adds to a left side that ends at it and to a right side that starts
/// at it: its count twice for object bins, where a reference starts and where it ends for
/// spatial ones.
fn planes(
    k: usize,
    bin: impl Fn(usize) -> (Aabb, usize, usize),
    mut each: impl FnMut(usize, (Aabb, usize), (Aabb, usize)),
) {
    let mut right = vec![(Aabb::EMPTY, 0usize); k];
    let mut acc = (Aabb::EMPTY, 0usize);
    for j in (1..k).rev() {
        let (b, _, r) = bin(j);
        acc = (acc.0.union(&b), acc.1 + r);
        right[j] = acc;
    }
    let mut left = (Aabb::EMPTY, 0usize);
    for (j, &r) in right.iter().enumerate().skip(1) {
        let (b, l, _) = bin(j - 1);
        left = (left.0.union(&b), left.1 + l);
        each(j, left, r);
    }
}

/// The bin of `k` that coordinate `f` (in bin widths from the first bin's start) falls in:
/// the first below it (and for NaN, which `max` drops), the last past it. Clamped in f32
/// first, so the conversion only truncates a small number: `as usize` on an unclamped
/// float saturates in a dozen instructions, and the builds call this five times a
/// reference per spatial pass.
#[inline]
fn bin_of(f: f32, k: usize) -> usize {
    f.max(0.0).min((k - 1) as f32) as i32 as usize
}

/// Spatial bins of one axis: [`SPATIAL_BINS`] equal slabs of the node's box.
#[derive(Clone, Copy)]
struct Grid {
    axis: usize,
    lo: f32,
    /// Bins per unit length (0 for a flat box).
    scale: f32,
    /// The planes, the node's two sides included: bin `j` lies between `planes[j]` and
    /// `planes[j + 1]` (computed once: the binning asks for two a slab).
    planes: [f32; SPATIAL_BINS + 1],
}

impl Grid {
    fn new(node: &Aabb, axis: usize) -> Grid {
        let (lo, width) = (node.min[axis], node.max[axis] - node.min[axis]);
        let k = SPATIAL_BINS as f32;
        Grid {
            axis,
            lo,
            scale: if width > 0.0 { k / width } else { 0.0 },
            planes: std::array::from_fn(|j| lo + width * (j as f32 / k)),
        }
    }

    /// The plane between bins `j - 1` and `j`.
    #[inline]
    fn plane(&self, j: usize) -> f32 {
        self.planes[j]
    }

    /// The bin holding coordinate `x` (clamped into the node).
    #[inline]
    fn bin(&self, x: f32) -> usize {
        bin_of((x - self.lo) * self.scale, SPATIAL_BINS)
    }
}

#[derive(Clone, Copy)]
struct SBin {
    bounds: Aabb,
    enter: u32,
    exit: u32,
}

impl SBin {
    const EMPTY: SBin = SBin {
        bounds: Aabb::EMPTY,
        enter: 0,
        exit: 0,
    };

    fn merge(&self, o: &SBin) -> SBin {
        SBin {
            bounds: self.bounds.union(&o.bounds),
            enter: self.enter + o.enter,
            exit: self.exit + o.exit,
        }
    }
}

struct SpatialPlane {
    grid: Grid,
    /// First bin of the right side; the plane is `grid.plane(bin)`.
    bin: usize,
    cost: f32,
    lbox: Aabb,
    rbox: Aabb,
    nl: usize,
    nr: usize,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> Triangle {
        Triangle::new(a.into(), b.into(), c.into())
    }

    /// `got` contains `want` and exceeds it by no more than the outward rounding (a few
    /// ulps) on any side.
    fn around(got: Aabb, want: Aabb) {
        let slack = |x: f32| 4e-7 * (1.0 + x.abs());
        assert!(got.contains(&want), "{got:?} does not contain {want:?}");
        for k in 0..3 {
            assert!(
                want.min[k] - got.min[k] <= slack(want.min[k]),
                "{got:?} vs {want:?}"
            );
            assert!(
                got.max[k] - want.max[k] <= slack(want.max[k]),
                "{got:?} vs {want:?}"
            );
        }
    }

    #[test]
    fn clipping_a_right_triangle_gives_the_exact_pieces() {
        // (0,0,0), (4,0,0), (0,4,0): the part with x <= 1 spans y in 0..4, the part with
        // x >= 1 spans y in 0..3 (the hypotenuse x + y = 4 at x = 1); both z = 0.
        let t = tri([0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 4.0, 0.0]);
        let (l, r) = clip_triangle(&t, 0, 1.0);
        around(l, Aabb::new(Vec3A::ZERO, Vec3A::new(1.0, 4.0, 0.0)));
        around(
            r,
            Aabb::new(Vec3A::new(1.0, 0.0, 0.0), Vec3A::new(4.0, 3.0, 0.0)),
        );
        // On the split axis the pieces end exactly at the plane.
        assert_eq!((l.max.x, r.min.x), (1.0, 1.0));
        // Cut along y at 2: below, x in 0..4; above, x in 0..2 (the hypotenuse at y = 2).
        let (l, r) = clip_triangle(&t, 1, 2.0);
        around(l, Aabb::new(Vec3A::ZERO, Vec3A::new(4.0, 2.0, 0.0)));
        around(
            r,
            Aabb::new(Vec3A::new(0.0, 2.0, 0.0), Vec3A::new(2.0, 4.0, 0.0)),
        );
    }

    #[test]
    fn clipping_a_long_diagonal_sliver_is_tight_and_conservative() {
        // A sliver along the diagonal (0,0,0)–(8,8,8): a slab of x in 2..3 holds its points
        // with y and z in [2, 3] up to the sliver's width (1/64 on z at most), so the piece
        // boxes must contain that and stay far smaller than the triangle's box.
        let t = tri([0.0, 0.0, 0.0], [8.0, 8.0, 8.0], [8.0, 8.0, 8.125]);
        let (_, above_2) = clip_triangle(&t, 0, 2.0);
        let (below_3, _) = clip_triangle(&t, 0, 3.0);
        let slab = intersect(&above_2, &below_3);
        // Exact points of the triangle with x = 2 and x = 3: on edge v0-v1 (2,2,2), (3,3,3);
        // on edge v0-v2 (2,2,2.03125), (3,3,3.046875).
        // Their box is the exact part's box (the triangle is convex, so these four span it).
        around(
            slab,
            Aabb::new(Vec3A::new(2.0, 2.0, 2.0), Vec3A::new(3.0, 3.0, 3.046875)),
        );
    }

    #[test]
    fn clipped_pieces_contain_the_exact_crossings() {
        // Awkward coordinates: the crossing is not representable, the boxes must still hold
        // the exact point (checked in f64 against the rounded-outward corners).
        let mut rng = crate::rng::Rng::new(7);
        for _ in 0..10_000 {
            let (lo, hi) = (Vec3A::new(-100.0, 0.0, 0.0), Vec3A::new(100.0, 2.0, 1.0));
            let t = Triangle::new(rng.in_box(lo, hi), rng.in_box(lo, hi), rng.in_box(lo, hi));
            let p = rng.in_box(Vec3A::splat(-20.0), Vec3A::splat(20.0)).x;
            let (l, r) = clip_triangle(&t, 0, p);
            for i in 0..3 {
                let (a, b) = (t.v[i], t.v[(i + 1) % 3]);
                if (a.x < p) == (b.x < p) || a.x == p || b.x == p {
                    continue;
                }
                let s = (p as f64 - a.x as f64) / (b.x as f64 - a.x as f64);
                for k in 1..3 {
                    let x = a[k] as f64 + s * (b[k] as f64 - a[k] as f64);
                    for side in [&l, &r] {
                        assert!(
                            side.min[k] as f64 <= x && x <= side.max[k] as f64,
                            "{t:?} at {p}: {x} outside {side:?}"
                        );
                    }
                }
            }
            // Vertices land on their side, and each box stays within the slab.
            assert!(l.is_empty() || l.max.x <= p);
            assert!(r.is_empty() || r.min.x >= p);
        }
    }

    #[test]
    fn binned_pieces_match_the_exact_clipping() {
        // The spatial bins' f32 pieces only rank planes, but they should be no looser than
        // the exact clipping's (up to rounding), and empty exactly where it is empty.
        let mut rng = crate::rng::Rng::new(3);
        let node = Aabb::new(Vec3A::ZERO, Vec3A::splat(10.0));
        for _ in 0..2000 {
            let t = Triangle::new(
                rng.in_box(node.min, node.max),
                rng.in_box(node.min, node.max),
                rng.in_box(node.min, node.max),
            );
            let axis = (rng.in_box(Vec3A::ZERO, Vec3A::splat(2.999)).x) as usize;
            // A reference that is the triangle's box, or a piece of it cut on another axis.
            let cut = rng.in_box(node.min, node.max);
            let other = (axis + 1) % 3;
            let b = clip_triangle(&t, other, cut[other]).0;
            if b.is_empty() {
                continue;
            }
            let grid = Grid::new(&node, axis);
            let span = (grid.bin(b.min[axis]), grid.bin(b.max[axis]));
            let mut row = vec![SBin::EMPTY; SPATIAL_BINS];
            bin_pieces(&mut row, &grid, span, &b, Some(&t));
            for (j, bin) in row.iter().enumerate() {
                let exact = if j < span.0 || j > span.1 {
                    Aabb::EMPTY
                } else {
                    let lo = clip_triangle(&t, axis, grid.plane(j)).1;
                    let hi = clip_triangle(&t, axis, grid.plane(j + 1)).0;
                    let mut slab = b;
                    if j > span.0 {
                        slab.min[axis] = grid.plane(j);
                    }
                    if j < span.1 {
                        slab.max[axis] = grid.plane(j + 1);
                    }
                    intersect(&intersect(&lo, &hi), &slab)
                };
                assert_eq!(bin.bounds.is_empty(), exact.is_empty(), "{t:?} bin {j}");
                if exact.is_empty() {
                    continue;
                }
                // The exact pieces are boxes of the slab's part on each side, intersected;
                // the binned one is the box of the slab's part itself, so it may be smaller,
                // never larger beyond rounding.
                for k in 0..3 {
                    let slack = 1e-4;
                    assert!(bin.bounds.min[k] >= exact.min[k] - slack, "{t:?} bin {j}");
                    assert!(bin.bounds.max[k] <= exact.max[k] + slack, "{t:?} bin {j}");
                }
            }
            let (enter, exit): (u32, u32) = (
                row.iter().map(|b| b.enter).sum(),
                row.iter().map(|b| b.exit).sum(),
            );
            assert_eq!((enter, exit), (1, 1));
            assert_eq!((row[span.0].enter, row[span.1].exit), (1, 1));
        }
    }

    #[test]
    fn a_triangle_on_one_side_gives_an_empty_other_piece() {
        let t = tri([2.0, 0.0, 0.0], [3.0, 1.0, 0.0], [2.5, 0.0, 1.0]);
        let (l, r) = clip_triangle(&t, 0, 1.0);
        assert!(l.is_empty());
        assert_eq!(r, t.bounds());
        let clip = Clip::Triangles(crate::builders::Triangles {
            get: &|_| Some(t),
            soon: &|_| {},
        });
        let cur = Aabb::new(Vec3A::ZERO, Vec3A::splat(3.0));
        let (l, r) = clip.split(0, &cur, 0, 1.0);
        assert!(l.is_empty());
        assert_eq!(r, t.bounds());
    }
}
