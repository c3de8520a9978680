//! The SPD's analytic primitives and [`Prim`], the mixed primitive a BVH holds for scenes in
//! curve mode. All-triangle scenes use [`Triangle`] directly and never pay for the dispatch.
//!
//! ```
//! use quiver_scenes::primitive::{Prim, Sphere};
//! use quiver_rt::{Primitive, Ray};
//! use glam::Vec3A;
//! let s = Prim::Sphere(Sphere { center: Vec3A::ZERO, radius: 2.0 });
//! let hit = s.intersect(&Ray::new(Vec3A::new(0.0, 0.0, -5.0), Vec3A::Z)).unwrap();
//! assert_eq!(hit.t, 3.0);
//! ```

// Comparisons are written as `!(x >= 0.0)` on purpose: a NaN must reject a hit.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use glam::Vec3A;
use quiver_rt::geometry::{unit_or_zero, unit_scale, Aabb, PrimHit, Ray, Triangle};
use quiver_rt::intersect::Watertight;
use quiver_rt::primitive::Primitive;
use quiver_rt::primitive::{PacketLanes, PacketLeaf};
use wide::f32x8;

/// A sphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// Centre.
    pub center: Vec3A,
    /// Radius (> 0).
    pub radius: f32,
}

/// A truncated cone between two circular ends, open (no caps), as NFF's `c`; equal radii make
/// a cylinder.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cone {
    /// Centre of the base end.
    pub base: Vec3A,
    /// Radius at the base end (>= 0).
    pub base_radius: f32,
    /// Centre of the apex end.
    pub apex: Vec3A,
    /// Radius at the apex end (>= 0).
    pub apex_radius: f32,
}

/// A planar polygon with any number of vertices, convex or not (the gears' 144-vertex faces).
/// Inside is decided by the even-odd rule in the plane.
#[derive(Clone, Debug, PartialEq)]
pub struct Polygon {
    verts: Box<[Vec3A]>,
    normal: Vec3A,
    /// The axis dropped when projecting to 2D (the normal's largest component).
    axis: usize,
}

/// A triangle of a polygonal patch: flat geometry, normals interpolated for shading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PatchTriangle {
    /// The geometry.
    pub tri: Triangle,
    /// Vertex normals, in the order of `tri.v`.
    pub normals: [Vec3A; 3],
}

/// A triangle cut from a polygon (by [`crate::scene::tessellate::polygon_triangles`]), traced
/// in the polygon's place: tested watertight, so no ray slips between two pieces of one
/// polygon, and shaded with the polygon's normal. A polygon of `n` vertices costs a few
/// triangle tests in the BVH's leaves instead of a walk over all `n` edges per ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PolygonPiece {
    /// The geometry.
    pub tri: Triangle,
    /// The whole polygon's unit normal.
    pub normal: Vec3A,
}

/// Any primitive: what a curve-mode SPD scene puts into its BVH.
#[derive(Clone, Debug, PartialEq)]
pub enum Prim {
    /// A flat triangle.
    Triangle(Triangle),
    /// A triangle with vertex normals.
    Patch(PatchTriangle),
    /// A sphere.
    Sphere(Sphere),
    /// A cone or cylinder.
    Cone(Cone),
    /// A polygon.
    Polygon(Polygon),
    /// A triangle of a polygon, traced in its place.
    Piece(PolygonPiece),
}

impl Polygon {
    /// A polygon through `verts` (at least three, all in one plane). The normal follows the
    /// vertex order (Newell's method, robust for concave and nearly collinear input).
    pub fn new(verts: Vec<Vec3A>) -> Polygon {
        // Newell's terms are products of two coordinates: bring them near 1 first (exactly,
        // by a power of two) so a polygon at 1e-30 or 1e30 keeps its normal.
        let s = unit_scale(
            verts
                .iter()
                .fold(0.0f32, |m, v| m.max(v.abs().max_element())),
        );
        let mut n = Vec3A::ZERO;
        for (i, a) in verts.iter().enumerate() {
            let (a, b) = (*a * s, verts[(i + 1) % verts.len()] * s);
            n += Vec3A::new(
                (a.y - b.y) * (a.z + b.z),
                (a.z - b.z) * (a.x + b.x),
                (a.x - b.x) * (a.y + b.y),
            );
        }
        let normal = unit_or_zero(n);
        let m = normal.abs();
        let axis = if m.x >= m.y && m.x >= m.z {
            0
        } else if m.y >= m.z {
            1
        } else {
            2
        };
        Polygon {
            verts: verts.into_boxed_slice(),
            normal,
            axis,
        }
    }

