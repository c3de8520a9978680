//! Turning objects into triangles: polygons by ear clipping (concave ones included), patches
//! by fans, and spheres and cones into polygonal patches the way the SPD's patch mode does.

use super::Shape;
use crate::primitive::{Cone, Polygon, Sphere};
use glam::{DVec3, Vec3A};
use quiver_rt::geometry::Triangle;

/// Appends the triangles of one shape to `out`, and to `normals` the vertex normals of each
/// (patches, and spheres and cones through their SPD tessellation, at `DEFAULT_RESOLUTION`)
/// or `None` (flat polygons).
pub fn shape_triangles(
    shape: &Shape,
    out: &mut Vec<Triangle>,
    normals: &mut Vec<Option<[Vec3A; 3]>>,
) {
    let start = out.len();
    match shape {
        Shape::Triangle(t) => out.push(*t),
        Shape::Polygon(v) => polygon_triangles(v, out),
        Shape::Patch { verts, normals: n } => return patch_fan(verts, n, out, normals),
        Shape::Sphere(s) => {
            for (verts, n) in sphere_patches(s, DEFAULT_RESOLUTION) {
                patch_fan(&verts, &n, out, normals);
            }
            return;
        }
        Shape::Cone(c) => {
            for (verts, n) in cone_patches(c, DEFAULT_RESOLUTION) {
                patch_fan(&verts, &n, out, normals);
            }
            return;
        }
    }
    normals.resize(normals.len() + out.len() - start, None);
}

/// A patch (the SPD's are triangles) as a fan, keeping each vertex's normal.
fn patch_fan(
    verts: &[Vec3A],
    n: &[Vec3A],
    out: &mut Vec<Triangle>,
    normals: &mut Vec<Option<[Vec3A; 3]>>,
) {
    for k in 1..verts.len().saturating_sub(1) {
        out.push(Triangle::new(verts[0], verts[k], verts[k + 1]));
        normals.push(Some([n[0], n[k], n[k + 1]]));
    }
}

/// The default tessellation resolution for patch mode: 4, the value the SPD Readme states
/// and its poly/patch statistics use (the programs' own `OUTPUT_RESOLUTION` is 3).
pub const DEFAULT_RESOLUTION: u32 = 4;

/// Triangulates a planar polygon by ear clipping in its projection plane. Convex polygons
/// give a fan; collinear and repeated vertices are tolerated (degenerate ears are skipped when
/// possible, never looped on).
///
/// The rule: while more than three vertices remain, cut the first vertex in input order that
/// is an ear (its corner turns the polygon's way and no other remaining vertex lies in or on
/// its triangle), or the first remaining vertex when none is. `ear_clip` finds that vertex
/// without testing every vertex against every ear, so a convex polygon of 100,000 vertices
/// takes milliseconds instead of the quadratic search's 40 s; the triangles are the same.
///
/// ```
/// use quiver_scenes::scene::tessellate::polygon_triangles;
/// use glam::Vec3A;
/// let square = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]].map(|[x, y]| Vec3A::new(x, y, 0.0));
/// let mut tris = Vec::new();
/// polygon_triangles(&square, &mut tris);
/// // A fan about the last vertex.
/// assert_eq!(tris.len(), 2);
/// assert_eq!(tris[0].v, [square[3], square[0], square[1]]);
/// ```
pub fn polygon_triangles(verts: &[Vec3A], out: &mut Vec<Triangle>) {
    match verts.len() {
        0..=2 => return,
        3 => {
            out.push(Triangle::new(verts[0], verts[1], verts[2]));
            return;
        }
        _ => {}
    }
    let (pts, sign) = projected(verts);
    ear_clip(&pts, sign, |a, b, c| {
        out.push(Triangle::new(verts[a], verts[b], verts[c]))
    });
}

/// The polygon in the plane of the two axes its normal is least along, in f64, and the sign
/// of its projected area (ears must turn the same way).
fn projected(verts: &[Vec3A]) -> (Vec<(f64, f64)>, f64) {
    let poly = Polygon::new(verts.to_vec());
    let n = poly.normal();
    let m = n.abs();
    let (i, j) = if m.x >= m.y && m.x >= m.z {
        (1, 2)
    } else if m.y >= m.z {
        (2, 0)
    } else {
        (0, 1)
    };
    let pts: Vec<(f64, f64)> = verts.iter().map(|v| (v[i] as f64, v[j] as f64)).collect();
    let area: f64 = (0..pts.len())
        .map(|k| {
            let (a, b) = (pts[k], pts[(k + 1) % pts.len()]);
            a.0 * b.1 - b.0 * a.1
        })
        .sum();
    (pts, if area >= 0.0 { 1.0 } else { -1.0 })
}

