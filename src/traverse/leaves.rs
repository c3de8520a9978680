//! A wide layout's leaves as its kernels read them ([`Leaves`]): one dispatcher over every
//! [`LeafFormat`], chosen by a compile-time constant, so a leaf is a primitive range (plain
//! types) or a range of [`Tri4`] groups (triangle formats), never a run-time check.

use super::tri4::{any_far, any_leaf, closest_far, closest_leaf, Ray4Tri};
use super::{Filter, Stats};
use crate::geometry::{Hit, Ray};
use crate::layout::tri4::FarGroups;
use crate::layout::{Bvh4, Bvh8, Node4, Tri4};
use crate::primitive::{LeafFormat, Primitive};

/// A wide layout's leaf data, as its kernels read it: the primitives themselves (plain
/// leaves: a leaf is `first..first + count` of `prims`) or [`Tri4`] groups (triangle formats:
/// a leaf is the groups from `first` holding its `count` triangles).
#[derive(Clone, Copy)]
pub(crate) struct Leaves<'a, P> {
    pub prims: &'a [P],
    pub ids: &'a [u32],
    pub tri4: &'a [Tri4],
    /// The groups stored far ([`Tri4`]); where there are any, leaves go through the path
    /// that tests such groups lane by lane.
    pub far: &'a FarGroups,
}

impl<P: Primitive> Leaves<'_, P> {
    /// Asks the CPU to start loading the leaf at `first` (its first group's three cache
    /// lines: a 160-byte group starts on a line or half-way into one), so the memory latency
    /// overlaps the work before the leaf is tested.
    #[inline(always)]
    pub fn prefetch(&self, first: usize) {
        if P::LEAF_FORMAT != LeafFormat::Plain {
            crate::isa::prefetch_index(self.tri4, first, 3);
        }
    }

    /// The leaf's groups (triangle formats).
    #[inline(always)]
    pub fn groups(&self, first: usize, count: u32) -> &[Tri4] {
        &self.tri4[first..first + crate::layout::tri4::groups(count) as usize]
    }

    /// Closest hit in one leaf, improving `best`; `prep` holds the ray's group terms once the
    /// first leaf made them. Returns true when `best` changed. Checks for far groups at run
    /// time: for callers outside a walk; a walk picks [`Leaves::closest_as`] once.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub fn closest<S: Stats, F: Filter<Hit>>(
        &self,
        first: usize,
        count: u32,
        ray: &Ray,
        prep: &mut Option<Ray4Tri>,
        best: &mut Hit,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        if P::LEAF_FORMAT != LeafFormat::Plain && self.far.any() {
            let groups = (self.groups(first, count), first, self.far);
            let (found, b) = closest_far(groups, count, ray, P::LEAF_FORMAT, *best, stats, filter);
            *best = b;
            return found;
        }
        self.closest_as::<S, F, false>(first, count, ray, prep, best, stats, filter)
    }

    /// [`Leaves::closest`] with the far groups' path compiled in (`FAR`) or out: only for a
    /// layout whose `far` is `FAR`, or false.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub fn closest_as<S: Stats, F: Filter<Hit>, const FAR: bool>(
        &self,
        first: usize,
        count: u32,
        ray: &Ray,
        prep: &mut Option<Ray4Tri>,
        best: &mut Hit,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        match P::LEAF_FORMAT {
            LeafFormat::Plain => {
                let range = first..first + count as usize;
                super::leaf_closest_hit(
                    &self.prims[range.clone()],
                    &self.ids[range],
                    ray,
                    best,
                    stats,
                    filter,
                )
            }
            format => closest_leaf::<S, F, FAR>(
                (self.groups(first, count), first, self.far),
                count,
                ray,
                prep,
                format,
                best,
                stats,
                filter,
            ),
        }
    }

    /// Whether anything in one leaf is hit within the ray's interval. Checks for far groups
    /// at run time, as [`Leaves::closest`] does.
    #[inline(always)]
    pub fn any<S: Stats, F: Filter<Hit>>(
        &self,
        first: usize,
        count: u32,
        ray: &Ray,
        prep: &mut Option<Ray4Tri>,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        if P::LEAF_FORMAT != LeafFormat::Plain && self.far.any() {
            let groups = (self.groups(first, count), first, self.far);
            return any_far(groups, count, ray, P::LEAF_FORMAT, stats, filter);
        }
        self.any_as::<S, F, false>(first, count, ray, prep, stats, filter)
    }

    /// [`Leaves::any`] with the far groups' path compiled in (`FAR`) or out, as for
    /// [`Leaves::closest_as`].
    #[inline(always)]
    pub fn any_as<S: Stats, F: Filter<Hit>, const FAR: bool>(
        &self,
        first: usize,
        count: u32,
        ray: &Ray,
        prep: &mut Option<Ray4Tri>,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        match P::LEAF_FORMAT {
            LeafFormat::Plain => {
                let range = first..first + count as usize;
                super::leaf_any_hit(
                    &self.prims[range.clone()],
                    &self.ids[range],
                    ray,
                    stats,
                    filter,
                )
            }
            format => any_leaf::<S, F, FAR>(
                (self.groups(first, count), first, self.far),
                count,
                ray,
                prep,
                format,
                stats,
                filter,
            ),
        }
    }
}

impl<P: Primitive, N: Node4> Bvh4<P, N> {
    /// The leaf data the kernels read.
    #[inline(always)]
    pub(crate) fn leaves(&self) -> Leaves<'_, P> {
        Leaves {
            prims: &self.prims,
            ids: &self.prim_ids,
            tri4: &self.tri4,
            far: &self.far,
        }
    }
}

impl<P: Primitive> Bvh8<P> {
    /// The leaf data the kernels read.
    #[inline(always)]
    pub(crate) fn leaves(&self) -> Leaves<'_, P> {
        Leaves {
            prims: &self.prims,
            ids: &self.prim_ids,
            tri4: &self.tri4,
            far: &self.far,
        }
    }
}