    /// The vertices.
    pub fn verts(&self) -> &[Vec3A] {
        &self.verts
    }

    /// Unit normal (zero for a degenerate polygon).
    pub fn normal(&self) -> Vec3A {
        self.normal
    }
}

impl Primitive for Sphere {
    fn bounds(&self) -> Aabb {
        Aabb::new(self.center - self.radius, self.center + self.radius)
    }

    fn surface_area(&self) -> f32 {
        4.0 * std::f32::consts::PI * self.radius * self.radius
    }

    fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
        // Roots of |o + t d - c|^2 = r^2, with the half-b form and the smaller root computed
        // without cancellation, solved from the ray's point nearest the centre: from the
        // origin, b^2 - ac cancels catastrophically for a small sphere far away (a radius of
        // 0.002 at distance 5 put hits 0.0004 outside the sphere's own box).
        let shift = nearest_t(ray, self.center);
        let oc = (ray.origin + ray.dir * shift) - self.center;
        let a = ray.dir.length_squared();
        let b = oc.dot(ray.dir);
        let c = oc.length_squared() - self.radius * self.radius;
        let disc = b * b - a * c;
        if !(disc >= 0.0) || a == 0.0 {
            return None;
        }
        let q = -(b + disc.sqrt().copysign(b));
        let (t0, t1) = {
            let (x, y) = (q / a, if q != 0.0 { c / q } else { -b / a });
            if x <= y {
                (x, y)
            } else {
                (y, x)
            }
        };
        [t0 + shift, t1 + shift]
            .into_iter()
            .find(|&t| t >= ray.t_min && t <= ray.t_max)
            .map(|t| PrimHit { t, u: 0.0, v: 0.0 })
    }
}

impl Sphere {
    /// [`Sphere::intersect`] for eight rays at once, operation for operation (so bit for bit
    /// the same answer): the lanes that hit, and their `t`.
    #[inline(always)]
    pub fn intersect_lanes(&self, l: &PacketLanes) -> (u32, f32x8) {
        let shift = nearest_t8(l, self.center);
        let oc = point_from8(l, shift, self.center);
        let a = dot8(&l.dir, &l.dir);
        let b = dot8(&oc, &l.dir);
        let c = dot8(&oc, &oc) - f32x8::splat(self.radius * self.radius);
        let disc = b * b - a * c;
        let ok = disc.simd_ge(f32x8::ZERO) & a.simd_ne(f32x8::ZERO);
        if ok.to_bitmask() & l.live == 0 {
            return (0, f32x8::ZERO);
        }
        let (t0, t1) = roots8(a, b, c, disc);
        let (t0, t1) = (t0 + shift, t1 + shift);
        let within = |t: f32x8| t.simd_ge(l.t_min) & t.simd_le(l.t_max);
        let (in0, in1) = (within(t0), within(t1));
        ((ok & (in0 | in1)).to_bitmask(), in0.select(t0, t1))
    }
}

/// The `t` of the ray's point nearest `p` (0 for a zero direction): solving a quadric from
/// there keeps its coefficients small, so they do not cancel.
#[inline]
fn nearest_t(ray: &Ray, p: Vec3A) -> f32 {
    let dd = ray.dir.length_squared();
    if dd > 0.0 && dd.is_finite() {
        let t = (p - ray.origin).dot(ray.dir) / dd;
        if t.is_finite() {
            return t;
        }
    }
    0.0
}