/// Twice the signed area of the projected triangle `a b c`: the one orientation test every
/// ear decision is made of, evaluated the same way everywhere (no fused operations), so the
/// decisions and therefore the triangles are exactly those of the direct search.
#[inline]
fn cross(a: (f64, f64), b: (f64, f64), c: (f64, f64)) -> f64 {
    (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0)
}

/// Whether `p` lies in or on the ear `a b c` of a polygon of orientation `sign`.
#[inline]
fn in_ear(a: (f64, f64), b: (f64, f64), c: (f64, f64), p: (f64, f64), sign: f64) -> bool {
    let (d1, d2, d3) = (
        cross(a, b, p) * sign,
        cross(b, c, p) * sign,
        cross(c, a, p) * sign,
    );
    d1 >= 0.0 && d2 >= 0.0 && d3 >= 0.0
}

/// Why a vertex was found not to be an ear, which says when to look at it again.
enum NotEar {
    /// Its corner does not turn the polygon's way: until a neighbour changes.
    Reflex,
    /// This remaining vertex lies in or on its triangle: until that vertex is cut (or a
    /// neighbour changes).
    Holds(usize),
}

/// Ear clipping of the projected polygon `pts` with orientation `sign`, calling `emit` with
/// each triangle's vertex indices in cutting order; returns the work done (points tested
/// against an ear plus tree nodes entered), which tests use to check the complexity.
///
/// It computes exactly what the direct rule (see [`polygon_triangles`]) computes: every
/// decision is the same floating-point test on the same points. What it saves is the tests
/// whose outcome is known:
///
/// - a vertex found not to be an ear stays one until a neighbour is cut (its triangle
///   changes) or, if a remaining vertex lay in its triangle, until that vertex is cut: the
///   other vertices only ever leave, so nothing else can make it an ear. Vertices are kept
///   in a set ordered by index while their status is unknown; the first ear is the smallest
///   member that tests as one.
/// - "no remaining vertex lies in the ear" asks a 2-d tree over the points (with counts of
///   the ones not yet cut), skipping a node when one edge's test is negative for every point
///   of its box. That is decided at the box's corners: each edge test is monotone in each
///   coordinate of the point separately (a difference, a product by a fixed number and a
///   difference, all rounded monotonically), so its largest value over a box is at a corner,
///   and a negative value there is negative for every point inside.
pub(crate) fn ear_clip(
    pts: &[(f64, f64)],
    sign: f64,
    mut emit: impl FnMut(usize, usize, usize),
) -> u64 {
    let n = pts.len();
    if n < 3 {
        return 0;
    }
    let mut tree = PointTree::new(pts);
    let mut next: Vec<usize> = (1..=n).map(|i| i % n).collect();
    let mut prev: Vec<usize> = (0..n).map(|i| (i + n - 1) % n).collect();
    let mut alive = vec![true; n];
    // Vertices that are not ears because a given vertex lies in their triangle, by that vertex.
    let mut waiting: Vec<Vec<usize>> = vec![Vec::new(); n];
    let mut unknown: std::collections::BTreeSet<usize> = (0..n).collect();
    let mut head = 0;
    let mut left = n;
    while left > 3 {
        let mut ear = None;
        while let Some(v) = unknown.pop_first() {
            let (a, b, c) = (pts[prev[v]], pts[v], pts[next[v]]);
            let why = if cross(a, b, c) * sign <= 0.0 {
                Some(NotEar::Reflex)
            } else {
                tree.find_in_ear(pts, [prev[v], v, next[v]], &alive, sign)
                    .map(NotEar::Holds)
            };
            match why {
                None => {
                    ear = Some(v);
                    break;
                }
                Some(NotEar::Reflex) => {}
                Some(NotEar::Holds(w)) => waiting[w].push(v),
            }
        }
        // Only degenerate corners remain (collinear runs): cut the first vertex to finish.
        let v = ear.unwrap_or(head);
        let (p, q) = (prev[v], next[v]);
        emit(p, v, q);
        alive[v] = false;
        tree.remove(v);
        next[p] = q;
        prev[q] = p;
        if v == head {
            head = q;
        }
        left -= 1;
        unknown.insert(p);
        unknown.insert(q);
        unknown.extend(
            std::mem::take(&mut waiting[v])
                .into_iter()
                .filter(|&w| alive[w]),
        );
    }
    emit(head, next[head], next[next[head]]);
    tree.work
}

