//! [`RayQuery`]: the one interface every traversable structure answers; [`Ask`], whether a
//! query wants the closest hit or any hit; [`Filter`], the candidate test a query may carry.

use super::packet::{each_packet, PacketMode, PacketQuery};
use super::{BoxTest, ConservativeBoxes, Counters, NoStats, Stats};
use crate::geometry::Ray;

/// What a query asks for, chosen at compile time: the closest hit ([`ClosestHit`]) or any
/// hit ([`AnyHit`]). Every walk is written once over it, so the two queries cannot drift apart.
///
/// ```
/// use quiver_rt::traverse::{AnyHit, Ask, ClosestHit};
/// assert!(AnyHit::ANY && !ClosestHit::ANY);
/// ```
pub trait Ask: Copy + Default + sealed::Sealed + 'static {
    /// True for any hit: the walk stops at the first hit the filter accepts and visits a
    /// node's children in any order; false for the closest hit: children nearest first, the
    /// search interval shrinking to the best hit so far.
    const ANY: bool;

    /// What a query answers for one ray: the hit found (`Option<H>`, closest hit) or whether
    /// there is one (`bool`, any hit). Its default is the answer for a ray not traced.
    type Answer<H: Copy>: Copy + Default;

    /// The answer for the hit a search found, if any.
    fn answer<H: Copy>(found: Option<H>) -> Self::Answer<H>;

    /// Whether `answer` says something was hit.
    fn is_hit<H: Copy>(answer: &Self::Answer<H>) -> bool;

    /// `answer` with its hit (if it names one) mapped by `f`.
    fn map<H: Copy, G: Copy>(answer: Self::Answer<H>, f: impl FnOnce(H) -> G) -> Self::Answer<G>;

    /// The hit `answer` names: a closest hit's own, or for any hit `stand_in` where there is
    /// one (an any-hit answer names none).
    fn into_hit<H: Copy>(answer: Self::Answer<H>, stand_in: H) -> Option<H>;
}

/// The nearest hit along the ray (lowest primitive index on ties).
#[derive(Clone, Copy, Debug, Default)]
pub struct ClosestHit;

/// Any hit within the ray's interval: the first the walk meets that the filter accepts.
#[derive(Clone, Copy, Debug, Default)]
pub struct AnyHit;

impl Ask for ClosestHit {
    const ANY: bool = false;
    type Answer<H: Copy> = Option<H>;

    #[inline(always)]
    fn answer<H: Copy>(found: Option<H>) -> Option<H> {
        found
    }

    #[inline(always)]
    fn is_hit<H: Copy>(answer: &Option<H>) -> bool {
        answer.is_some()
    }

    #[inline(always)]
    fn map<H: Copy, G: Copy>(answer: Option<H>, f: impl FnOnce(H) -> G) -> Option<G> {
        answer.map(f)
    }

    #[inline(always)]
    fn into_hit<H: Copy>(answer: Option<H>, _: H) -> Option<H> {
        answer
    }
}

impl Ask for AnyHit {
    const ANY: bool = true;
    type Answer<H: Copy> = bool;

    #[inline(always)]
    fn answer<H: Copy>(found: Option<H>) -> bool {
        found.is_some()
    }

    #[inline(always)]
    fn is_hit<H: Copy>(answer: &bool) -> bool {
        *answer
    }

    #[inline(always)]
    fn map<H: Copy, G: Copy>(answer: bool, _: impl FnOnce(H) -> G) -> bool {
        answer
    }

    #[inline(always)]
    fn into_hit<H: Copy>(answer: bool, stand_in: H) -> Option<H> {
        answer.then_some(stand_in)
    }
}

mod sealed {
    /// The walks know exactly two questions.
    pub trait Sealed {}
    impl Sealed for super::ClosestHit {}
    impl Sealed for super::AnyHit {}
}