impl Primitive for Cone {
    fn bounds(&self) -> Aabb {
        // Each end circle lies within its centre ± radius·sqrt(1 - axis_i^2) per axis.
        let axis = unit_or_zero(self.apex - self.base);
        let spread = (Vec3A::ONE - axis * axis).max(Vec3A::ZERO);
        let ext = |r: f32| Vec3A::new(spread.x.sqrt(), spread.y.sqrt(), spread.z.sqrt()) * r;
        let a = Aabb::new(
            self.base - ext(self.base_radius),
            self.base + ext(self.base_radius),
        );
        let b = Aabb::new(
            self.apex - ext(self.apex_radius),
            self.apex + ext(self.apex_radius),
        );
        a.union(&b)
    }

    fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
        let axis = self.apex - self.base;
        let h = axis.length();
        if !(h > 0.0) {
            return None;
        }
        let w = axis / h;
        let k = (self.apex_radius - self.base_radius) / h;
        let ds = ray.dir.dot(w);
        let dp = ray.dir - w * ds;
        // |op + t dp|^2 = (r0 + r1 t)^2 with the radius r(s) = base_radius + k s along the axis.
        let r1 = k * ds;
        let dpdp = dp.dot(dp);
        let a = dpdp - r1 * r1;
        let parallel = a.abs() <= f32::EPSILON * dpdp.max(r1 * r1);
        // The coefficients from the ray's point at `shift`: the roots are distances from there.
        let from = |shift: f32| {
            let o = (ray.origin + ray.dir * shift) - self.base;
            let os = o.dot(w);
            let op = o - w * os;
            let r0 = self.base_radius + k * os;
            (os, r0, op.dot(dp) - r0 * r1, op.dot(op) - r0 * r0)
        };
        // Solved from the ray's point nearest the cone's middle (see `Sphere::intersect`),
        // then again from the parabola's vertex (midway between the roots): on a flat cone the
        // two nappes lie close together, far from that point, and `b^2 - ac` computed from
        // there cancels to noise in f32 (a cone of radius 1e6 and height 2 lost 29% of its
        // hits); from the vertex `b` and `c` are small and the discriminant exact enough.
        let mut shift = nearest_t(ray, (self.base + self.apex) * 0.5);
        let (mut os, mut r0, mut b, mut c) = from(shift);
        let vertex = -b / a;
        if !parallel && vertex.is_finite() {
            shift += vertex;
            (os, r0, b, c) = from(shift);
        }
        let roots = if parallel {
            // The ray runs parallel to a line of the surface: one root.
            if b == 0.0 {
                return None;
            }
            [-c / (2.0 * b), f32::NAN]
        } else {
            let disc = b * b - a * c;
            if !(disc >= 0.0) {
                return None;
            }
            let q = -(b + disc.sqrt().copysign(b));
            let (x, y) = (q / a, if q != 0.0 { c / q } else { -b / a });
            if x <= y {
                [x, y]
            } else {
                [y, x]
            }
        };
        roots
            .into_iter()
            .find(|&t| {
                let (s, tt) = (os + t * ds, t + shift);
                tt >= ray.t_min && tt <= ray.t_max && (0.0..=h).contains(&s) && r0 + r1 * t >= 0.0
            })
            .map(|t| PrimHit {
                t: t + shift,
                u: 0.0,
                v: 0.0,
            })
    }
}