/// A 2-d tree over a polygon's points that counts, per node, the points not yet cut, for
/// [`ear_clip`]'s question "does any remaining point lie in this ear?".
struct PointTree {
    /// Point indices, grouped so that each node's points are a contiguous range.
    order: Vec<usize>,
    nodes: Vec<Node>,
    /// The leaf holding each point.
    leaf_of: Vec<usize>,
    /// Points tested and nodes entered so far.
    work: u64,
}

struct Node {
    /// The points' range in `order`.
    range: std::ops::Range<usize>,
    /// Bounding box: min x, min y, max x, max y.
    bounds: [f64; 4],
    /// Children (none for a leaf) and parent (`usize::MAX` at the root).
    children: Option<[usize; 2]>,
    parent: usize,
    /// Points in the node not yet cut.
    alive: usize,
}

/// Most points in a leaf.
const LEAF: usize = 8;

impl PointTree {
    fn new(pts: &[(f64, f64)]) -> Self {
        let mut tree = PointTree {
            order: (0..pts.len()).collect(),
            nodes: Vec::new(),
            leaf_of: vec![0; pts.len()],
            work: 0,
        };
        tree.build(pts, 0..pts.len(), usize::MAX);
        tree
    }

    /// Adds the node over `order[range]` and its subtree; returns its index.
    fn build(&mut self, pts: &[(f64, f64)], range: std::ops::Range<usize>, parent: usize) -> usize {
        let mut bounds = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        for &i in &self.order[range.clone()] {
            let (x, y) = pts[i];
            bounds = [
                bounds[0].min(x),
                bounds[1].min(y),
                bounds[2].max(x),
                bounds[3].max(y),
            ];
        }
        let id = self.nodes.len();
        self.nodes.push(Node {
            range: range.clone(),
            bounds,
            children: None,
            parent,
            alive: range.len(),
        });
        if range.len() <= LEAF {
            for &i in &self.order[range] {
                self.leaf_of[i] = id;
            }
            return id;
        }
        // Split at the median of the longer side (NaN coordinates sort last, anywhere).
        let x_axis = (bounds[3] - bounds[1]).partial_cmp(&(bounds[2] - bounds[0]))
            != Some(std::cmp::Ordering::Greater);
        let key = |i: usize| if x_axis { pts[i].0 } else { pts[i].1 };
        let mid = range.start + range.len() / 2;
        self.order[range.clone()]
            .select_nth_unstable_by(mid - range.start, |&a, &b| key(a).total_cmp(&key(b)));
        let left = self.build(pts, range.start..mid, id);
        let right = self.build(pts, mid..range.end, id);
        self.nodes[id].children = Some([left, right]);
        id
    }

    /// Marks point `i` as cut.
    fn remove(&mut self, i: usize) {
        let mut node = self.leaf_of[i];
        while node != usize::MAX {
            self.nodes[node].alive -= 1;
            node = self.nodes[node].parent;
        }
    }

    /// A remaining point, other than the ear's own corners `[a, b, c]`, in or on the ear, if
    /// there is one.
    fn find_in_ear(
        &mut self,
        pts: &[(f64, f64)],
        corners: [usize; 3],
        alive: &[bool],
        sign: f64,
    ) -> Option<usize> {
        let [a, b, c] = corners.map(|k| pts[k]);
        let edges = [(a, b), (b, c), (c, a)];
        let mut stack = vec![0];
        while let Some(id) = stack.pop() {
            let node = &self.nodes[id];
            self.work += 1;
            if node.alive == 0 {
                continue;
            }
            let [x0, y0, x1, y1] = node.bounds;
            let box_corners = [(x0, y0), (x0, y1), (x1, y0), (x1, y1)];
            // Some edge's test negative at all four corners: negative for the whole box.
            let outside = edges
                .iter()
                .any(|&(u, v)| box_corners.iter().all(|&p| cross(u, v, p) * sign < 0.0));
            if outside {
                continue;
            }
            match node.children {
                Some([l, r]) => stack.extend([l, r]),
                None => {
                    for &i in &self.order[node.range.clone()] {
                        if !alive[i] || corners.contains(&i) {
                            continue;
                        }
                        self.work += 1;
                        if in_ear(a, b, c, pts[i], sign) {
                            return Some(i);
                        }
                    }
                }
            }
        }
        None
    }
}

