//! Leaf tests over [`Tri4`] groups: four triangles per SIMD test, each lane computing exactly
//! what the scalar test ([`crate::Triangle::intersect`] or
//! [`crate::intersect::Watertight`]) computes for that triangle, so the answers are the
//! scalar leaf test's, ties by primitive index included. [`super::leaves::Leaves`] picks
//! them for triangle leaf formats.

use super::search::offer;
use super::simd::bits;
use super::{Ask, Filter, Stats};
use crate::geometry::{Hit, PrimHit, Ray};
use crate::intersect::Watertight;
use crate::layout::tri4::FarGroups;
use crate::layout::Tri4;
use crate::primitive::{LeafFormat, Primitive};
use wide::f32x4;

/// A ray's terms for the group tests, splatted once per leaf.
pub(crate) struct Ray4Tri {
    o: [f32x4; 3],
    d: [f32x4; 3],
    /// Watertight: the shear (largest axis last) and its factors.
    k: [usize; 3],
    s: [f32x4; 3],
    t_min: f32x4,
}

impl Ray4Tri {
    #[inline(always)]
    pub(crate) fn new(ray: &Ray, format: LeafFormat) -> Self {
        let o: [f32; 3] = ray.origin.into();
        let d: [f32; 3] = ray.dir.into();
        let (k, s) = if format == LeafFormat::WatertightTriangles {
            let (kx, ky, kz) = crate::intersect::shear_axes(ray.dir);
            let sz = 1.0 / d[kz];
            ([kx, ky, kz], [d[kx] * sz, d[ky] * sz, sz])
        } else {
            ([0, 1, 2], [0.0; 3])
        };
        Ray4Tri {
            o: o.map(f32x4::splat),
            d: d.map(f32x4::splat),
            k,
            s: s.map(f32x4::splat),
            t_min: f32x4::splat(ray.t_min),
        }
    }
}

#[inline(always)]
fn row(g: &Tri4, v: usize, a: usize) -> f32x4 {
    f32x4::from(g.rows[v][a])
}

/// The fast test of one group: the mask of lanes hit within `[t_min, t_max]` and their
/// `t`, `u`, `v`, in [`crate::Triangle::intersect`]'s operations (glam's dot and cross orders).
#[inline(always)]
fn fast4(g: &Tri4, r: &Ray4Tri, t_max: f32) -> (u32, [f32; 4], [f32; 4], [f32; 4]) {
    let [dx, dy, dz] = r.d;
    let (e1x, e1y, e1z) = (row(g, 1, 0), row(g, 1, 1), row(g, 1, 2));
    let (e2x, e2y, e2z) = (row(g, 2, 0), row(g, 2, 1), row(g, 2, 2));
    // n = e1 × e2 as glam computes it (and as packing did before), each component a product
    // minus a product.
    let nx = e1y * e2z - e1z * e2y;
    let ny = e1z * e2x - e1x * e2z;
    let nz = e1x * e2y - e1y * e2x;
    let det = (nx * dx + ny * dy) + nz * dz;
    let inv = f32x4::ONE / det;
    let [cx, cy, cz] = [0, 1, 2].map(|a| row(g, 0, a) - r.o[a]);
    // d × c as glam computes it: each component a product minus a product.
    let rx = dy * cz - cy * dz;
    let ry = dz * cx - cz * dx;
    let rz = dx * cy - cx * dy;
    let u = ((rx * e2x + ry * e2y) + rz * e2z) * inv;
    let v = ((rx * e1x + ry * e1y) + rz * e1z) * inv;
    let t = ((nx * cx + ny * cy) + nz * cz) * inv;
    let ok = det.simd_ne(f32x4::ZERO)
        & u.simd_ge(f32x4::ZERO)
        & v.simd_ge(f32x4::ZERO)
        & (u + v).simd_le(f32x4::ONE)
        & t.simd_ge(r.t_min)
        & t.simd_le(f32x4::splat(t_max));
    (ok.to_bitmask(), t.to_array(), u.to_array(), v.to_array())
}