impl Cone {
    /// [`Cone::intersect`] for eight rays at once, operation for operation (so bit for bit
    /// the same answer): the lanes that hit, and their `t`. Lanes whose ray runs parallel to
    /// a line of the surface (one root) take the scalar test.
    #[inline(always)]
    pub fn intersect_lanes(&self, l: &PacketLanes) -> (u32, f32x8) {
        let axis = self.apex - self.base;
        let h = axis.length();
        if !(h > 0.0) {
            return (0, f32x8::ZERO);
        }
        let w = axis / h;
        let k = (self.apex_radius - self.base_radius) / h;
        let w8 = [f32x8::splat(w.x), f32x8::splat(w.y), f32x8::splat(w.z)];
        let ds = dot8(&l.dir, &w8);
        let dp = [
            l.dir[0] - w8[0] * ds,
            l.dir[1] - w8[1] * ds,
            l.dir[2] - w8[2] * ds,
        ];
        let k8 = f32x8::splat(k);
        let r1 = k8 * ds;
        let dpdp = dot8(&dp, &dp);
        let a = dpdp - r1 * r1;
        // Where `a` is not clearly away from 0 (or is NaN) the scalar test decides.
        let eps = f32x8::splat(f32::EPSILON);
        let quadratic = a.abs().simd_gt(eps * dpdp.max(r1 * r1));
        let from = |shift: f32x8| {
            let o = point_from8(l, shift, self.base);
            let os = dot8(&o, &w8);
            let op = [o[0] - w8[0] * os, o[1] - w8[1] * os, o[2] - w8[2] * os];
            let r0 = f32x8::splat(self.base_radius) + k8 * os;
            (os, r0, dot8(&op, &dp) - r0 * r1, dot8(&op, &op) - r0 * r0)
        };
        // From the nearest point, then from the parabola's vertex, as the scalar test.
        let first = nearest_t8(l, (self.base + self.apex) * 0.5);
        let (_, _, b0, _) = from(first);
        let vertex = -b0 / a;
        let shift = (quadratic & vertex.is_finite()).select(first + vertex, first);
        let (os, r0, b, c) = from(shift);
        let disc = b * b - a * c;
        let ok = quadratic & disc.simd_ge(f32x8::ZERO);
        let (x, y) = roots8(a, b, c, disc);
        let hh = f32x8::splat(h);
        let within = |t: f32x8| {
            let (s, tt) = (os + t * ds, t + shift);
            tt.simd_ge(l.t_min)
                & tt.simd_le(l.t_max)
                & s.simd_ge(f32x8::ZERO)
                & s.simd_le(hh)
                & (r0 + r1 * t).simd_ge(f32x8::ZERO)
        };
        let (in0, in1) = (within(x), within(y));
        let mut hit = (ok & (in0 | in1)).to_bitmask() & l.live;
        let mut t = in0.select(x, y) + shift;
        let odd = !quadratic.to_bitmask() & l.live & 0xFF;
        if odd != 0 {
            let mut ts = t.to_array();
            for (lane, tl) in ts.iter_mut().enumerate() {
                if odd >> lane & 1 == 1 {
                    if let Some(found) = self.intersect(&l.ray(lane)) {
                        hit |= 1 << lane;
                        *tl = found.t;
                    }
                }
            }
            t = f32x8::from(ts);
        }
        (hit, t)
    }
}

impl Primitive for Polygon {
    fn bounds(&self) -> Aabb {
        self.verts.iter().fold(Aabb::EMPTY, |b, &v| {
            let mut b = b;
            b.grow(v);
            b
        })
    }

    fn is_finite(&self) -> bool {
        self.verts.iter().all(|v| v.is_finite())
    }

    fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
        let denom = self.normal.dot(ray.dir);
        if denom == 0.0 {
            return None;
        }
        let t = self.normal.dot(self.verts[0] - ray.origin) / denom;
        if !(t >= ray.t_min && t <= ray.t_max) {
            return None;
        }
        let p = ray.at(t);
        let (i, j) = match self.axis {
            0 => (1, 2),
            1 => (2, 0),
            _ => (0, 1),
        };
        let (px, py) = (p[i], p[j]);
        // Even-odd crossing test along +i from the hit point.
        let mut inside = false;
        let mut prev = self.verts[self.verts.len() - 1];
        for &cur in self.verts.iter() {
            let (ay, by) = (prev[j], cur[j]);
            if (ay > py) != (by > py) {
                let x = prev[i] + (py - ay) / (by - ay) * (cur[i] - prev[i]);
                if px < x {
                    inside = !inside;
                }
            }
            prev = cur;
        }
        inside.then_some(PrimHit { t, u: 0.0, v: 0.0 })
    }
}

impl Primitive for PatchTriangle {
    fn bounds(&self) -> Aabb {
        Primitive::bounds(&self.tri)
    }

    fn is_finite(&self) -> bool {
        self.tri.is_finite()
    }

    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
        self.tri.intersect(ray)
    }

    fn surface_area(&self) -> f32 {
        self.tri.surface_area()
    }
}