/// A sphere as the SPD's patch mode writes it (`lib_output_polygon_sphere`): the six faces of
/// a cube projected onto the sphere, each an `res × res` grid cut into two triangles per cell,
/// `12 res^2` triangles in all, counter-clockwise from outside, with the unit radial
/// direction as each vertex normal. Faces come in the order -X, -Y, -Z, +X, +Y, +Z.
pub fn sphere_patches(s: &Sphere, res: u32) -> Vec<(Vec<Vec3A>, Vec<Vec3A>)> {
    let mut out = Vec::with_capacity(12 * res.max(1) as usize * res.max(1) as usize);
    for_each_sphere_patch(s, res, |v, n| out.push((v.to_vec(), n.to_vec())));
    out
}

/// [`sphere_patches`] one patch at a time: `f(vertices, normals)` for each, in the same order,
/// holding only the face grid (`(res + 1)²` points), so a sphere at any resolution can be
/// written out without its `12 res²` patches in memory.
pub fn for_each_sphere_patch(s: &Sphere, res: u32, mut f: impl FnMut([Vec3A; 3], [Vec3A; 3])) {
    use std::f64::consts::FRAC_PI_4;
    let r = res.max(1) as usize;
    let angle = |e: usize| FRAC_PI_4 * (2.0 * e as f64 / r as f64 - 1.0);
    // The +Z face: crossing a meridian direction with a parallel direction.
    let mut grid: Vec<Vec<DVec3>> = (0..=r)
        .map(|u| {
            let a = angle(u);
            let xa = DVec3::new(a.cos(), 0.0, -a.sin());
            (0..=r)
                .map(|v| {
                    let b = angle(v);
                    xa.cross(DVec3::new(0.0, b.cos(), b.sin())).normalize()
                })
                .collect()
        })
        .collect();
    let center = DVec3::new(s.center.x as f64, s.center.y as f64, s.center.z as f64);
    let radius = s.radius as f64;
    let v3 = |p: DVec3| Vec3A::new(p.x as f32, p.y as f32, p.z as f32);
    for face in 0..6 {
        // Each face is the previous one turned by a quarter about the next axis.
        for p in grid.iter_mut().flatten() {
            *p = match (face + 2) % 3 {
                0 => DVec3::new(-p.y, p.x, p.z),
                1 => DVec3::new(p.x, -p.z, p.y),
                _ => DVec3::new(-p.z, p.y, p.x),
            };
        }
        for u in 0..r {
            for v in 0..r {
                let q = [
                    grid[u][v],
                    grid[u][v + 1],
                    grid[u + 1][v + 1],
                    grid[u + 1][v],
                ];
                for tri in [[q[0], q[1], q[2]], [q[2], q[3], q[0]]] {
                    f(tri.map(|n| v3(center + n * radius)), tri.map(v3));
                }
            }
        }
    }
}

/// A cone or cylinder as the SPD's patch mode writes it (`lib_output_polygon_cylcone`): `4 res`
/// segments around the axis, two triangles each (`8 res` in all), facing outward, with normals
/// that lean by the cone's slope.
pub fn cone_patches(c: &Cone, res: u32) -> Vec<(Vec<Vec3A>, Vec<Vec3A>)> {
    let mut out = Vec::with_capacity(8 * res.max(1) as usize);
    for_each_cone_patch(c, res, |v, n| out.push((v.to_vec(), n.to_vec())));
    out
}

