//! Point queries: the primitives near a point ([`Bvh::point_query`], with a callback that may
//! shrink the search radius) and the closest point on a BVH's triangles
//! ([`Bvh::closest_point`], answered as a [`PointHit`]); worlds answer the same question in
//! world space (`World::closest_point`, in `world/point.rs`).
//!
//! One scalar walk per layout family, nearest child first: a node's children are ordered by
//! the distance from the point to their boxes (in f64, where no squared distance overflows or
//! underflows) and a child is entered only while its box lies within the current radius.
//! The walks read the layouts as the ray kernels do (binary nodes by their mapping's child
//! rule, 4- and 8-wide nodes by their child slots, quantized boxes dequantized conservatively,
//! SIMD triangle groups lane by lane), so every [`crate::Layout`] answers.
//!
//! A BVH built in a scaled frame (a scene far from unit size, see `frame.rs`) is walked in its
//! frame: the point comes in by the frame's power of two, radii go in and out by it (exact in
//! f64), and distances are measured between the caller's point and the found point brought
//! back to the caller's units.

use crate::builders::MAX_DEPTH;
use crate::bvh::Bvh;
use crate::geometry::{closest_uv, Triangle};
use crate::layout::bvh2::{compact_children, Addressing};
use crate::layout::tri4::groups;
use crate::layout::{Bvh2, Bvh4, Bvh8, Bvh8Node, Node4, Tri4};
use crate::primitive::{LeafFormat, Primitive};
use crate::traverse::leaves::Leaves;
use crate::traverse::stack::Stack;
use glam::{DVec3, Vec3A};

/// The closest point of a [`Bvh`]'s triangles to a query point ([`Bvh::closest_point`]).
///
/// ```
/// use quiver_rt::{point::PointHit, Bvh, Triangle};
/// use glam::Vec3A;
/// let bvh = Bvh::new(&[Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)]);
/// let hit: PointHit = bvh.closest_point(Vec3A::new(0.25, 0.5, 2.0), f32::INFINITY).unwrap();
/// assert_eq!((hit.prim, hit.point, hit.distance), (0, Vec3A::new(0.25, 0.5, 0.0), 2.0));
/// assert_eq!((hit.u, hit.v), (0.25, 0.5));
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointHit {
    /// The primitive: its index in the build's input.
    pub prim: u32,
    /// The point on it nearest the query point.
    pub point: Vec3A,
    /// Barycentric weight of the triangle's second vertex at `point`.
    pub u: f32,
    /// Barycentric weight of the triangle's third vertex at `point`.
    pub v: f32,
    /// The distance from the query point to `point`.
    pub distance: f32,
}

/// One primitive as a layout's leaf stores it: the primitive itself, or a lane of a SIMD
/// triangle group (`true`: the fast format's `v0`, `e1 = v0 - v1`, `e2 = v2 - v0`; `false`:
/// the vertices, as watertight and far groups store them).
#[derive(Clone, Copy)]
pub(crate) enum PrimAt<'a, P> {
    Prim(&'a P),
    Lane(&'a Tri4, usize, bool),
}

impl<P: Primitive> PrimAt<'_, P> {
    /// The triangle quiver tests for it, as its first vertex and the two edges from it, with
    /// the arithmetic of [`Triangle::closest_point`] (`v1 - v0 = -(v0 - v1)` exactly, so a
    /// fast group's edges are the ones it computes); `None` for a primitive without one.
    #[inline]
    fn edges(&self) -> Option<(Vec3A, Vec3A, Vec3A)> {
        let of = |t: Triangle| (t.v[0], t.v[1] - t.v[0], t.v[2] - t.v[0]);
        match *self {
            PrimAt::Prim(p) => p.triangle().map(of),
            PrimAt::Lane(g, l, true) => {
                let r = |k: usize| Vec3A::new(g.rows[k][0][l], g.rows[k][1][l], g.rows[k][2][l]);
                Some((r(0), -r(1), r(2)))
            }
            PrimAt::Lane(g, l, false) => Some(of(g.triangle(l))),
        }
    }
}