impl Primitive for Prim {
    fn bounds(&self) -> Aabb {
        let b = match self {
            Prim::Triangle(t) => Primitive::bounds(t),
            Prim::Patch(p) => p.bounds(),
            Prim::Sphere(s) => s.bounds(),
            Prim::Cone(c) => c.bounds(),
            Prim::Polygon(p) => p.bounds(),
            Prim::Piece(p) => Primitive::bounds(&p.tri),
        };
        if b.is_finite() {
            b
        } else {
            Aabb::new(Vec3A::NAN, Vec3A::NAN)
        }
    }

    fn scaled(&self, s: f32) -> Option<Self> {
        Some(match self {
            Prim::Triangle(t) => Prim::Triangle(t.scaled(s)?),
            Prim::Patch(p) => Prim::Patch(PatchTriangle {
                tri: p.tri.scaled(s)?,
                normals: p.normals,
            }),
            Prim::Sphere(sp) => Prim::Sphere(Sphere {
                center: sp.center * s,
                radius: sp.radius * s,
            }),
            Prim::Cone(c) => Prim::Cone(Cone {
                base: c.base * s,
                base_radius: c.base_radius * s,
                apex: c.apex * s,
                apex_radius: c.apex_radius * s,
            }),
            // Unit normal and projection axis do not change with the size.
            Prim::Polygon(p) => Prim::Polygon(Polygon {
                verts: p.verts.iter().map(|&v| v * s).collect(),
                normal: p.normal,
                axis: p.axis,
            }),
            Prim::Piece(p) => Prim::Piece(PolygonPiece {
                tri: p.tri.scaled(s)?,
                normal: p.normal,
            }),
        })
    }

    /// Triangles and spheres give their own; cones and polygons their box's stand-in.
    fn surface_area(&self) -> f32 {
        match self {
            Prim::Triangle(t) => t.surface_area(),
            Prim::Patch(p) => p.surface_area(),
            Prim::Sphere(s) => s.surface_area(),
            other => other.bounds().half_area(),
        }
    }

    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
        match self {
            Prim::Triangle(t) => t.intersect(ray),
            Prim::Patch(p) => p.intersect(ray),
            Prim::Sphere(s) => s.intersect(ray),
            Prim::Cone(c) => c.intersect(ray),
            Prim::Polygon(p) => p.intersect(ray),
            Prim::Piece(p) => Watertight(p.tri).intersect(ray),
        }
    }

    /// Spheres and cones eight rays at a time ([`Sphere::intersect_lanes`],
    /// [`Cone::intersect_lanes`]), the other kinds ray by ray. Primitive by primitive: each
    /// ray still meets the leaf's primitives in order, each with its interval as shortened
    /// by the ones before, so its answer is the ray-by-ray one.
    #[inline]
    fn intersect_packet<F>(leaf: &[Self], rays: &mut PacketLeaf<'_, F>)
    where
        F: FnMut(usize, u32, PrimHit) -> Option<f32>,
    {
        for (j, p) in leaf.iter().enumerate() {
            if rays.rays() == 0 {
                return;
            }
            match p {
                Prim::Sphere(s) => rays.test_lanes(j, |l| no_uv(s.intersect_lanes(l))),
                Prim::Cone(c) => rays.test_lanes(j, |l| no_uv(c.intersect_lanes(l))),
                other => {
                    let mut m = rays.rays();
                    while m != 0 {
                        let i = m.trailing_zeros() as usize;
                        m &= m - 1;
                        if let Some(h) = other.intersect(&rays.ray(i)) {
                            rays.report(i, j, h);
                        }
                    }
                }
            }
        }
    }
}

/// An eight-ray test's hits and `t` as [`PacketLeaf::test_lanes`] takes them (`u = v = 0`).
#[inline(always)]
fn no_uv((hit, t): (u32, f32x8)) -> (u32, [f32x8; 3]) {
    (hit, [t, f32x8::ZERO, f32x8::ZERO])
}

