//! [`RayQuery`]: the one interface every traversable structure answers.

use super::packet::{each_packet, PacketMode, PacketQuery};
use super::{BoxTest, ConservativeBoxes, Counters, NoStats, Stats};
use crate::geometry::{Hit, Ray};

/// Ray queries: closest hit and any hit, one ray at a time or in packets.
///
/// Every layout ([`crate::Bvh2`], [`crate::Bvh4`], [`crate::QBvh4`], [`crate::Bvh8`]), the
/// layout-erased [`crate::Bvh`], and quiver-scenes' `SceneBvh` implement it. An implementor
/// writes the two single-ray `*_with` methods, generic over the box test ([`BoxTest`]) and a
/// statistics sink ([`Stats`]), and the two packet `*_with` methods where it has a packet
/// kernel (without one they trace ray by ray); the short forms (`closest_hit`, `any_hit`, the
/// counted and packet forms) come with the trait and use the conservative box test.
///
/// Answers follow the rules in [`crate::geometry`]: the interval `[t_min, t_max]` is closed,
/// and among hits at equal distance the lowest primitive index wins, so every implementor
/// returns the same hit for the same ray.
///
/// ```
/// use quiver::{Bvh, Ray, RayQuery, Triangle};
/// use quiver::traverse::Counters;
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
    /// The nearest hit along `ray`, with the box test `B`, reporting work to `stats`.
    fn closest_hit_with<B: BoxTest, S: Stats>(&self, ray: &Ray, stats: &mut S) -> Option<Hit>;

    /// Whether anything is hit within the ray's interval (stops at the first hit), with the
    /// box test `B`, reporting work to `stats`.
    fn any_hit_with<B: BoxTest, S: Stats>(&self, ray: &Ray, stats: &mut S) -> bool;

    /// Closest hits of the query's rays into `hits` (one slot per ray), in packets of
    /// [`super::PACKET_RAYS`] where its mode and the layout allow: only active rays are traced
    /// (the others get `None`). Each answer is exactly [`RayQuery::closest_hit_with`]'s for
    /// that ray. `stats` counts packet node visits, not per-ray ones.
    ///
    /// Without a packet kernel (the default) every active ray goes through
    /// [`RayQuery::closest_hit_with`] and the mode is ignored.
    ///
    /// # Panics
    /// When `hits` or the active flags differ in length from the rays.
    fn closest_hit_packet_with<B: BoxTest, S: Stats>(
        &self,
        query: PacketQuery<'_>,
        hits: &mut [Option<Hit>],
        stats: &mut S,
    ) {
        closest_ray_by_ray::<_, B, S>(self, query, hits, stats)
    }

    /// Any-hit answers of the query's rays into `occluded` (inactive rays get `false`); see
    /// [`RayQuery::closest_hit_packet_with`].
    ///
    /// # Panics
    /// When `occluded` or the active flags differ in length from the rays.
    fn any_hit_packet_with<B: BoxTest, S: Stats>(
        &self,
        query: PacketQuery<'_>,
        occluded: &mut [bool],
        stats: &mut S,
    ) {
        any_ray_by_ray::<_, B, S>(self, query, occluded, stats)
    }

    /// The nearest hit along `ray` (lowest primitive index on ties).
    #[inline]
    fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        self.closest_hit_with::<ConservativeBoxes, _>(ray, &mut NoStats)
    }

    /// True when anything is hit within the ray's interval; stops at the first hit.
    #[inline]
    fn any_hit(&self, ray: &Ray) -> bool {
        self.any_hit_with::<ConservativeBoxes, _>(ray, &mut NoStats)
    }

    /// [`RayQuery::closest_hit`], adding what the traversal did to `counters`.
    #[inline]
    fn closest_hit_counted(&self, ray: &Ray, counters: &mut Counters) -> Option<Hit> {
        self.closest_hit_with::<ConservativeBoxes, _>(ray, counters)
    }

    /// [`RayQuery::any_hit`], adding what the traversal did to `counters`.
    #[inline]
    fn any_hit_counted(&self, ray: &Ray, counters: &mut Counters) -> bool {
        self.any_hit_with::<ConservativeBoxes, _>(ray, counters)
    }

    /// Closest hits of `rays` into `hits` (same length), traced in packets where they are
    /// coherent ([`PacketMode::Auto`]). Each answer is exactly [`RayQuery::closest_hit`]'s.
    ///
    /// ```
    /// use quiver::{reference, Bvh, Ray, RayQuery, Triangle};
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
    fn closest_hit_packet(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        self.closest_hit_packet_with::<ConservativeBoxes, _>(
            PacketQuery::new(rays),
            hits,
            &mut NoStats,
        )
    }

    /// Whether each ray hits anything within its interval, into `occluded`, in packets where
    /// the rays are coherent.
    ///
    /// # Panics
    /// When `occluded` and `rays` differ in length.
    #[inline]
    fn any_hit_packet(&self, rays: &[Ray], occluded: &mut [bool]) {
        self.any_hit_packet_with::<ConservativeBoxes, _>(
            PacketQuery::new(rays),
            occluded,
            &mut NoStats,
        )
    }
}

/// The packet closest-hit query of a structure without a packet kernel: each active ray
/// through `q`'s single-ray query, inactive ones `None`. The query's mode is ignored.
///
/// # Panics
/// When `hits` or `active` differ in length from `rays`.
#[inline]
pub(crate) fn closest_ray_by_ray<Q: RayQuery + ?Sized, B: BoxTest, S: Stats>(
    q: &Q,
    query: PacketQuery<'_>,
    hits: &mut [Option<Hit>],
    stats: &mut S,
) {
    each_packet(query.mode(PacketMode::Never), hits, |rays, on, _, hits| {
        for (i, (h, r)) in hits.iter_mut().zip(rays).enumerate() {
            *h = (on >> i & 1 == 1)
                .then(|| q.closest_hit_with::<B, S>(r, stats))
                .flatten();
        }
    });
}

/// The packet any-hit query of a structure without a packet kernel (see
/// [`closest_ray_by_ray`]).
///
/// # Panics
/// When `occluded` or `active` differ in length from `rays`.
#[inline]
pub(crate) fn any_ray_by_ray<Q: RayQuery + ?Sized, B: BoxTest, S: Stats>(
    q: &Q,
    query: PacketQuery<'_>,
    occluded: &mut [bool],
    stats: &mut S,
) {
    super::packet::each_packet(
        query.mode(PacketMode::Never),
        occluded,
        |rays, on, _, out| {
            for (i, (o, r)) in out.iter_mut().zip(rays).enumerate() {
                *o = on >> i & 1 == 1 && q.any_hit_with::<B, S>(r, stats);
            }
        },
    );
}