/// Which candidate hits a query keeps: an alpha test that looks up the texel at `(u, v)`, a
/// rule that skips the surface a ray leaves from. A rejected candidate is as if the primitive
/// were not there at that point; the ray goes on.
///
/// Queries take the filter as a type parameter, as they take [`Stats`]: [`NoFilter`] says at
/// compile time that it accepts everything, so a query without a filter pays nothing. Any
/// closure `FnMut(&H) -> bool` is a filter. It may be called for candidates in any order and
/// more than once for the same one (packets and single rays visit leaves in other orders), so
/// it should answer from the candidate alone.
///
/// ```
/// use quiver_rt::{Bvh, Hit, Ray, RayQuery, Triangle};
/// use glam::Vec3A;
/// // Two squares' halves stacked along z: the nearer one alpha-tested away where u > 0.5.
/// let near = Triangle::new(Vec3A::new(0.0, 0.0, 1.0), Vec3A::new(1.0, 0.0, 1.0), Vec3A::new(0.0, 1.0, 1.0));
/// let far = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
/// let bvh = Bvh::new(&[near, far]);
/// let ray = Ray::new(Vec3A::new(0.6, 0.2, 2.0), -Vec3A::Z);
/// assert_eq!(bvh.closest_hit(&ray).map(|h| h.prim), Some(0));
/// let transparent = |h: &Hit| !(h.prim == 0 && h.u > 0.5);
/// assert_eq!(bvh.closest_hit_filtered(&ray, transparent).map(|h| h.prim), Some(1));
/// ```
pub trait Filter<H> {
    /// Whether the filter can reject anything: `false` lets the kernels skip it entirely.
    const ACTIVE: bool = true;
    /// Whether to keep `candidate`.
    fn accept(&mut self, candidate: &H) -> bool;
}

/// The filter that keeps every hit, known at compile time: what the unfiltered queries use.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoFilter;

impl<H> Filter<H> for NoFilter {
    const ACTIVE: bool = false;
    #[inline(always)]
    fn accept(&mut self, _: &H) -> bool {
        true
    }
}

impl<H, F: FnMut(&H) -> bool> Filter<H> for F {
    #[inline(always)]
    fn accept(&mut self, candidate: &H) -> bool {
        self(candidate)
    }
}

/// Ray queries: closest hit and any hit, one ray at a time or in packets.
///
/// Every layout ([`crate::layout::Bvh2`], [`crate::layout::Bvh4`], [`crate::layout::QBvh4`],
/// [`crate::layout::Bvh8`]), the layout-erased [`crate::Bvh`], a [`crate::World`] of
/// instances and quiver-scenes' `SceneBvh` implement it. What a hit names is the implementor's
/// [`RayQuery::Hit`]: [`crate::Hit`] for one BVH, [`crate::WorldHit`] (instance, geometry,
/// primitive) for a world. An implementor writes [`RayQuery::trace_with`], generic over the
/// question ([`Ask`]), the box test ([`BoxTest`]), a statistics sink ([`Stats`]) and a
/// candidate [`Filter`], and [`RayQuery::trace_packet_with`] where it has a packet kernel
/// (without one, packets are traced ray by ray); every other form comes with the trait and
/// uses the conservative box test.
///
/// Answers follow the rules in [`crate::geometry`]: the interval `[t_min, t_max]` is closed,
/// and among hits at equal distance the lowest primitive index wins, so every implementor
/// returns the same closest hit for the same ray.
///
/// ```
/// use quiver_rt::{Bvh, Ray, RayQuery, Triangle};
/// use quiver_rt::traverse::Counters;
/// use glam::Vec3A;
/// let tris = [Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)];
/// let bvh = Bvh::new(&tris);
/// let ray = Ray::new(Vec3A::new(0.25, 0.25, 1.0), -Vec3A::Z);
/// assert_eq!(bvh.closest_hit(&ray).map(|h| h.t), Some(1.0));
/// assert!(bvh.any_hit(&ray));
/// let mut work = Counters::default();
/// bvh.closest_hit_counted(&ray, &mut work);
/// assert_eq!(work.prim_tests, 1);
/// ```
pub trait RayQuery {
    /// What a hit names.
    type Hit: Copy;

    /// The answer `A` asks for along `ray`, among the hits `filter` accepts: the nearest hit
    /// ([`ClosestHit`]), or whether there is one ([`AnyHit`], which stops at the first it
    /// meets); with the box test `B`, reporting work to `stats`.
    fn trace_with<A: Ask, B: BoxTest, S: Stats, F: Filter<Self::Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> A::Answer<Self::Hit>;

    /// [`RayQuery::trace_with`] for each of the query's rays into `answers` (one slot per
    /// ray), in packets of [`super::PACKET_RAYS`] where its mode and the layout allow: only active
    /// rays are traced (the others get the default answer: no hit). Each answer is exactly
    /// [`RayQuery::trace_with`]'s for that ray. `stats` counts packet node visits, not per-ray
    /// ones.
    ///
    /// Without a packet kernel (the default) every active ray goes through
    /// [`RayQuery::trace_with`] and the mode is ignored.
    ///
    /// # Panics
    /// When `answers` or the active flags differ in length from the rays.
    fn trace_packet_with<A: Ask, B: BoxTest, S: Stats, F: Filter<Self::Hit>>(
        &self,
        query: PacketQuery<'_>,
        answers: &mut [A::Answer<Self::Hit>],
        stats: &mut S,
        filter: &mut F,
    ) {
        ray_by_ray::<_, A, B, S, F>(self, query, answers, stats, filter)
    }