/// `a · b` of lane vectors, summed as glam sums a `Vec3A` dot product: `(x + y) + z`.
#[inline(always)]
fn dot8(a: &[f32x8; 3], b: &[f32x8; 3]) -> f32x8 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// [`nearest_t`] in eight lanes, operation for operation.
#[inline(always)]
fn nearest_t8(l: &PacketLanes, p: Vec3A) -> f32x8 {
    let dd = dot8(&l.dir, &l.dir);
    let to_p = [
        f32x8::splat(p.x) - l.origin[0],
        f32x8::splat(p.y) - l.origin[1],
        f32x8::splat(p.z) - l.origin[2],
    ];
    let t = dot8(&to_p, &l.dir) / dd;
    let ok = dd.simd_gt(f32x8::ZERO) & dd.is_finite() & t.is_finite();
    ok.select(t, f32x8::ZERO)
}

/// `o + d * s - c` in lanes (the ray's point at `s`, relative to `c`).
#[inline(always)]
fn point_from8(l: &PacketLanes, s: f32x8, c: Vec3A) -> [f32x8; 3] {
    [
        (l.origin[0] + l.dir[0] * s) - f32x8::splat(c.x),
        (l.origin[1] + l.dir[1] * s) - f32x8::splat(c.y),
        (l.origin[2] + l.dir[2] * s) - f32x8::splat(c.z),
    ]
}

/// The two roots of `a t^2 - 2 b t + c` as the scalar tests take them (the half-b form, the
/// smaller root without cancellation), ascending where both are numbers.
#[inline(always)]
fn roots8(a: f32x8, b: f32x8, c: f32x8, disc: f32x8) -> (f32x8, f32x8) {
    let q = -(b + disc.sqrt().copysign(b));
    let x = q / a;
    let y = q.simd_ne(f32x8::ZERO).select(c / q, -b / a);
    let sorted = x.simd_le(y);
    (sorted.select(x, y), sorted.select(y, x))
}