/// What a walk visits: a primitive's input index (`u32::MAX` where the layout keeps none: a
/// world's top level), the primitive, and the current radius (local units), which it may
/// shrink; false stops the walk.
pub(crate) type Visit<'v, P> = dyn FnMut(u32, PrimAt<'_, P>, &mut f64) -> bool + 'v;

/// What [`Bvh::walk_points`] visits: a primitive's input index, the primitive (in the
/// frame's units), the point in the frame, the radius in the caller's units (which it may
/// shrink), and the factor from frame to caller units; false stops the walk.
pub(crate) type FramedVisit<'v, P> =
    dyn FnMut(u32, PrimAt<'_, P>, Vec3A, &mut f64, f64) -> bool + 'v;

/// A stack entry: a node to enter or a leaf (first, count) to visit, behind its squared box
/// distance.
#[derive(Clone, Copy)]
enum Item {
    Node(u32),
    Leaf(u32, u32),
}

/// The walks' stack: at most the (up to eight) children of every node on the path from the
/// root pushed at once, and trees are at most [`MAX_DEPTH`] deep. A fixed array rather than a
/// heap allocation per query (a world's query walks one tree per instance it enters).
type PointStack = Stack<(f64, Item), { 7 * MAX_DEPTH + 8 }>;

/// The squared distance from `p` to the box `min..max` in f64 (no square root per child:
/// the walk compares squares): [`box_distances2`] of one box. Infinite for an empty
/// (inverted) box; a NaN coordinate gives no gap on its axis, so such a box is kept (a
/// superset: what it holds is still measured, and a NaN distance never wins).
#[inline]
fn box_distance2(min: Vec3A, max: Vec3A, p: Vec3A) -> f64 {
    let planes = [min.x, min.y, min.z, max.x, max.y, max.z].map(|c| [c]);
    box_distances2::<1>(&planes, p)[0]
}

/// The squared distances from `p` to a wide node's `W` child boxes (`planes`: min x, y, z and
/// max x, y, z, one lane per child), lane by lane so the compiler makes one vector operation
/// of each step (comparisons rather than `f32::max`, whose NaN rule costs a blend per step:
/// the planes are never NaN, and an empty slot's infinite planes give an infinite distance
/// either way).
#[inline]
fn box_distances2<const W: usize>(planes: &[[f32; W]; 6], p: Vec3A) -> [f64; W] {
    let mut d2 = [0.0; W];
    for (k, d2) in d2.iter_mut().enumerate() {
        let gap = |axis: usize, c: f32| {
            let (below, above) = (planes[axis][k] - c, c - planes[axis + 3][k]);
            let g = if below > above { below } else { above };
            (if g > 0.0 { g } else { 0.0 }) as f64
        };
        let (x, y, z) = (gap(0, p.x), gap(1, p.y), gap(2, p.z));
        *d2 = x * x + y * y + z * z;
    }
    d2
}

/// Whether the triangle `v` may have a point within `r` of `p`: the squared distance to its
/// box, with a slack of a few ulps of the coordinates (for vertices rebuilt from edges, and
/// for the rounding of the point a measure computes on it). A cheap test before
/// [`closest_uv`]'s exact one: in a leaf, most triangles lie beyond the radius.
#[inline]
pub(crate) fn may_reach(v: [Vec3A; 3], p: Vec3A, r: f64) -> bool {
    let (min, max) = (v[0].min(v[1]).min(v[2]), v[0].max(v[1]).max(v[2]));
    let size = min.abs().max(max.abs()).max(p.abs()).max_element() as f64;
    let reach = r + (r + size) * (1.0 / (1u64 << 20) as f64);
    box_distance2(min, max, p) <= reach * reach
}

/// The best-first walk all layouts share: pops the nearest pending item, drops it when its
/// box lies beyond the radius, expands a node with `children` (which pushes the children
/// whose squared box distance is at most the squared reach it is given, behind that distance)
/// and visits a leaf with `leaf`. Returns false when a visit stopped it.
fn best_first(
    p: Vec3A,
    radius: &mut f64,
    root: (f64, Item),
    mut children: impl FnMut(u32, f64, &mut PointStack),
    mut leaf: impl FnMut(u32, u32, &mut f64) -> bool,
) -> bool {
    let reach = p.abs().max_element() as f64;
    // How far (squared) a box may lie and still hold a point within the radius: a slack of a
    // few ulps of the lengths involved, so a primitive whose computed point rounds a hair
    // outside its box is never lost. A NaN distance (never made: the point is finite) is
    // pruned too.
    let reach2 = |radius: f64| {
        let reach = radius + (2.0 * radius + reach) * (1.0 / (1u64 << 20) as f64);
        reach * reach
    };
    let mut stack = PointStack::new();
    stack.push(root);
    while let Some((d2, item)) = stack.pop() {
        let limit = reach2(*radius);
        if d2 > limit {
            continue;
        }
        match item {
            Item::Leaf(first, count) => {
                if !leaf(first, count, radius) {
                    return false;
                }
            }
            Item::Node(i) => {
                let at = stack.len();
                children(i, limit, &mut stack);
                // Farthest first, so the nearest is popped next: an insertion sort of the (at
                // most eight) pushed.
                let pushed = stack.above_mut(at);
                for k in 1..pushed.len() {
                    let item = pushed[k];
                    let mut j = k;
                    while j > 0 && pushed[j - 1].0 < item.0 {
                        pushed[j] = pushed[j - 1];
                        j -= 1;
                    }
                    pushed[j] = item;
                }
            }
        }
    }
    true
}

/// Visits the leaf primitives `first..first + count` of a plain leaf.
#[inline]
fn visit_prims<P: Primitive>(
    prims: &[P],
    ids: &[u32],
    first: u32,
    count: u32,
    radius: &mut f64,
    visit: &mut Visit<'_, P>,
) -> bool {
    let range = first as usize..(first + count) as usize;
    for (j, p) in range.clone().zip(&prims[range]) {
        let id = ids.get(j).copied().unwrap_or(u32::MAX);
        if !visit(id, PrimAt::Prim(p), radius) {
            return false;
        }
    }
    true
}

/// Visits a wide layout's leaf: plain primitives or the lanes of its SIMD groups.
#[inline]
fn visit_leaf<P: Primitive>(
    leaves: &Leaves<'_, P>,
    first: u32,
    count: u32,
    radius: &mut f64,
    visit: &mut Visit<'_, P>,
) -> bool {
    if P::LEAF_FORMAT == LeafFormat::Plain {
        return visit_prims(leaves.prims, leaves.ids, first, count, radius, visit);
    }
    for g in first as usize..(first + groups(count)) as usize {
        let group = &leaves.tri4[g];
        let edges = P::LEAF_FORMAT == LeafFormat::FastTriangles && !leaves.far.has(g);
        for (lane, &id) in group.id.iter().enumerate() {
            if id != u32::MAX && !visit(id, PrimAt::Lane(group, lane, edges), radius) {
                return false;
            }
        }
    }
    true
}

/// The item a child with this box distance, index and count (`leaf`) is.
#[inline]
fn child_item(index: u32, count: u32, leaf: bool) -> Option<Item> {
    match (leaf, count) {
        (true, 0) => None,
        (true, n) => Some(Item::Leaf(index, n)),
        (false, _) => Some(Item::Node(index)),
    }
}

/// A layout walked for a point: every layout family implements it once.
pub(crate) trait PointWalk<P> {
    /// Offers `visit` every primitive whose leaf box lies within `radius` of `p` (local
    /// units), nearest boxes first, as the radius shrinks; false when `visit` stopped it.
    fn point_walk(&self, p: Vec3A, radius: &mut f64, visit: &mut Visit<'_, P>) -> bool;
}

impl<P: Primitive> PointWalk<P> for Bvh2<P> {
    fn point_walk(&self, p: Vec3A, radius: &mut f64, visit: &mut Visit<'_, P>) -> bool {
        if self.nodes.is_empty() {
            return true;
        }
        let addressing = self.mapping.addressing();
        let item = |i: usize| {
            let n = &self.nodes[i];
            let d = box_distance2(n.min.into(), n.max.into(), p);
            if n.is_leaf() {
                (d, Item::Leaf(n.link, n.prim_count()))
            } else {
                (d, Item::Node(i as u32))
            }
        };
        best_first(
            p,
            radius,
            item(0),
            |i, reach2, stack| {
                let i = i as usize;
                let n = &self.nodes[i];
                let (l, r) = match addressing {
                    Addressing::DepthFirst => (i + 1, n.link as usize),
                    Addressing::Explicit => (n.link as usize, n.count as usize),
                    Addressing::Compact if n.count == 0 => compact_children(i, n.link),
                    Addressing::Compact => (n.link as usize, n.count as usize),
                };
                for child in [item(l), item(r)] {
                    if child.0 <= reach2 {
                        stack.push(child);
                    }
                }
            },
            |first, count, radius| {
                visit_prims(&self.prims, &self.prim_ids, first, count, radius, visit)
            },
        )
    }
}

impl<P: Primitive, N: Node4> PointWalk<P> for Bvh4<P, N> {
    fn point_walk(&self, p: Vec3A, radius: &mut f64, visit: &mut Visit<'_, P>) -> bool {
        let leaves = self.leaves();
        if self.nodes.is_empty() {
            return true;
        }
        best_first(
            p,
            radius,
            (0.0, Item::Node(0)),
            |i, reach2, stack| {
                let n = &self.nodes[i as usize];
                let d2 = box_distances2(&n.planes().map(|r| r.to_array()), p);
                for (k, &d2) in d2.iter().enumerate() {
                    if d2 > reach2 {
                        continue;
                    }
                    let (c, count) = n.child(k);
                    let leaf = count & crate::layout::Bvh4Node::LEAF != 0;
                    let count = count & !crate::layout::Bvh4Node::LEAF;
                    if let Some(item) = child_item(c, count, leaf) {
                        stack.push((d2, item));
                    }
                }
            },
            |first, count, radius| visit_leaf(&leaves, first, count, radius, visit),
        )
    }
}

impl<P: Primitive> PointWalk<P> for Bvh8<P> {
    fn point_walk(&self, p: Vec3A, radius: &mut f64, visit: &mut Visit<'_, P>) -> bool {
        let leaves = self.leaves();
        if self.nodes.is_empty() {
            return true;
        }
        best_first(
            p,
            radius,
            (0.0, Item::Node(0)),
            |i, reach2, stack| {
                let n = &self.nodes[i as usize];
                let d2 = box_distances2(&n.planes, p);
                for (k, (&child, &count)) in n.child.iter().zip(&n.count).enumerate() {
                    if d2[k] > reach2 {
                        continue;
                    }
                    let leaf = count & Bvh8Node::LEAF != 0;
                    if let Some(item) = child_item(child, count & !Bvh8Node::LEAF, leaf) {
                        stack.push((d2[k], item));
                    }
                }
            },
            |first, count, radius| visit_leaf(&leaves, first, count, radius, visit),
        )
    }
}

/// True when a point query may run: a finite point, a radius that is not NaN nor negative.
/// The point nearest `p` (the caller's units, in f64) on a primitive a walk offers, measured
/// on the edges the layout stores at `local` (the point in the tree's frame, `up` the frame's
/// scale): its distance in f64, the point in the caller's units and its barycentrics. `None`
/// for a primitive without a triangle, or whose box lies beyond `r` (caller's units).
#[inline]
pub(crate) fn measure<P: Primitive>(
    prim: PrimAt<'_, P>,
    p: DVec3,
    local: Vec3A,
    r: f64,
    up: f64,
) -> Option<(f64, Vec3A, f32, f32)> {
    let (a, ab, ac) = prim.edges()?;
    if !may_reach([a, a + ab, a + ac], local, r / up) {
        return None;
    }
    let (u, v) = closest_uv(a, ab, ac, local);
    let q = wide(a + ab * u + ac * v) * up;
    let d = (p - q).length();
    Some((d, Vec3A::new(q.x as f32, q.y as f32, q.z as f32), u, v))
}

#[inline]
fn valid(point: Vec3A, radius: f32) -> bool {
    point.is_finite() && radius >= 0.0
}

/// `v` in f64.
#[inline]
pub(crate) fn wide(v: Vec3A) -> DVec3 {
    DVec3::new(v.x as f64, v.y as f64, v.z as f64)
}

/// Whether `(d, prim)` beats the best so far `(best_d, best_prim)`: nearer, or as near with a
/// lower index (the order every layout agrees on).
#[inline]
pub(crate) fn beats(d: f64, prim: u32, best: Option<(f64, u32)>) -> bool {
    match best {
        None => true,
        Some((bd, bp)) => d < bd || (d == bd && prim < bp),
    }
}

impl<P: Primitive> Bvh<P> {
    /// The layout's walk in the BVH's frame, told in the caller's units: `visit` gets the
    /// primitive (in the frame's units), the point in the frame and the radius in the
    /// caller's units, and `2^k`, the factor from frame to caller units.
    pub(crate) fn walk_points(
        &self,
        point: Vec3A,
        radius: f64,
        visit: &mut FramedVisit<'_, P>,
    ) -> bool {
        let (layout, frame) = self.layout();
        let up = 2f64.powi(frame.k());
        // The point in the frame, held inside f32 (a point far from a tiny scene comes in
        // nearer, which only makes the boxes' distances smaller: the walk stays a superset).
        let local = (wide(point) / up).clamp(
            DVec3::splat(-f32::MAX as f64),
            DVec3::splat(f32::MAX as f64),
        );
        let local = Vec3A::new(local.x as f32, local.y as f32, local.z as f32);
        let mut r = radius / up;
        let mut inner = |id: u32, prim: PrimAt<'_, P>, r: &mut f64| {
            let mut world = *r * up;
            let go = visit(id, prim, local, &mut world, up);
            *r = r.min(world / up);
            go
        };
        use crate::bvh::AnyLayout;
        match layout {
            AnyLayout::Bvh2(b) => b.point_walk(local, &mut r, &mut inner),
            AnyLayout::Bvh4(b) => b.point_walk(local, &mut r, &mut inner),
            AnyLayout::QBvh4(b) => b.point_walk(local, &mut r, &mut inner),
            AnyLayout::Bvh8(b) => b.point_walk(local, &mut r, &mut inner),
        }
    }

    /// Offers `visit` every primitive that may lie within `radius` of `point`: each one whose
    /// box (as the layout stores it; a quantized layout's box is a little larger) lies within
    /// the radius is offered, nearest boxes first (once; a tree built with spatial splits,
    /// [`crate::builders::Builder::Sbvh`], may hold a primitive in several leaves and offer it
    /// once from each), with its index in the build's input
    /// and the current radius, which the callback may shrink (a larger value is ignored) to
    /// prune the rest of the walk; returning false stops the walk. Some primitives beyond the
    /// radius may be offered too: the callback measures its own primitives. Returns false when
    /// the callback stopped the walk.
    ///
    /// The callback form of [`Bvh::closest_point`], for any primitive type (the "all
    /// primitives within a radius" query keeps the radius; a nearest-primitive query shrinks
    /// it to each better distance). A NaN or non-finite point, or a NaN or negative radius,
    /// offers nothing (and returns true); an infinite radius offers everything.
    ///
    /// ```
    /// use quiver_rt::{Aabb, Bvh, PrimHit, Primitive, Ray};
    /// use glam::Vec3A;
    ///
    /// /// A point-like primitive: a small cube around its centre.
    /// #[derive(Clone)]
    /// struct Dot(Vec3A);
    /// impl Primitive for Dot {
    ///     fn bounds(&self) -> Aabb {
    ///         Aabb::new(self.0 - 0.01, self.0 + 0.01)
    ///     }
    ///     fn intersect(&self, _: &Ray) -> Option<PrimHit> {
    ///         None
    ///     }
    /// }
    ///
    /// let dots: Vec<Dot> = (0..100).map(|i| Dot(Vec3A::new(i as f32, 0.0, 0.0))).collect();
    /// let bvh = Bvh::new(&dots);
    /// // Every dot within 2.5 of x = 10.
    /// let q = Vec3A::new(10.0, 0.0, 0.0);
    /// let mut near = Vec::new();
    /// bvh.point_query(q, 2.5, |i, r| {
    ///     if dots[i as usize].0.distance(q) <= *r {
    ///         near.push(i);
    ///     }
    ///     true
    /// });
    /// near.sort();
    /// assert_eq!(near, [8, 9, 10, 11, 12]);
    /// // The nearest dot to x = 41.3: shrink the radius to each better one.
    /// let q = Vec3A::new(41.3, 0.0, 0.0);
    /// let mut best = None;
    /// bvh.point_query(q, f32::INFINITY, |i, r| {
    ///     let d = dots[i as usize].0.distance(q);
    ///     if d < *r {
    ///         (best, *r) = (Some(i), d);
    ///     }
    ///     true
    /// });
    /// assert_eq!(best, Some(41));
    /// ```
    pub fn point_query(
        &self,
        point: Vec3A,
        radius: f32,
        mut visit: impl FnMut(u32, &mut f32) -> bool,
    ) -> bool {
        if !valid(point, radius) {
            return true;
        }
        self.walk_points(point, radius as f64, &mut |id, _, _, r, _| {
            // The caller's radius in f32, rounded up so that the walk never prunes a box
            // the caller's radius reaches.
            let mut f = *r as f32;
            if (f as f64) < *r {
                f = f.next_up();
            }
            let before = f;
            let go = visit(id, &mut f);
            if f < before {
                *r = f as f64;
            }
            go
        })
    }
}

impl<P: Primitive> Bvh<P> {
    /// The point of the BVH's triangles nearest `point`, within `max_distance` (inclusive):
    /// the primitive (its index in the build's input), the point, its barycentrics and its
    /// distance; `None` when no triangle lies that near. For every primitive type whose
    /// [`Primitive::triangle`] gives its triangle ([`Triangle`] and the triangle formats;
    /// primitives without one are skipped: [`Bvh::point_query`] serves those).
    ///
    /// Each candidate is measured by [`Triangle::closest_point`] (in f32, in the BVH's frame
    /// for a scene far from unit size), its distance from the query point in f64, so a
    /// far-off point or scene neither overflows nor underflows. Among triangles at the same
    /// distance the lower index wins, in every layout. A NaN or non-finite `point`, or a NaN
    /// or negative `max_distance`, answers `None`; `f32::INFINITY` searches everything.
    ///
    /// ```
    /// use quiver_rt::{BuildOptions, Bvh, Layout, Triangle};
    /// use glam::Vec3A;
    /// let tris: Vec<Triangle> = (0..50)
    ///     .map(|i| {
    ///         let o = Vec3A::new(2.0 * i as f32, 0.0, 0.0);
    ///         Triangle::new(o, o + Vec3A::X, o + Vec3A::Y)
    ///     })
    ///     .collect();
    /// let q = Vec3A::new(14.25, 0.25, 3.0); // above triangle 7
    /// for layout in Layout::ALL {
    ///     let bvh = Bvh::build(&tris, &BuildOptions::default().layout(layout)).unwrap();
    ///     let hit = bvh.closest_point(q, f32::INFINITY).unwrap();
    ///     assert_eq!((hit.prim, hit.distance), (7, 3.0));
    ///     assert_eq!(bvh.closest_point(q, 2.5), None); // nothing that near
    ///     assert_eq!(bvh.closest_point(Vec3A::NAN, 1.0), None);
    /// }
    /// ```
    pub fn closest_point(&self, point: Vec3A, max_distance: f32) -> Option<PointHit> {
        if !valid(point, max_distance) {
            return None;
        }
        let mut best: Option<(f64, u32)> = None;
        let mut hit = None;
        let p = wide(point);
        self.walk_points(point, max_distance as f64, &mut |id, prim, local, r, up| {
            let Some((d, point, u, v)) = measure(prim, p, local, *r, up) else {
                return true;
            };
            if d <= *r && beats(d, id, best) {
                best = Some((d, id));
                *r = d;
                hit = Some(PointHit {
                    prim: id,
                    point,
                    u,
                    v,
                    distance: d as f32,
                });
            }
            true
        });
        hit
    }
}

/// The box distance as the walks measure it, for tests.
#[cfg(test)]
pub(crate) fn distance_to_box(b: &crate::Aabb, p: Vec3A) -> f64 {
    box_distance2(b.min, b.max, p).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::soup;
    use crate::{BuildOptions, Layout};

    fn brute(tris: &[Triangle], p: Vec3A) -> (f64, u32) {
        let mut best = (f64::INFINITY, u32::MAX);
        for (i, t) in tris.iter().enumerate() {
            let (q, _, _) = t.closest_point(p);
            let d = (wide(p) - wide(q)).length();
            if beats(d, i as u32, Some(best)) {
                best = (d, i as u32);
            }
        }
        best
    }

    #[test]
    fn every_layout_finds_what_brute_force_finds() {
        let tris = soup(400, 5);
        let layouts =
            Layout::ALL.map(|l| Bvh::build(&tris, &BuildOptions::default().layout(l)).unwrap());
        let mut rng = crate::rng::Rng::new(7);
        for _ in 0..300 {
            let p = rng.in_box(Vec3A::splat(-1.0), Vec3A::splat(2.0));
            let (d, prim) = brute(&tris, p);
            for (bvh, l) in layouts.iter().zip(Layout::ALL) {
                let hit = bvh.closest_point(p, f32::INFINITY).unwrap();
                assert_eq!((hit.prim, hit.distance), (prim, d as f32), "{l} at {p}");
            }
        }
    }

    #[test]
    fn empty_and_bad_inputs_answer_nothing() {
        for layout in Layout::ALL {
            let bvh = Bvh::<Triangle>::build(&[], &BuildOptions::default().layout(layout)).unwrap();
            assert_eq!(
                bvh.closest_point(Vec3A::ZERO, f32::INFINITY),
                None,
                "{layout}"
            );
            assert!(bvh.point_query(Vec3A::ZERO, f32::INFINITY, |_, _| panic!("{layout}")));
        }
        let bvh = Bvh::new(&soup(20, 1));
        for (p, r) in [
            (Vec3A::NAN, 1.0),
            (Vec3A::ZERO, f32::NAN),
            (Vec3A::ZERO, -1.0),
            (Vec3A::splat(f32::INFINITY), 1.0),
        ] {
            assert_eq!(bvh.closest_point(p, r), None);
            assert!(bvh.point_query(p, r, |_, _| panic!("nothing offered")));
        }
        let b = crate::Aabb::new(Vec3A::ZERO, Vec3A::ONE);
        assert_eq!(distance_to_box(&b, Vec3A::new(0.5, 3.0, 0.5)), 2.0);
        assert_eq!(
            distance_to_box(&crate::Aabb::EMPTY, Vec3A::ZERO),
            f64::INFINITY
        );
    }
}