    /// The nearest hit along `ray` that `filter` accepts, with the box test `B`, reporting
    /// work to `stats`.
    #[inline]
    fn closest_hit_with<B: BoxTest, S: Stats, F: Filter<Self::Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> Option<Self::Hit> {
        self.trace_with::<ClosestHit, B, S, F>(ray, stats, filter)
    }

    /// Whether anything `filter` accepts is hit within the ray's interval (stops at the first
    /// accepted hit), with the box test `B`, reporting work to `stats`.
    #[inline]
    fn any_hit_with<B: BoxTest, S: Stats, F: Filter<Self::Hit>>(
        &self,
        ray: &Ray,
        stats: &mut S,
        filter: &mut F,
    ) -> bool {
        self.trace_with::<AnyHit, B, S, F>(ray, stats, filter)
    }

    /// Closest hits of the query's rays into `hits`: [`RayQuery::trace_packet_with`] asking
    /// [`ClosestHit`].
    ///
    /// # Panics
    /// When `hits` or the active flags differ in length from the rays.
    #[inline]
    fn closest_hit_packet_with<B: BoxTest, S: Stats, F: Filter<Self::Hit>>(
        &self,
        query: PacketQuery<'_>,
        hits: &mut [Option<Self::Hit>],
        stats: &mut S,
        filter: &mut F,
    ) {
        self.trace_packet_with::<ClosestHit, B, S, F>(query, hits, stats, filter)
    }

    /// Any-hit answers of the query's rays into `occluded` (inactive rays get `false`):
    /// [`RayQuery::trace_packet_with`] asking [`AnyHit`].
    ///
    /// # Panics
    /// When `occluded` or the active flags differ in length from the rays.
    #[inline]
    fn any_hit_packet_with<B: BoxTest, S: Stats, F: Filter<Self::Hit>>(
        &self,
        query: PacketQuery<'_>,
        occluded: &mut [bool],
        stats: &mut S,
        filter: &mut F,
    ) {
        self.trace_packet_with::<AnyHit, B, S, F>(query, occluded, stats, filter)
    }

    /// The nearest hit along `ray` (lowest primitive index on ties).
    #[inline]
    fn closest_hit(&self, ray: &Ray) -> Option<Self::Hit> {
        self.closest_hit_with::<ConservativeBoxes, _, _>(ray, &mut NoStats, &mut NoFilter)
    }

    /// True when anything is hit within the ray's interval; stops at the first hit.
    #[inline]
    fn any_hit(&self, ray: &Ray) -> bool {
        self.any_hit_with::<ConservativeBoxes, _, _>(ray, &mut NoStats, &mut NoFilter)
    }

    /// The nearest hit along `ray` that `filter` accepts (see [`Filter`]).
    #[inline]
    fn closest_hit_filtered(
        &self,
        ray: &Ray,
        mut filter: impl FnMut(&Self::Hit) -> bool,
    ) -> Option<Self::Hit> {
        self.closest_hit_with::<ConservativeBoxes, _, _>(ray, &mut NoStats, &mut filter)
    }

    /// Whether anything `filter` accepts is hit within the ray's interval.
    #[inline]
    fn any_hit_filtered(&self, ray: &Ray, mut filter: impl FnMut(&Self::Hit) -> bool) -> bool {
        self.any_hit_with::<ConservativeBoxes, _, _>(ray, &mut NoStats, &mut filter)
    }

    /// [`RayQuery::closest_hit`], adding what the traversal did to `counters`.
    #[inline]
    fn closest_hit_counted(&self, ray: &Ray, counters: &mut Counters) -> Option<Self::Hit> {
        self.closest_hit_with::<ConservativeBoxes, _, _>(ray, counters, &mut NoFilter)
    }

    /// [`RayQuery::any_hit`], adding what the traversal did to `counters`.
    #[inline]
    fn any_hit_counted(&self, ray: &Ray, counters: &mut Counters) -> bool {
        self.any_hit_with::<ConservativeBoxes, _, _>(ray, counters, &mut NoFilter)
    }