impl Prim {
    /// The shading normal at the hit `(t, u, v)` of `ray` (not normalised to face the ray):
    /// the geometric normal, or for patch triangles the interpolated vertex normal.
    pub fn normal(&self, ray: &Ray, hit: &PrimHit) -> Vec3A {
        let p = ray.at(hit.t);
        match self {
            Prim::Triangle(t) => {
                let (e1, e2) = (t.v[1] - t.v[0], t.v[2] - t.v[0]);
                // Edges of 1e-20 or 1e20 would under- or overflow in the cross product.
                let s = unit_scale(e1.abs().max(e2.abs()).max_element());
                unit_or_zero((e1 * s).cross(e2 * s))
            }
            Prim::Patch(pt) => {
                let w = 1.0 - hit.u - hit.v;
                (pt.normals[0] * w + pt.normals[1] * hit.u + pt.normals[2] * hit.v)
                    .normalize_or_zero()
            }
            Prim::Sphere(s) => ((p - s.center) / s.radius).normalize_or_zero(),
            Prim::Cone(c) => {
                // Lengths brought near 1 by a power of two (exact): `h` and the dot product
                // square them.
                let s = unit_scale((c.apex - c.base).abs().max_element());
                let along = (c.apex - c.base) * s;
                let axis = unit_or_zero(along);
                let h = along.length();
                let rel = (p - c.base) * s;
                let radial = unit_or_zero(rel - axis * rel.dot(axis));
                // The surface leans by the radius change along the axis.
                let slope = (c.base_radius - c.apex_radius) * s / h;
                (radial + axis * slope).normalize_or_zero()
            }
            Prim::Polygon(poly) => poly.normal,
            Prim::Piece(piece) => piece.normal,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hit_t(p: &impl Primitive, o: [f32; 3], d: [f32; 3]) -> Option<f32> {
        p.intersect(&Ray::new(Vec3A::from(o), Vec3A::from(d)))
            .map(|h| h.t)
    }

    #[test]
    fn sphere_from_outside_and_inside() {
        let s = Sphere {
            center: Vec3A::new(1.0, 0.0, 0.0),
            radius: 1.0,
        };
        assert_eq!(hit_t(&s, [-2.0, 0.0, 0.0], [1.0, 0.0, 0.0]), Some(2.0));
        assert_eq!(hit_t(&s, [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]), Some(1.0));
        assert_eq!(hit_t(&s, [-2.0, 1.5, 0.0], [1.0, 0.0, 0.0]), None);
        assert_eq!(hit_t(&s, [3.0, 0.0, 0.0], [1.0, 0.0, 0.0]), None);
    }

    #[test]
    fn cylinder_and_cone() {
        let cyl = Cone {
            base: Vec3A::ZERO,
            base_radius: 1.0,
            apex: Vec3A::new(0.0, 0.0, 2.0),
            apex_radius: 1.0,
        };
        assert_eq!(hit_t(&cyl, [-3.0, 0.0, 1.0], [1.0, 0.0, 0.0]), Some(2.0));
        // Inside, looking out.
        assert_eq!(hit_t(&cyl, [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]), Some(1.0));
        // Beyond the ends: open, so no hit.
        assert_eq!(hit_t(&cyl, [-3.0, 0.0, 2.5], [1.0, 0.0, 0.0]), None);
        // Down the axis of an open cylinder: nothing.
        assert_eq!(hit_t(&cyl, [0.0, 0.0, -1.0], [0.0, 0.0, 1.0]), None);
        let cone = Cone {
            base: Vec3A::ZERO,
            base_radius: 2.0,
            apex: Vec3A::new(0.0, 0.0, 2.0),
            apex_radius: 0.0,
        };
        // At height 1 the radius is 1.
        assert_eq!(hit_t(&cone, [-3.0, 0.0, 1.0], [1.0, 0.0, 0.0]), Some(2.0));
        let b = cone.bounds();
        assert_eq!(
            (b.min, b.max),
            (Vec3A::new(-2.0, -2.0, 0.0), Vec3A::new(2.0, 2.0, 2.0))
        );
    }

    /// Rays that hit, graze and miss `p` (whose surface passes through the points `on`),
    /// run parallel to the lines `along` (a cone's generators and axis), start on and
    /// inside it, or are degenerate (zero, NaN and infinite directions, empty intervals).
    fn hard_rays(rng: &mut crate::rng::Rng, on: &[Vec3A], along: &[Vec3A]) -> Vec<Ray> {
        let mut rays = Vec::new();
        for _ in 0..400 {
            let target = on[rng.next_u64() as usize % on.len()];
            let from = target + rng.unit_vector() * rng.range(0.0, 4.0);
            let jitter = rng.unit_vector() * rng.range(0.0, 0.01);
            let mut ray = Ray::new(from, target + jitter - from);
            match rng.next_u64() % 8 {
                0 => ray.dir = along[rng.next_u64() as usize % along.len()],
                1 => ray.t_max = rng.range(0.0, 1.5),
                2 => ray.t_min = rng.range(0.0, 1.5),
                3 => ray.origin = target,
                _ => {}
            }
            rays.push(ray);
        }
        let o = on[0] + Vec3A::new(0.3, -0.2, 0.1);
        for dir in [
            Vec3A::ZERO,
            Vec3A::X,
            -Vec3A::Z,
            Vec3A::new(f32::NAN, 1.0, 0.0),
            Vec3A::new(f32::INFINITY, 0.0, 0.0),
            Vec3A::new(1e-30, 1e-30, 0.0),
        ] {
            rays.push(Ray::new(o, dir));
        }
        rays.push(Ray::segment(o, Vec3A::X, 2.0, 1.0));
        rays.push(Ray::segment(o, Vec3A::X, 0.0, f32::NEG_INFINITY));
        rays
    }

    /// `intersect_lanes` against `intersect`, lane by lane, bit for bit.
    fn lanes_match(
        what: &str,
        p: &impl Primitive,
        lanes: impl Fn(&PacketLanes) -> (u32, f32x8),
        rays: &[Ray],
    ) -> usize {
        let mut hits = 0;
        for chunk in rays.chunks(8) {
            let mut eight = [chunk[0]; 8];
            eight[..chunk.len()].copy_from_slice(chunk);
            let (mask, t) = lanes(&PacketLanes::from_rays(&eight));
            let t = t.to_array();
            for (l, ray) in eight.iter().enumerate() {
                let want = p.intersect(ray).map(|h| h.t.to_bits());
                let got = (mask >> l & 1 == 1).then(|| t[l].to_bits());
                assert_eq!(got, want, "{what}: {ray:?}");
                hits += want.is_some() as usize;
            }
        }
        hits
    }

    #[test]
    fn eight_lane_spheres_and_cones_answer_as_the_scalar_tests() {
        let mut rng = crate::rng::Rng::new(17);
        for (c, r) in [
            (Vec3A::ZERO, 1.0),
            (Vec3A::new(5.0, -2.0, 0.5), 0.002),
            (Vec3A::splat(1e4), 3.0),
        ] {
            let s = Sphere {
                center: c,
                radius: r,
            };
            let on: Vec<Vec3A> = (0..16).map(|_| c + rng.unit_vector() * r).collect();
            let rays = hard_rays(&mut rng, &on, &[Vec3A::X, Vec3A::Y]);
            let hits = lanes_match("sphere", &s, |l| s.intersect_lanes(l), &rays);
            assert!(hits > rays.len() / 10, "sphere {r}: {hits} hits");
        }
        let cones = [
            (Vec3A::ZERO, 1.0, Vec3A::new(0.0, 0.0, 2.0), 1.0),
            (Vec3A::ZERO, 2.0, Vec3A::new(0.0, 0.0, 2.0), 0.0),
            (
                Vec3A::new(1.0, 2.0, 3.0),
                0.3,
                Vec3A::new(1.5, 2.2, 2.0),
                0.1,
            ),
            (
                Vec3A::new(5.0, 0.0, 0.0),
                0.002,
                Vec3A::new(5.0, 0.01, 0.003),
                0.001,
            ),
        ];
        for (base, base_radius, apex, apex_radius) in cones {
            let c = Cone {
                base,
                base_radius,
                apex,
                apex_radius,
            };
            let axis = apex - base;
            let u = unit_or_zero(axis).any_orthonormal_vector();
            let mut on = Vec::new();
            let mut along = vec![axis, -axis];
            for k in 0..8 {
                let a = k as f32 * std::f32::consts::TAU / 8.0;
                let out = u * a.cos() + unit_or_zero(axis).cross(u) * a.sin();
                let (b, e) = (base + out * base_radius, apex + out * apex_radius);
                along.push(e - b);
                on.push(b + (e - b) * rng.f32());
            }
            let rays = hard_rays(&mut rng, &on, &along);
            let hits = lanes_match("cone", &c, |l| c.intersect_lanes(l), &rays);
            assert!(hits > rays.len() / 10, "cone {base_radius}: {hits} hits");
            // Parallel to one generator and through a point of another: one root (the
            // scalar test's other branch), at that point.
            let mut parallel = Vec::new();
            let generator = |a: f32| {
                let out = u * a.cos() + unit_or_zero(axis).cross(u) * a.sin();
                (base + out * base_radius, apex + out * apex_radius)
            };
            for k in 0..40 {
                let (b, e) = generator(k as f32 * 0.7);
                let (qb, qe) = generator(k as f32 * 0.7 + rng.range(0.5, 3.0));
                let q = qb + (qe - qb) * rng.range(0.1, 0.9);
                parallel.push(Ray::new(q - (e - b) * 2.0, e - b));
            }
            let hits = lanes_match("cone, parallel", &c, |l| c.intersect_lanes(l), &parallel);
            if base_radius != apex_radius {
                assert!(hits > 0, "cone {base_radius}: no parallel ray hits");
            }
        }
    }

    #[test]
    fn concave_polygon() {
        // A U shape: the notch between the arms is outside.
        let u = Polygon::new(
            [
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
            .map(|&[x, y]| Vec3A::new(x, y, 0.0))
            .collect(),
        );
        let down = [0.0, 0.0, -1.0];
        assert_eq!(hit_t(&u, [0.5, 2.0, 1.0], down), Some(1.0));
        assert_eq!(hit_t(&u, [1.5, 2.0, 1.0], down), None);
        assert_eq!(hit_t(&u, [1.5, 0.5, 1.0], down), Some(1.0));
        assert_eq!(hit_t(&u, [3.5, 0.5, 1.0], down), None);
        assert_eq!(u.normal(), Vec3A::Z);
    }
}
