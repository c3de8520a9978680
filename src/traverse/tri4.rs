//! Leaf tests over [`Tri4`] groups: four triangles per SIMD test, each lane computing exactly
//! what the scalar test ([`crate::Triangle::intersect`] or
//! [`crate::intersect::Watertight`]) computes for that triangle, so the answers are the
//! scalar leaf test's, ties by primitive index included. [`super::leaves::Leaves`] picks
//! them for triangle leaf formats.

use super::lane8::F8;
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

/// The watertight test's shear of `ray` (largest axis last) and its factors; the identity for
/// the fast test, which does not read them.
#[inline(always)]
fn shear_terms(ray: &Ray, format: LeafFormat) -> ([usize; 3], [f32; 3]) {
    if format == LeafFormat::WatertightTriangles {
        let d: [f32; 3] = ray.dir.into();
        let (kx, ky, kz) = crate::intersect::shear_axes(ray.dir);
        let sz = 1.0 / d[kz];
        ([kx, ky, kz], [d[kx] * sz, d[ky] * sz, sz])
    } else {
        ([0, 1, 2], [0.0; 3])
    }
}

impl Ray4Tri {
    #[inline(always)]
    pub(crate) fn new(ray: &Ray, format: LeafFormat) -> Self {
        let (k, s) = shear_terms(ray, format);
        Self::of(ray, k, s)
    }

    #[inline(always)]
    fn of(ray: &Ray, k: [usize; 3], s: [f32; 3]) -> Self {
        let o: [f32; 3] = ray.origin.into();
        let d: [f32; 3] = ray.dir.into();
        Ray4Tri {
            o: [f32x4::splat(o[0]), f32x4::splat(o[1]), f32x4::splat(o[2])],
            d: [f32x4::splat(d[0]), f32x4::splat(d[1]), f32x4::splat(d[2])],
            k,
            s: [f32x4::splat(s[0]), f32x4::splat(s[1]), f32x4::splat(s[2])],
            t_min: f32x4::splat(ray.t_min),
        }
    }
}

/// A ray's terms for two groups tested as one, in eight lanes of `V` (the second group's
/// lanes beside the first's).
pub(crate) struct Ray8Tri<V: F8> {
    o: [V; 3],
    d: [V; 3],
    s: [V; 3],
    t_min: V,
}

/// A ray's terms for a leaf's group tests, made at its first leaf: four lanes for a lone
/// group, eight for a pair.
pub(crate) struct LeafRay<V: F8> {
    four: Ray4Tri,
    eight: Ray8Tri<V>,
}

impl<V: F8> LeafRay<V> {
    #[inline(always)]
    fn new(cpu: V::Cpu, ray: &Ray, format: LeafFormat) -> Self {
        let (k, s) = shear_terms(ray, format);
        let o: [f32; 3] = ray.origin.into();
        let d: [f32; 3] = ray.dir.into();
        LeafRay {
            four: Ray4Tri::of(ray, k, s),
            eight: Ray8Tri {
                o: V::splat3(cpu, o),
                d: V::splat3(cpu, d),
                s: V::splat3(cpu, s),
                t_min: V::splat(cpu, ray.t_min),
            },
        }
    }
}

/// Row `v`, axis `a` of groups `g` and `h` side by side in eight lanes.
#[inline(always)]
fn pair_row<V: F8>(cpu: V::Cpu, g: &Tri4, h: &Tri4, v: usize, a: usize) -> V {
    V::load_halves(cpu, &g.rows[v][a], &h.rows[v][a])
}

/// [`fast4`] of groups `g` and `h` at once, in eight lanes of `V`: lane for lane the same
/// operations.
#[inline(always)]
fn fast8<V: F8>(
    cpu: V::Cpu,
    (g, h): (&Tri4, &Tri4),
    r: &Ray8Tri<V>,
    t_max: f32,
) -> (u32, [f32; 8], [f32; 8], [f32; 8]) {
    let [dx, dy, dz] = r.d;
    let (e1x, e1y, e1z) = (
        pair_row::<V>(cpu, g, h, 1, 0),
        pair_row::<V>(cpu, g, h, 1, 1),
        pair_row::<V>(cpu, g, h, 1, 2),
    );
    let (e2x, e2y, e2z) = (
        pair_row::<V>(cpu, g, h, 2, 0),
        pair_row::<V>(cpu, g, h, 2, 1),
        pair_row::<V>(cpu, g, h, 2, 2),
    );
    let nx = e1y.mul(e2z).sub(e1z.mul(e2y));
    let ny = e1z.mul(e2x).sub(e1x.mul(e2z));
    let nz = e1x.mul(e2y).sub(e1y.mul(e2x));
    let det = nx.mul(dx).add(ny.mul(dy)).add(nz.mul(dz));
    let inv = V::splat(cpu, 1.0).div(det);
    let cx = pair_row::<V>(cpu, g, h, 0, 0).sub(r.o[0]);
    let cy = pair_row::<V>(cpu, g, h, 0, 1).sub(r.o[1]);
    let cz = pair_row::<V>(cpu, g, h, 0, 2).sub(r.o[2]);
    let rx = dy.mul(cz).sub(cy.mul(dz));
    let ry = dz.mul(cx).sub(cz.mul(dx));
    let rz = dx.mul(cy).sub(cx.mul(dy));
    let u = rx.mul(e2x).add(ry.mul(e2y)).add(rz.mul(e2z)).mul(inv);
    let v = rx.mul(e1x).add(ry.mul(e1y)).add(rz.mul(e1z)).mul(inv);
    let t = nx.mul(cx).add(ny.mul(cy)).add(nz.mul(cz)).mul(inv);
    let zero = V::splat(cpu, 0.0);
    let ok = det
        .ne(zero)
        .and(u.ge(zero))
        .and(v.ge(zero))
        .and(u.add(v).le(V::splat(cpu, 1.0)))
        .and(t.ge(r.t_min))
        .and(t.le(V::splat(cpu, t_max)));
    (ok.bitmask(), t.to_array(), u.to_array(), v.to_array())
}

