//! What a refit takes: the moved primitives, read by input index ([`MovedPrims`]) and checked
//! against what the tree holds before anything changes ([`check_moved`], [`RefitError`]).

use super::refit::RefitInput;
use super::Inputs;
use crate::frame::{Frame, Sizes};
use crate::geometry::Aabb;
use crate::mesh::MeshError;
use crate::primitive::Primitive;
use rayon::prelude::*;
use std::fmt;

/// Why a refit ([`crate::Bvh::refit`], [`crate::Bvh::refit_mesh`], or a layout's own `refit`)
/// refused its input. The BVH is left as it was.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RefitError {
    /// `given` primitives (or mesh triangles) for a BVH built over `expected`: a refit takes
    /// the build's primitives, moved, in the same order.
    Count {
        /// The primitives the BVH was built over (any it dropped included).
        expected: usize,
        /// The primitives given.
        given: usize,
    },
    /// Primitive `prim` has a non-finite coordinate. The build drops such primitives; a refit
    /// keeps the tree's primitives, so one the tree holds cannot become non-finite (rebuild to
    /// leave it out).
    NonFinite {
        /// Its index in the input.
        prim: usize,
    },
    /// Primitive `prim` is finite, but the build left it out (it had a non-finite coordinate
    /// then): a refit cannot add it to the tree (rebuild to include it).
    NotInTree {
        /// Its index in the input.
        prim: usize,
    },
    /// An index of the new mesh names no vertex.
    Mesh(MeshError),
}

impl fmt::Display for RefitError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RefitError::Count { expected, given } => write!(
                f,
                "{given} primitives given to refit a BVH built over {expected}: a refit takes \
                 the same primitives, moved, in the same order"
            ),
            RefitError::NonFinite { prim } => write!(
                f,
                "primitive {prim} has a non-finite coordinate: the tree holds it, and a refit \
                 cannot drop it (rebuild to leave it out)"
            ),
            RefitError::NotInTree { prim } => write!(
                f,
                "primitive {prim} is finite, but the build left it out for a non-finite \
                 coordinate: a refit cannot add it (rebuild to include it)"
            ),
            RefitError::Mesh(e) => write!(f, "the new mesh: {e}"),
        }
    }
}

impl std::error::Error for RefitError {}

impl From<MeshError> for RefitError {
    fn from(e: MeshError) -> Self {
        RefitError::Mesh(e)
    }
}

/// The new input as a refit reads it: primitive `i` from `get`, brought into `frame`;
/// `slice`, where the input is one, to prefetch from.
pub(crate) struct MovedPrims<'s, P, G> {
    pub(crate) get: G,
    pub(crate) frame: Frame,
    pub(crate) slice: Option<&'s [P]>,
}

impl<P: Primitive, G: Fn(u32) -> P + Sync> RefitInput<P> for MovedPrims<'_, P, G> {
    #[inline]
    fn prefetch(&self, id: u32) {
        if let Some(s) = self.slice {
            crate::isa::prefetch_at(s, id as usize);
        }
    }

    #[inline]
    fn get(&self, id: u32) -> P {
        let p = (self.get)(id);
        if self.frame.is_identity() {
            p
        } else {
            // Every primitive was checked to scale before this frame was chosen.
            self.frame.prim(&p).unwrap_or(p)
        }
    }
}

/// One pass over the new input's boxes: how many are finite, the first that is not, their
/// union, and what the frame depends on. Every step is exact, so any grouping of a parallel
/// reduction gives the same summary.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Summary {
    pub(crate) finite: usize,
    pub(crate) first_bad: usize,
    pub(crate) all: Aabb,
    pub(crate) sizes: Sizes,
}

impl Default for Summary {
    fn default() -> Self {
        Summary {
            finite: 0,
            first_bad: usize::MAX,
            all: Aabb::EMPTY,
            sizes: Sizes::default(),
        }
    }
}