/// The watertight test of one group, in [`Watertight`]'s operations: the mask of lanes hit
/// and their `t`, `u`, `v`, plus the mask of lanes on an edge in f32 (some edge function
/// exactly zero), which the caller decides with the scalar test (its f64 fallback).
#[inline(always)]
fn watertight4(g: &Tri4, r: &Ray4Tri, t_max: f32) -> (u32, u32, [f32; 4], [f32; 4], [f32; 4]) {
    let [kx, ky, kz] = r.k;
    let [sx, sy, sz] = r.s;
    let rel = |v: usize, a: usize| row(g, v, a) - r.o[a];
    let x = [0, 1, 2].map(|v| rel(v, kx) - sx * rel(v, kz));
    let y = [0, 1, 2].map(|v| rel(v, ky) - sy * rel(v, kz));
    let u = x[2] * y[1] - y[2] * x[1];
    let v = x[0] * y[2] - y[0] * x[2];
    let w = x[1] * y[0] - y[1] * x[0];
    let zero = f32x4::ZERO;
    // An unused lane is NaN: of no sign, never on an edge, and its t fails the range test.
    // Inside: edge functions all of one sign, none zero (the scalar test's sign test where it
    // stays in f32); it also makes the determinant nonzero, a sum of nonzero terms of one sign.
    let lo = u.fast_min(v).fast_min(w);
    let hi = u.fast_max(v).fast_max(w);
    let inside = lo.simd_gt(zero) | hi.simd_lt(zero);
    // On an edge: some edge function zero, which the scalar test decides in f64. A product
    // that underflowed adds lanes the scalar test decides alike; one inside is decided here.
    let edge = (u * v * w).simd_eq(zero) & !inside;
    // Most groups a ray reaches it misses: no lane inside or on an edge leaves nothing for
    // the distance (a division) to decide.
    if (inside | edge).none() {
        return (0, 0, [0.0; 4], [0.0; 4], [0.0; 4]);
    }
    let det = u + v + w;
    let z = [0, 1, 2].map(|v| sz * rel(v, kz));
    let t_scaled = u * z[0] + v * z[1] + w * z[2];
    let inv = f32x4::ONE / det;
    let t = t_scaled * inv;
    let ok = inside & t.simd_ge(r.t_min) & t.simd_le(f32x4::splat(t_max));
    let (hu, hv) = (v * inv, w * inv);
    (
        ok.to_bitmask(),
        edge.to_bitmask(),
        t.to_array(),
        hu.to_array(),
        hv.to_array(),
    )
}

/// A leaf's groups as the kernels take them: the groups, the index of the first in the
/// layout, and the layout's far groups.
pub(crate) type LeafGroups<'a> = (&'a [Tri4], usize, &'a FarGroups);

/// Hits of one group in `format` within `[t_min, t_max]`: `(lane, hit)` for each. `far`:
/// the group is stored far and is tested lane by lane; only looked at when `FAR` (the
/// layout holds far groups).
#[inline(always)]
pub(crate) fn group_hits<const FAR: bool>(
    (g, far): (&Tri4, bool),
    r: &Ray4Tri,
    ray: &Ray,
    t_max: f32,
    format: LeafFormat,
    mut hit: impl FnMut(usize, PrimHit),
) {
    if FAR && far {
        for (l, h) in far_hits(g, ray, t_max, format).into_iter().enumerate() {
            if let Some(h) = h {
                hit(l, h);
            }
        }
        return;
    }
    // The fast test has no edge lanes; `format` is a constant here, so that loop compiles away.
    let (ok, edge, t, u, v) = if format == LeafFormat::WatertightTriangles {
        watertight4(g, r, t_max)
    } else {
        let (ok, t, u, v) = fast4(g, r, t_max);
        (ok, 0, t, u, v)
    };
    for l in bits(ok) {
        hit(
            l,
            PrimHit {
                t: t[l],
                u: u[l],
                v: v[l],
            },
        );
    }
    for l in bits(edge) {
        if let Some(h) = edge_hit(g, l, ray, t_max) {
            hit(l, h);
        }
    }
}