/// [`watertight4`] of groups `g` and `h` at once, in eight lanes of `V`.
#[inline(always)]
fn watertight8<V: F8>(
    cpu: V::Cpu,
    (g, h): (&Tri4, &Tri4),
    k: [usize; 3],
    r: &Ray8Tri<V>,
    t_max: f32,
) -> (u32, u32, [f32; 8], [f32; 8], [f32; 8]) {
    let [kx, ky, kz] = k;
    let [sx, sy, sz] = r.s;
    // Written as a function, not a closure: lane operations must stay inside the kernel.
    #[inline(always)]
    fn rel<V: F8>(cpu: V::Cpu, gh: (&Tri4, &Tri4), o: &[V; 3], v: usize, a: usize) -> V {
        pair_row::<V>(cpu, gh.0, gh.1, v, a).sub(o[a])
    }
    let o = &r.o;
    let (z0, z1, z2) = (
        rel(cpu, (g, h), o, 0, kz),
        rel(cpu, (g, h), o, 1, kz),
        rel(cpu, (g, h), o, 2, kz),
    );
    let x = [
        rel(cpu, (g, h), o, 0, kx).sub(sx.mul(z0)),
        rel(cpu, (g, h), o, 1, kx).sub(sx.mul(z1)),
        rel(cpu, (g, h), o, 2, kx).sub(sx.mul(z2)),
    ];
    let y = [
        rel(cpu, (g, h), o, 0, ky).sub(sy.mul(z0)),
        rel(cpu, (g, h), o, 1, ky).sub(sy.mul(z1)),
        rel(cpu, (g, h), o, 2, ky).sub(sy.mul(z2)),
    ];
    let u = x[2].mul(y[1]).sub(y[2].mul(x[1]));
    let v = x[0].mul(y[2]).sub(y[0].mul(x[2]));
    let w = x[1].mul(y[0]).sub(y[1].mul(x[0]));
    let zero = V::splat(cpu, 0.0);
    let lo = u.min_nan_first(v).min_nan_first(w);
    let hi = u.max_nan_first(v).max_nan_first(w);
    let inside = zero.lt(lo).or(hi.lt(zero));
    let edge = u.mul(v).mul(w).eq(zero).and_not(inside);
    if inside.or(edge).bitmask() == 0 {
        return (0, 0, [0.0; 8], [0.0; 8], [0.0; 8]);
    }
    let det = u.add(v).add(w);
    let t_scaled = u
        .mul(sz.mul(z0))
        .add(v.mul(sz.mul(z1)))
        .add(w.mul(sz.mul(z2)));
    let inv = V::splat(cpu, 1.0).div(det);
    let t = t_scaled.mul(inv);
    let ok = inside.and(t.ge(r.t_min)).and(t.le(V::splat(cpu, t_max)));
    let (hu, hv) = (v.mul(inv), w.mul(inv));
    (
        ok.bitmask(),
        edge.bitmask(),
        t.to_array(),
        hu.to_array(),
        hv.to_array(),
    )
}