    /// Closest hits of `rays` into `hits` (same length), traced in packets where they are
    /// coherent ([`PacketMode::Auto`]). Each answer is exactly [`RayQuery::closest_hit`]'s.
    ///
    /// ```
    /// use quiver_rt::traverse::reference;
    /// use quiver_rt::{Bvh, Ray, RayQuery, Triangle};
    /// use glam::Vec3A;
    /// let tris: Vec<Triangle> = (0..64)
    ///     .map(|i| {
    ///         let o = Vec3A::new((i % 8) as f32, (i / 8) as f32, 0.0);
    ///         Triangle::new(o, o + Vec3A::X, o + Vec3A::Y)
    ///     })
    ///     .collect();
    /// let bvh = Bvh::new(&tris);
    /// // 64 parallel rays over the grid: one coherent packet.
    /// let rays: Vec<Ray> = (0..64)
    ///     .map(|i| Ray::new(Vec3A::new(i as f32 / 8.0, 3.3, 1.0), -Vec3A::Z))
    ///     .collect();
    /// let mut hits = vec![None; rays.len()];
    /// bvh.closest_hit_packet(&rays, &mut hits);
    /// for (ray, hit) in rays.iter().zip(&hits) {
    ///     assert_eq!(*hit, reference::closest_hit(&tris, ray));
    /// }
    /// assert!(hits.iter().filter(|h| h.is_some()).count() > 10);
    /// ```
    ///
    /// # Panics
    /// When `hits` and `rays` differ in length.
    #[inline]
    fn closest_hit_packet(&self, rays: &[Ray], hits: &mut [Option<Self::Hit>]) {
        self.closest_hit_packet_with::<ConservativeBoxes, _, _>(
            PacketQuery::new(rays),
            hits,
            &mut NoStats,
            &mut NoFilter,
        )
    }

    /// Whether each ray hits anything within its interval, into `occluded`, in packets where
    /// the rays are coherent.
    ///
    /// # Panics
    /// When `occluded` and `rays` differ in length.
    #[inline]
    fn any_hit_packet(&self, rays: &[Ray], occluded: &mut [bool]) {
        self.any_hit_packet_with::<ConservativeBoxes, _, _>(
            PacketQuery::new(rays),
            occluded,
            &mut NoStats,
            &mut NoFilter,
        )
    }

    /// [`RayQuery::closest_hit_packet`] keeping only the candidates `filter` accepts.
    ///
    /// ```
    /// use quiver_rt::{Bvh, Hit, Ray, RayQuery, Triangle};
    /// use glam::Vec3A;
    /// let near = Triangle::new(Vec3A::new(0.0, 0.0, 1.0), Vec3A::new(1.0, 0.0, 1.0), Vec3A::new(0.0, 1.0, 1.0));
    /// let far = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
    /// let bvh = Bvh::new(&[near, far]);
    /// let rays = [Ray::new(Vec3A::new(0.2, 0.2, 2.0), -Vec3A::Z); 8];
    /// let mut hits = [None; 8];
    /// bvh.closest_hit_packet_filtered(&rays, &mut hits, |h: &Hit| h.prim != 0);
    /// assert!(hits.iter().all(|h| h.map(|h| h.prim) == Some(1)));
    /// ```
    ///
    /// # Panics
    /// When `hits` and `rays` differ in length.
    #[inline]
    fn closest_hit_packet_filtered(
        &self,
        rays: &[Ray],
        hits: &mut [Option<Self::Hit>],
        mut filter: impl FnMut(&Self::Hit) -> bool,
    ) {
        self.closest_hit_packet_with::<ConservativeBoxes, _, _>(
            PacketQuery::new(rays),
            hits,
            &mut NoStats,
            &mut filter,
        )
    }

    /// [`RayQuery::any_hit_packet`] counting only the candidates `filter` accepts.
    ///
    /// # Panics
    /// When `occluded` and `rays` differ in length.
    #[inline]
    fn any_hit_packet_filtered(
        &self,
        rays: &[Ray],
        occluded: &mut [bool],
        mut filter: impl FnMut(&Self::Hit) -> bool,
    ) {
        self.any_hit_packet_with::<ConservativeBoxes, _, _>(
            PacketQuery::new(rays),
            occluded,
            &mut NoStats,
            &mut filter,
        )
    }
}

/// The packet query of a structure without a packet kernel: each active ray through `q`'s
/// single-ray query, inactive ones `None`. The query's mode is ignored.
///
/// # Panics
/// When `hits` or `active` differ in length from `rays`.
#[inline]
pub(crate) fn ray_by_ray<Q, A, B, S, F>(
    q: &Q,
    query: PacketQuery<'_>,
    hits: &mut [A::Answer<Q::Hit>],
    stats: &mut S,
    filter: &mut F,
) where
    Q: RayQuery + ?Sized,
    A: Ask,
    B: BoxTest,
    S: Stats,
    F: Filter<Q::Hit>,
{
    each_packet(query.mode(PacketMode::Never), hits, |rays, on, _, hits| {
        for (i, (h, r)) in hits.iter_mut().zip(rays).enumerate() {
            *h = if on >> i & 1 == 1 {
                q.trace_with::<A, B, S, F>(r, stats, filter)
            } else {
                Default::default()
            };
        }
    });
}