/// [`cone_patches`] one patch at a time, in the same order (see [`for_each_sphere_patch`]).
pub fn for_each_cone_patch(c: &Cone, res: u32, mut emit: impl FnMut([Vec3A; 3], [Vec3A; 3])) {
    let d = |v: Vec3A| DVec3::new(v.x as f64, v.y as f64, v.z as f64);
    let f = |p: DVec3| Vec3A::new(p.x as f32, p.y as f32, p.z as f32);
    let (base, apex) = (d(c.base), d(c.apex));
    let (br, ar) = (c.base_radius as f64, c.apex_radius as f64);
    let axis = apex - base;
    let h = axis.length();
    if h == 0.0 {
        return;
    }
    let na = axis / h;
    let side = axis.cross(DVec3::Z);
    let sd = if side.length() < 1e-6 {
        axis.cross(DVec3::X).normalize()
    } else {
        side.normalize()
    };
    let (r0, r1) = (sd * br, sd * ar);
    let sn = if br == ar {
        sd
    } else {
        (sd * h + na * (br - ar)).normalize()
    };
    let n = 4 * res.max(1) as usize;
    let step = std::f64::consts::TAU / n as f64;
    let (mut b_prev, mut a_prev, mut n_prev) = (base + r0, apex + r1, sn);
    let mut theta = 0.0;
    for _ in 0..n {
        // The angle accumulates by repeated addition, as the SPD library does.
        theta += step;
        let (a_i, b_i, n_i) = (
            apex + rotate(r1, na, theta),
            base + rotate(r0, na, theta),
            rotate(sn, na, theta),
        );
        emit(
            [f(a_i), f(a_prev), f(b_prev)],
            [f(n_i), f(n_prev), f(n_prev)],
        );
        emit([f(b_i), f(a_i), f(b_prev)], [f(n_i), f(n_i), f(n_prev)]);
        (a_prev, b_prev, n_prev) = (a_i, b_i, n_i);
    }
}