/// Hits of groups `g` and `h` tested as one in `format` within `[t_min, t_max]`: `(lane,
/// hit)` for each, lanes 4 to 7 being `h`'s. Neither group is far.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn pair_hits<V: F8>(
    cpu: V::Cpu,
    (g, h): (&Tri4, &Tri4),
    r: &LeafRay<V>,
    ray: &Ray,
    t_max: f32,
    format: LeafFormat,
    mut hit: impl FnMut(usize, PrimHit),
) {
    // The fast test has no edge lanes; `format` is a constant here, so that loop compiles away.
    let (ok, edge, t, u, v) = if format == LeafFormat::WatertightTriangles {
        watertight8::<V>(cpu, (g, h), r.four.k, &r.eight, t_max)
    } else {
        let (ok, t, u, v) = fast8::<V>(cpu, (g, h), &r.eight, t_max);
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
        let group = if l < 4 { g } else { h };
        if let Some(e) = edge_hit(group, l & 3, ray, t_max) {
            hit(l, e);
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

/// [`test_groups`] for a layout holding far groups, out of the fast path's line, on the
/// portable lanes: from `best`, the new best and whether it changed. By value, and with the
/// ray's group terms made here, so the fast path's search state never has its address taken
/// (which would keep it in memory).
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
    let r = LeafRay::<wide::f32x8>::new((), ray, format);
    let found = test_groups::<wide::f32x8, A, S, F, true>(
        (),
        groups,
        count,
        ray,
        &r,
        format,
        &mut best,
        stats,
        filter,
    );
    (found, best)
}

/// A triangle leaf's search through [`test_groups`], the ray's group terms made at its first
/// leaf (`prep`, see [`prepared`]).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn test_leaf<V: F8, A: Ask, S: Stats, F: Filter<Hit>, const FAR: bool>(
    cpu: V::Cpu,
    groups: LeafGroups<'_>,
    count: u32,
    ray: &Ray,
    prep: &mut Option<LeafRay<V>>,
    format: LeafFormat,
    best: &mut Hit,
    stats: &mut S,
    filter: &mut F,
) -> bool {
    let r = prepared::<V>(cpu, prep, ray, format);
    test_groups::<V, A, S, F, FAR>(cpu, groups, count, ray, r, format, best, stats, filter)
}

/// The ray's group terms, made at its first leaf. The watertight shear (an axis choice, a
/// division, splats) is made out of line: inlined, the compiler hoisted it to every ray's
/// entry, though most rays reach no leaf, and held its terms in registers the walk needed.
/// The fast terms are splats of the ray and stay inline.
#[inline(always)]
fn prepared<'p, V: F8>(
    cpu: V::Cpu,
    prep: &'p mut Option<LeafRay<V>>,
    ray: &Ray,
    format: LeafFormat,
) -> &'p LeafRay<V> {
    // Written out rather than `get_or_insert_with`: a std combinator taking a closure may be
    // compiled out of line in the caller's crate, outside the kernel's target features.
    // The outlined shear writes into `prep` itself: returned by value, its 512 bytes were
    // copied by a `memcpy` call on every ray that reached a leaf.
    if prep.is_none() {
        if format == LeafFormat::WatertightTriangles {
            V::outlined(
                cpu,
                #[inline(always)]
                || *prep = Some(LeafRay::<V>::new(cpu, ray, format)),
            );
        } else {
            *prep = Some(LeafRay::<V>::new(cpu, ray, format));
        }
    }
    match prep {
        Some(r) => r,
        None => unreachable!("made above"),
    }
}

/// The search `A` among a leaf's groups (`count` triangles in the leaf), improving `best`:
/// every group for the closest hit, until one is kept for any hit. Returns true when `best`
/// changed. Two groups are tested as one in eight lanes (a leaf of five to eight triangles in
/// one test), a lone group in four. `FAR`: as for [`group_hits`]; a far group goes alone.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn test_groups<V: F8, A: Ask, S: Stats, F: Filter<Hit>, const FAR: bool>(
    cpu: V::Cpu,
    (groups, first, far): LeafGroups<'_>,
    count: u32,
    ray: &Ray,
    r: &LeafRay<V>,
    format: LeafFormat,
    best: &mut Hit,
    stats: &mut S,
    filter: &mut F,
) -> bool {
    let mut found = false;
    let mut i = 0;
    while i < groups.len() {
        let pair = i + 1 < groups.len() && !(FAR && (far.has(first + i) || far.has(first + i + 1)));
        if pair {
            let (g, h) = (&groups[i], &groups[i + 1]);
            // Any hit keeps the first candidate its filter accepts; the other lanes are then
            // not offered.
            pair_hits::<V>(
                cpu,
                (g, h),
                r,
                ray,
                best.t,
                format,
                #[inline(always)]
                |l, hit| {
                    if !(A::ANY && found) {
                        let id = if l < 4 { g.id[l] } else { h.id[l - 4] };
                        found |= offer::<A, F>(best, id, hit, filter);
                    }
                },
            );
            i += 2;
        } else {
            let g = (&groups[i], FAR && far.has(first + i));
            group_hits::<FAR>(
                g,
                &r.four,
                ray,
                best.t,
                format,
                #[inline(always)]
                |l, hit| {
                    if !(A::ANY && found) {
                        found |= offer::<A, F>(best, g.0.id[l], hit, filter);
                    }
                },
            );
            i += 1;
        }
        if A::ANY && found {
            stats.prims((4 * i as u32).min(count));
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
