//! What a search does with a primitive's hit: the test every kernel and the reference apply
//! ([`prim_hit`]), the closest-hit and any-hit bookkeeping written once over [`Ask`]
//! ([`offer`]), and the plain leaves' test ([`test_prims`]).

use super::{Ask, Filter, Stats};
use crate::geometry::{Hit, PrimHit, Ray};
use crate::intersect::Watertight;
use crate::primitive::{LeafFormat, Primitive};

/// The test every kernel and the reference apply to a primitive: [`Primitive::intersect`] for
/// plain types; for a triangle [`LeafFormat`], the triangle [`Primitive::triangle`] gives,
/// with the format's arithmetic (what the SIMD groups compute), so a type is tested alike in
/// every layout and `intersect` is never consulted. A triangle type without a triangle is
/// never hit.
#[inline(always)]
pub(crate) fn prim_hit<P: Primitive>(p: &P, ray: &Ray) -> Option<PrimHit> {
    match P::LEAF_FORMAT {
        LeafFormat::Plain => p.intersect(ray),
        LeafFormat::FastTriangles => p.triangle()?.intersect(ray),
        LeafFormat::WatertightTriangles => Watertight(p.triangle()?).intersect(ray),
    }
}

/// Offers primitive `prim`'s hit `h` (inside the search interval) to the search at `best`:
/// the closest-hit search keeps it when it beats `best` (nearer, or as near with a lower
/// index), the any-hit search keeps any; either only where `filter` accepts it, so a filter is
/// only asked about candidates that would change the answer. Returns true when kept.
#[inline(always)]
pub(crate) fn offer<A: Ask, F: Filter<Hit>>(
    best: &mut Hit,
    prim: u32,
    h: PrimHit,
    filter: &mut F,
) -> bool {
    if !A::ANY && !best.is_beaten_by(h.t, prim) {
        return false;
    }
    let candidate = Hit {
        t: h.t,
        prim,
        u: h.u,
        v: h.v,
    };
    if F::ACTIVE && !filter.accept(&candidate) {
        return false;
    }
    *best = candidate;
    true
}

/// Tests a plain leaf's primitives (`prim_ids` their input indices) for the search `A` at
/// `best`: every one for the closest hit, until one is kept for any hit. Returns true when
/// `best` changed.
#[inline(always)]
pub(crate) fn test_prims<A: Ask, P: Primitive, S: Stats, F: Filter<Hit>>(
    prims: &[P],
    prim_ids: &[u32],
    ray: &Ray,
    best: &mut Hit,
    stats: &mut S,
    filter: &mut F,
) -> bool {
    // The interval up to the best hit so far (any hit stops at its first, so it searches
    // the whole ray): a primitive beyond it cannot change the answer.
    let shortened;
    let r = if A::ANY {
        ray
    } else {
        shortened = Ray {
            t_max: best.t,
            ..*ray
        };
        &shortened
    };
    let mut found = false;
    for i in 0..prims.len().min(prim_ids.len()) {
        if let Some(h) = prim_hit(&prims[i], r) {
            if offer::<A, F>(best, prim_ids[i], h, filter) {
                found = true;
                if A::ANY {
                    stats.prims(i as u32 + 1);
                    return true;
                }
            }
        }
    }
    stats.prims(prims.len() as u32);
    if !found {
        stats.empty_leaf();
    }
    found
}