/// Right-handed rotation of `p` about unit axis `u` by `a` radians (Rodrigues' formula).
pub(crate) fn rotate(p: DVec3, u: DVec3, a: f64) -> DVec3 {
    let (s, c) = a.sin_cos();
    p * c + u.cross(p) * s + u * u.dot(p) * (1.0 - c)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The direct ear search [`ear_clip`] must reproduce: for each cut, every remaining
    /// vertex in order, each tested against every other (quadratic; the code before
    /// issue 29).
    fn ear_clip_reference(pts: &[(f64, f64)], sign: f64) -> Vec<[usize; 3]> {
        let mut out = Vec::new();
        let mut idx: Vec<usize> = (0..pts.len()).collect();
        while idx.len() > 3 {
            let k = idx.len();
            let ear = (0..k).find(|&e| {
                let (a, b, c) = (
                    pts[idx[(e + k - 1) % k]],
                    pts[idx[e]],
                    pts[idx[(e + 1) % k]],
                );
                if cross(a, b, c) * sign <= 0.0 {
                    return false;
                }
                idx.iter().enumerate().all(|(q, &vi)| {
                    if q == e || q == (e + k - 1) % k || q == (e + 1) % k {
                        return true;
                    }
                    !in_ear(a, b, c, pts[vi], sign)
                })
            });
            let e = ear.unwrap_or(0);
            out.push([idx[(e + k - 1) % k], idx[e], idx[(e + 1) % k]]);
            idx.remove(e);
        }
        out.push([idx[0], idx[1], idx[2]]);
        out
    }

    /// [`ear_clip`]'s triangles (as index triples) and its work.
    fn clipped(pts: &[(f64, f64)], sign: f64) -> (Vec<[usize; 3]>, u64) {
        let mut out = Vec::new();
        let work = ear_clip(pts, sign, |a, b, c| out.push([a, b, c]));
        (out, work)
    }

    /// Seeded random numbers in [0, 1).
    fn uniform(seed: &mut u64) -> f64 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*seed >> 11) as f64 / (1u64 << 53) as f64
    }

    fn to_3d(pts: &[(f64, f64)]) -> Vec<Vec3A> {
        pts.iter()
            .map(|&(x, y)| Vec3A::new(x as f32, 0.5, y as f32))
            .collect()
    }

    /// Same triangles as the direct search, in the same order, on every kind of input: the
    /// SPD's gear faces, convex, star-shaped (concave), with repeated and collinear vertices,
    /// and random self-crossing garbage.
    #[test]
    fn ear_clip_equals_the_direct_search() {
        let mut polygons: Vec<Vec<Vec3A>> = Vec::new();
        for size in [1, 2, 4] {
            let scene = crate::Scene::load(&format!("gears{size}")).unwrap();
            for o in &scene.objects {
                if let crate::scene::Shape::Polygon(v) = &o.shape {
                    polygons.push(v.clone());
                }
            }
        }
        assert!(polygons.len() > 500 && polygons.iter().any(|p| p.len() == 144));
        let mut seed = 29;
        for case in 0..3000 {
            let n = 4 + (uniform(&mut seed) * [8.0, 40.0, 200.0][case % 3]) as usize;
            let pts: Vec<(f64, f64)> = (0..n)
                .map(|k| {
                    let t = std::f64::consts::TAU * k as f64 / n as f64;
                    let r = match case % 5 {
                        0 => 1.0,
                        1 | 2 => 0.3 + uniform(&mut seed),
                        _ => 0.0,
                    };
                    if case % 5 >= 3 {
                        // Garbage, on a coarse grid so points repeat and line up.
                        let g = |s: &mut u64| (uniform(s) * 6.0).floor();
                        (g(&mut seed), g(&mut seed))
                    } else {
                        (r * t.cos(), r * t.sin())
                    }
                })
                .collect();
            let mut pts = pts;
            if case % 7 == 0 {
                // Repeat a vertex and put one on an edge's midpoint.
                let k = (uniform(&mut seed) * n as f64) as usize;
                pts.insert(k, pts[k]);
                let (a, b) = (pts[0], pts[1]);
                pts.insert(1, ((a.0 + b.0) / 2.0, (a.1 + b.1) / 2.0));
            }
            polygons.push(to_3d(&pts));
        }
        for v in &polygons {
            let (pts, sign) = projected(v);
            let (fast, _) = clipped(&pts, sign);
            assert_eq!(fast, ear_clip_reference(&pts, sign), "{v:?}");
        }
    }

    /// The area of triangle `t` projected like `p`'s polygon, and whether two triangles'
    /// interiors overlap (a separating axis among their edges says no).
    fn area2(t: [(f64, f64); 3]) -> f64 {
        cross(t[0], t[1], t[2]) / 2.0
    }

    fn overlap(s: [(f64, f64); 3], t: [(f64, f64); 3]) -> bool {
        let side = |tri: [(f64, f64); 3], other: [(f64, f64); 3]| {
            let o = area2(tri).signum();
            (0..3).any(|k| {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                other.iter().all(|&p| cross(a, b, p) * o <= 1e-12)
            })
        };
        !(side(s, t) || side(t, s))
    }

    /// The triangles of convex and concave (simple) polygons tile them: their areas sum to the
    /// polygon's, every triangle turns the polygon's way, and no two overlap.
    #[test]
    fn ear_clipping_tiles_convex_and_concave_polygons() {
        let mut seed = 7;
        for case in 0..200 {
            let n = 4 + (uniform(&mut seed) * 40.0) as usize;
            // A star-shaped polygon around the origin (convex when case is even).
            let pts: Vec<(f64, f64)> = (0..n)
                .map(|k| {
                    let t =
                        std::f64::consts::TAU * (k as f64 + 0.3 * uniform(&mut seed)) / n as f64;
                    let r = if case % 2 == 0 {
                        1.0
                    } else {
                        0.2 + uniform(&mut seed)
                    };
                    (
                        (r * t.cos() * 64.0).round() / 64.0,
                        (r * t.sin() * 64.0).round() / 64.0,
                    )
                })
                .collect();
            let (p, sign) = projected(&to_3d(&pts));
            let whole: f64 = (0..n)
                .map(|k| {
                    let (a, b) = (p[k], p[(k + 1) % n]);
                    a.0 * b.1 - b.0 * a.1
                })
                .sum::<f64>()
                .abs()
                / 2.0;
            let (tris, _) = clipped(&p, sign);
            assert_eq!(tris.len(), n - 2);
            let corners: Vec<[(f64, f64); 3]> = tris.iter().map(|t| t.map(|k| p[k])).collect();
            let sum: f64 = corners.iter().map(|&t| area2(t) * sign).sum();
            assert!(
                (sum - whole).abs() <= 1e-9 * whole,
                "case {case}: {sum} vs {whole}"
            );
            for (i, &s) in corners.iter().enumerate() {
                assert!(
                    area2(s) * sign >= 0.0,
                    "case {case}: triangle {i} turns the wrong way"
                );
                for &t in &corners[..i] {
                    assert!(!overlap(s, t), "case {case}: {s:?} overlaps {t:?}");
                }
            }
        }
    }

    /// Work grows near-linearly, as n log² n: a strictly convex 100,000-gon (exact in f64;
    /// the fan) and a 100,000-gon of f32 points on a circle (rounding makes some corners
    /// reflex or collinear) cost under 2 log²n tests per vertex (about 1.2 and 0.25 log²n
    /// measured from 1,000 to 256,000 vertices), where the direct search costs n/2 per vertex.
    #[test]
    fn ear_clipping_is_near_linear_on_convex_and_near_convex_polygons() {
        let bound = |n: usize| 2 * n as u64 * (n as f64).log2().powi(2) as u64;
        // y = x² on integers: exact in f64, strictly convex.
        let n = 100_000;
        let parabola: Vec<(f64, f64)> = (0..n).map(|x| (x as f64, (x as f64).powi(2))).collect();
        let (tris, work) = clipped(&parabola, 1.0);
        // The fan about the last vertex, as the direct search cuts it.
        assert_eq!(tris[0], [n - 1, 0, 1]);
        assert!(tris[..n - 3]
            .iter()
            .enumerate()
            .all(|(k, t)| *t == [n - 1, k, k + 1]));
        assert_eq!(tris[n - 3], [n - 3, n - 2, n - 1]);
        assert!(work < bound(n), "parabola: {work} for {n} vertices");
        let n = 100_000;
        let circle: Vec<Vec3A> = (0..n)
            .map(|k| {
                let t = std::f64::consts::TAU * k as f64 / n as f64;
                Vec3A::new((1e3 * t.cos()) as f32, (1e3 * t.sin()) as f32, 2.0)
            })
            .collect();
        let (pts, sign) = projected(&circle);
        let (tris, work) = clipped(&pts, sign);
        assert_eq!(tris.len(), n - 2);
        assert!(work < bound(n), "circle: {work} for {n} vertices");
    }

    fn area(tris: &[Triangle]) -> f32 {
        tris.iter()
            .map(|t| (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).length() * 0.5)
            .sum()
    }

    /// Every vertex on the surface, every normal radial, outward winding, 12 r^2 triangles.
    #[test]
    fn sphere_patches_lie_on_the_sphere_and_face_out() {
        let s = Sphere {
            center: Vec3A::new(1.0, 2.0, 3.0),
            radius: 2.0,
        };
        for res in [1, 3, 4] {
            let p = sphere_patches(&s, res);
            assert_eq!(p.len(), 12 * (res * res) as usize);
            for (v, n) in &p {
                for (x, nx) in v.iter().zip(n) {
                    assert!(((*x - s.center).length() - 2.0).abs() < 1e-5);
                    assert!((*nx - (*x - s.center) / 2.0).length() < 1e-5);
                }
                let face = (v[1] - v[0]).cross(v[2] - v[0]);
                assert!(face.dot(v[0] - s.center) > 0.0, "winding");
            }
        }
        // Resolution 1 gives the cube's corners.
        let corner = 1.0 / 3f32.sqrt();
        for (_, n) in sphere_patches(&s, 1) {
            assert!(n
                .iter()
                .all(|x| (x.abs() - Vec3A::splat(corner)).abs().max_element() < 1e-6));
        }
    }

    #[test]
    fn cone_patches_lie_on_the_cone_and_face_out() {
        let c = Cone {
            base: Vec3A::ZERO,
            base_radius: 2.0,
            apex: Vec3A::new(0.0, 0.0, 2.0),
            apex_radius: 1.0,
        };
        for res in [1, 3, 4] {
            let p = cone_patches(&c, res);
            assert_eq!(p.len(), 8 * res as usize);
            for (v, _) in &p {
                for x in v {
                    let r = (x.x * x.x + x.y * x.y).sqrt();
                    assert!((r - (2.0 - x.z / 2.0)).abs() < 1e-5, "{x}");
                }
                let face = (v[1] - v[0]).cross(v[2] - v[0]);
                let out = Vec3A::new(v[0].x, v[0].y, 0.0);
                assert!(face.dot(out) > 0.0, "winding");
            }
        }
    }

    #[test]
    fn ear_clipping_covers_a_concave_polygon_exactly() {
        // A U shape of area 3*3 - 1*2 = 7, in both orientations.
        let mut u: Vec<Vec3A> = [
            [0.0, 0.0],
            [3.0, 0.0],
            [3.0, 3.0],
            [2.0, 3.0],
            [2.0, 1.0],
            [1.0, 1.0],
            [1.0, 3.0],
            [0.0, 3.0],
        ]
        .iter()
        .map(|&[x, y]| Vec3A::new(x, 1.0, y))
        .collect();
        for _ in 0..2 {
            let mut tris = Vec::new();
            polygon_triangles(&u, &mut tris);
            assert_eq!(tris.len(), u.len() - 2);
            assert!((area(&tris) - 7.0).abs() < 1e-5, "area {}", area(&tris));
            u.reverse();
        }
    }
}