impl Summary {
    /// The summary of primitives `range`, whose boxes `boxes_of` gives.
    fn of(range: std::ops::Range<usize>, boxes_of: impl Fn(usize) -> Aabb) -> Summary {
        let mut s = Summary::default();
        for i in range {
            let b = boxes_of(i);
            if b.is_finite() {
                s.finite += 1;
                s.all = s.all.union(&b);
                s.sizes.add_finite(&b);
            } else {
                s.first_bad = s.first_bad.min(i);
            }
        }
        s
    }

    fn merge(self, o: Summary) -> Summary {
        Summary {
            finite: self.finite + o.finite,
            first_bad: self.first_bad.min(o.first_bad),
            all: self.all.union(&o.all),
            sizes: self.sizes.merge(o.sizes),
        }
    }
}

/// A layout a refit rewrites in place: what it was built over, the input index of each of its
/// leaf positions, and the rewrite from a [`RefitInput`].
pub(crate) trait RefitTarget<P: Primitive> {
    /// What the layout was built over.
    fn inputs(&self) -> Inputs;
    /// For each primitive in leaf order, its index in the input.
    fn held_ids(&self) -> &[u32];
    /// Recomputes every box (and the leaf data) from `src`.
    fn refit_from<S: RefitInput<P>>(&mut self, src: &S);
}

/// Refits `layout` to `prims` in their own units (a layout keeps no frame): the moved
/// primitives checked, then the boxes rewritten. What each layout's public `refit` is.
pub(crate) fn refit_unscaled<P: Primitive, L: RefitTarget<P>>(
    layout: &mut L,
    prims: &[P],
) -> Result<(), RefitError> {
    let get = |i: u32| prims[i as usize].clone();
    check_moved(
        layout.inputs(),
        layout.held_ids(),
        prims.len(),
        Some(prims),
        &get,
    )?;
    layout.refit_from(&MovedPrims {
        get,
        frame: Frame::default(),
        slice: Some(prims),
    });
    Ok(())
}

/// Checks `n` moved primitives, primitive `i` being `get(i)` (`slice[i]` where they are a
/// slice), against a layout built over `inputs` whose leaves name input indices `held`: the
/// same count, every primitive the tree holds finite, every one the build dropped still
/// non-finite. Returns their summary (count, union, sizes) for the refit.
pub(crate) fn check_moved<P: Primitive, G: Fn(u32) -> P + Sync>(
    inputs: Inputs,
    held: &[u32],
    n: usize,
    slice: Option<&[P]>,
    get: &G,
) -> Result<Summary, RefitError> {
    if n != inputs.len {
        return Err(RefitError::Count {
            expected: inputs.len,
            given: n,
        });
    }
    let boxes_of = |i: usize| {
        if let Some(s) = slice {
            crate::isa::prefetch_stream(s, i);
        }
        get(i as u32).bounds()
    };
    // In chunks, each a plain loop with its summary in registers.
    const CHUNK: usize = 8192;
    let summary = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| Summary::of(c * CHUNK..n.min((c + 1) * CHUNK), boxes_of))
        .reduce(Summary::default, Summary::merge);
    // A primitive the build split spatially is held more than once: count it once.
    let distinct = inputs.held;
    if distinct == n {
        if summary.first_bad != usize::MAX {
            return Err(RefitError::NonFinite {
                prim: summary.first_bad,
            });
        }
    } else if summary.finite != distinct
        || held
            .par_iter()
            .with_min_len(4096)
            .any(|&id| !boxes_of(id as usize).is_finite())
    {
        // The build dropped some: those must stay non-finite and the rest finite. Only now is
        // it worth knowing which primitives the tree holds, to name the first that changed.
        let mut in_tree = vec![false; n];
        for &id in held {
            in_tree[id as usize] = true;
        }
        let changed = (0..n)
            .into_par_iter()
            .find_first(|&i| boxes_of(i).is_finite() != in_tree[i]);
        if let Some(prim) = changed {
            return Err(if in_tree[prim] {
                RefitError::NonFinite { prim }
            } else {
                RefitError::NotInTree { prim }
            });
        }
    }
    Ok(summary)
}
