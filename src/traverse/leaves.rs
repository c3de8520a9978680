//! A wide layout's leaves as its kernels read them ([`Leaves`]): one dispatcher over every
//! [`LeafFormat`], chosen by a compile-time constant, so a leaf is a primitive range (plain
//! types) or a range of [`Tri4`] groups (triangle formats), never a run-time check.

use super::lane8::F8;
use super::search::test_prims;
use super::tri4::{test_far, test_leaf, LeafRay};
use super::{Ask, Filter, Stats};
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

    /// The search `A` in one leaf at `first` (`count` primitives), improving `best`; `prep`
    /// holds the ray's group terms once the first leaf made them. Returns true when `best`
    /// changed. `FAR`: the far groups' path compiled in (only for a layout whose `far` is
    /// `FAR`, or false).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub fn test<V: F8, A: Ask, S: Stats, F: Filter<Hit>, const FAR: bool>(
        &self,
        cpu: V::Cpu,
        first: usize,
        count: u32,
        ray: &Ray,
        prep: &mut Option<LeafRay<V>>,
        best: &mut Hit,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        match P::LEAF_FORMAT {
            LeafFormat::Plain => {
                let range = first..first + count as usize;
                test_prims::<A, P, S, F>(
                    &self.prims[range.clone()],
                    &self.ids[range],
                    ray,
                    best,
                    stats,
                    filter,
                )
            }
            format => test_leaf::<V, A, S, F, FAR>(
                cpu,
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

    /// [`Leaves::test`] with the far groups checked at run time, for callers outside a walk
    /// (a packet's ray alone at a leaf).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub fn test_checked<V: F8, A: Ask, S: Stats, F: Filter<Hit>>(
        &self,
        cpu: V::Cpu,
        first: usize,
        count: u32,
        ray: &Ray,
        best: &mut Hit,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        if P::LEAF_FORMAT != LeafFormat::Plain && self.far.any() {
            let groups = (self.groups(first, count), first, self.far);
            let format = P::LEAF_FORMAT;
            let (found, b) = test_far::<A, S, F>(groups, count, ray, format, *best, stats, filter);
            *best = b;
            return found;
        }
        self.test::<V, A, S, F, false>(cpu, first, count, ray, &mut None, best, stats, filter)
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