/// One lane of a group on an edge in f32, decided by the scalar watertight test (its f64
/// fallback). Out of line, so the walks do not compute its per-ray terms (the shear) at every
/// ray's entry, as the compiler did when this was inlined: almost no ray comes here.
#[cold]
#[inline(never)]
fn edge_hit(g: &Tri4, l: usize, ray: &Ray, t_max: f32) -> Option<PrimHit> {
    Watertight(g.triangle(l)).intersect(&Ray { t_max, ..*ray })
}

/// A far group's hits ([`Tri4`]): each lane by the scalar test of `format`, which rescales
/// what would leave f32's range.
#[cold]
#[inline(never)]
fn far_hits(g: &Tri4, ray: &Ray, t_max: f32, format: LeafFormat) -> [Option<PrimHit>; 4] {
    let ray = Ray { t_max, ..*ray };
    std::array::from_fn(|l| {
        let t = g.triangle(l);
        match format {
            LeafFormat::WatertightTriangles => Watertight(t).intersect(&ray),
            _ => t.intersect(&ray),
        }
    })
}

/// [`test_groups`] for a layout holding far groups, out of the fast path's line: from `best`,
/// the new best and whether it changed. By value, and with the ray's group terms made here,
/// so the fast path's search state never has its address taken (which would keep it in
/// memory).
#[cold]
#[inline(never)]
pub(crate) fn test_far<A: Ask, S: Stats, F: Filter<Hit>>(
    groups: LeafGroups<'_>,
    count: u32,
    ray: &Ray,
    format: LeafFormat,
    mut best: Hit,
    stats: &mut S,
    filter: &mut F,
) -> (bool, Hit) {
    let r = Ray4Tri::new(ray, format);
    let found = test_groups::<A, S, F, true>(groups, count, ray, &r, format, &mut best, stats, filter);
    (found, best)
}

/// A triangle leaf's search through [`test_groups`], the ray's group terms made at its first
/// leaf (`prep`, see [`prepared`]).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn test_leaf<A: Ask, S: Stats, F: Filter<Hit>, const FAR: bool>(
    groups: LeafGroups<'_>,
    count: u32,
    ray: &Ray,
    prep: &mut Option<Ray4Tri>,
    format: LeafFormat,
    best: &mut Hit,
    stats: &mut S,
    filter: &mut F,
) -> bool {
    let r = prepared(prep, ray, format);
    test_groups::<A, S, F, FAR>(groups, count, ray, r, format, best, stats, filter)
}

/// The ray's group terms, made at its first leaf. The watertight shear (an axis choice, a
/// division, splats) is made out of line: inlined, the compiler hoisted it to every ray's
/// entry, though most rays reach no leaf, and held its terms in registers the walk needed.
/// The fast terms are splats of the ray and stay inline.
#[inline(always)]
fn prepared<'p>(prep: &'p mut Option<Ray4Tri>, ray: &Ray, format: LeafFormat) -> &'p Ray4Tri {
    if format == LeafFormat::WatertightTriangles {
        prep.get_or_insert_with(|| shear(ray))
    } else {
        prep.get_or_insert_with(|| Ray4Tri::new(ray, format))
    }
}

/// [`Ray4Tri::new`] for the watertight test, out of line (see [`prepared`]).
#[cold]
#[inline(never)]
fn shear(ray: &Ray) -> Ray4Tri {
    Ray4Tri::new(ray, LeafFormat::WatertightTriangles)
}

/// The search `A` among a leaf's groups (`count` triangles in the leaf), improving `best`:
/// every group for the closest hit, until one is kept for any hit. Returns true when `best`
/// changed. `FAR`: as for [`group_hits`].
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn test_groups<A: Ask, S: Stats, F: Filter<Hit>, const FAR: bool>(
    (groups, first, far): LeafGroups<'_>,
    count: u32,
    ray: &Ray,
    r: &Ray4Tri,
    format: LeafFormat,
    best: &mut Hit,
    stats: &mut S,
    filter: &mut F,
) -> bool {
    let mut found = false;
    for i in 0..groups.len() {
        let g = (&groups[i], FAR && far.has(first + i));
        // Any hit keeps the first candidate its filter accepts, and the group's other lanes
        // are then not offered.
        group_hits::<FAR>(g, r, ray, best.t, format, |l, h| {
            if !(A::ANY && found) {
                found |= offer::<A, F>(best, g.0.id[l], h, filter);
            }
        });
        if A::ANY && found {
            stats.prims((4 * (i as u32 + 1)).min(count));
            return true;
        }
    }
    stats.prims(count);
    if !found {
        stats.empty_leaf();
    }
    found
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{pow2, Triangle};
    use crate::layout::tri4::fill;
    use crate::rng::Rng;
    use bytemuck::Zeroable;
    use glam::Vec3A;

    /// Each lane of the watertight group test answers exactly as the scalar watertight test
    /// (hit or miss; t, u, v bit for bit), and once: on rays through the shared vertex and
    /// edge points of a fan (edge functions exactly zero, the scalar test's f64 fallback), on
    /// rays through random interior points, and at a scale inside the SIMD band where the
    /// product of the edge functions underflows (lanes the group sends to the scalar test
    /// although no edge function is zero).
    #[test]
    fn watertight_groups_answer_as_the_scalar_test() {
        let mut rng = Rng::new(7);
        let mut zero_lanes = 0;
        let mut edge_lanes = [0usize; 2];
        for (scale_index, scale) in [1.0, pow2(-38)].into_iter().enumerate() {
            for _ in 0..300 {
                // Four triangles around a shared centre, each sharing an edge with the next.
                let centre = rng.in_box(Vec3A::splat(-scale), Vec3A::splat(scale));
                let ring: Vec<Vec3A> = (0..5)
                    .map(|_| centre + rng.in_box(Vec3A::splat(-scale), Vec3A::splat(scale)))
                    .collect();
                let tris: [Option<Triangle>; 4] =
                    std::array::from_fn(|i| Some(Triangle::new(centre, ring[i], ring[i + 1])));
                let mut g = Tri4::zeroed();
                if fill(&mut g, &tris, LeafFormat::WatertightTriangles) {
                    // A far group is tested lane by lane with the scalar test.
                    continue;
                }
                let mut targets = vec![centre, (centre + ring[1]) * 0.5, ring[2]];
                for t in tris.iter().flatten() {
                    let a = 0.3 * rng.in_box(Vec3A::ZERO, Vec3A::ONE).x;
                    targets.push(t.v[0] + (t.v[1] - t.v[0]) * a + (t.v[2] - t.v[0]) * 0.3);
                }
                for target in targets {
                    let origin =
                        target + rng.in_box(Vec3A::splat(-4.0 * scale), Vec3A::splat(4.0 * scale));
                    let ray = Ray::new(origin, target - origin);
                    let r = Ray4Tri::new(&ray, LeafFormat::WatertightTriangles);
                    let (_, edge, ..) = watertight4(&g, &r, ray.t_max);
                    edge_lanes[scale_index] += edge.count_ones() as usize;
                    let mut got = [None; 4];
                    group_hits::<false>(
                        (&g, false),
                        &r,
                        &ray,
                        ray.t_max,
                        LeafFormat::WatertightTriangles,
                        |l, h| {
                            assert!(got[l].is_none(), "lane {l} reported twice");
                            got[l] = Some(h);
                        },
                    );
                    for (l, t) in tris.iter().enumerate() {
                        let want = Watertight(t.unwrap()).intersect(&ray);
                        let bits =
                            |h: Option<PrimHit>| h.map(|h| [h.t, h.u, h.v].map(f32::to_bits));
                        assert_eq!(
                            bits(got[l]),
                            bits(want),
                            "lane {l}, scale {scale}, ray {ray:?}"
                        );
                        zero_lanes += usize::from(edge >> l & 1 == 1 && want.is_some());
                    }
                }
            }
        }
        // Both kinds of lane the scalar test decides were met.
        assert!(edge_lanes[0] > 0 && edge_lanes[1] > 0, "{edge_lanes:?}");
        assert!(zero_lanes > 0);
    }
}
