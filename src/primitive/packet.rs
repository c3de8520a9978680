//! The packet hooks of [`crate::Primitive`]: the rays of a packet that enter a leaf
//! ([`PacketLeaf`]), as single rays or as SIMD lanes ([`PacketLanes`]), and where a
//! primitive's packet test reports its hits. The packet kernels (`traverse::packet`) fill
//! these in; a primitive type only reads them.

use crate::geometry::{PrimHit, Ray};
use crate::mask::bits;
use glam::Vec3A;
use wide::f32x8;

/// Rays per packet. Longer inputs are cut into packets of this size.
pub const PACKET_RAYS: usize = 64;
/// Rays per SIMD chunk.
pub(crate) const LANES: usize = 8;
/// SIMD chunks per packet.
pub(crate) const CHUNKS: usize = PACKET_RAYS / LANES;

/// One value per ray of a packet, eight rays to a SIMD chunk.
pub(crate) type Lanes = [f32x8; CHUNKS];

#[inline(always)]
pub(crate) fn lane(l: &Lanes, i: usize) -> f32 {
    bytemuck::cast_ref::<Lanes, [f32; PACKET_RAYS]>(l)[i]
}

#[inline(always)]
fn lane_mut(l: &mut Lanes, i: usize) -> &mut f32 {
    &mut bytemuck::cast_mut::<Lanes, [f32; PACKET_RAYS]>(l)[i]
}

/// The rays of a packet as a leaf test reads them: origins, directions and each ray's
/// interval, eight rays to a SIMD chunk. The packet walk keeps the rest of its state beside it.
pub(crate) struct PacketRays {
    pub(crate) o: [Lanes; 3],
    pub(crate) d: [Lanes; 3],
    pub(crate) t_min: Lanes,
    /// How far each ray still searches: `t_max`, then the best hit so far; `-inf` once a ray
    /// is inactive, so every test fails for it.
    pub(crate) limit: Lanes,
}

impl PacketRays {
    /// Ray `i` with its current search limit as `t_max`.
    #[inline(always)]
    pub(crate) fn ray(&self, i: usize) -> Ray {
        let at = |l: &Lanes| lane(l, i);
        Ray::segment(
            Vec3A::new(at(&self.o[0]), at(&self.o[1]), at(&self.o[2])),
            Vec3A::new(at(&self.d[0]), at(&self.d[1]), at(&self.d[2])),
            at(&self.t_min),
            at(&self.limit),
        )
    }

    /// Ray `i`'s search limit.
    #[inline(always)]
    pub(crate) fn limit(&self, i: usize) -> f32 {
        lane(&self.limit, i)
    }

    /// Shortens ray `i`'s search to `t` (a nearer hit was found).
    #[inline(always)]
    pub(crate) fn set_limit(&mut self, i: usize, t: f32) {
        *lane_mut(&mut self.limit, i) = t;
    }
}

/// Eight rays' fields as lanes: origin x, y, z, direction x, y, z, `t_min`, `t_max`.
///
/// Transposed in registers: gathering the fields into an array with scalar stores and
/// loading its rows as vectors stalls every load on store forwarding (a tenth of a
/// coherent packet's time in `perf`).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn ray_rows(r: &[Ray; LANES]) -> [f32x8; 8] {
    use std::arch::x86_64::*;
    // Four vectors' lanes, rows to columns.
    #[inline(always)]
    fn transpose(v: [__m128; 4]) -> [__m128; 4] {
        // SAFETY: SSE is part of every x86-64 CPU; register operations only.
        unsafe {
            let (ab_lo, cd_lo) = (_mm_unpacklo_ps(v[0], v[1]), _mm_unpacklo_ps(v[2], v[3]));
            let (ab_hi, cd_hi) = (_mm_unpackhi_ps(v[0], v[1]), _mm_unpackhi_ps(v[2], v[3]));
            [
                _mm_movelh_ps(ab_lo, cd_lo),
                _mm_movehl_ps(cd_lo, ab_lo),
                _mm_movelh_ps(ab_hi, cd_hi),
                _mm_movehl_ps(cd_hi, ab_hi),
            ]
        }
    }
    #[inline(always)]
    fn half(r: &[Ray]) -> [__m128; 8] {
        let o = transpose([
            r[0].origin.into(),
            r[1].origin.into(),
            r[2].origin.into(),
            r[3].origin.into(),
        ]);
        let d = transpose([
            r[0].dir.into(),
            r[1].dir.into(),
            r[2].dir.into(),
            r[3].dir.into(),
        ]);
        // SAFETY: as in `transpose`.
        let (t_min, t_max) = unsafe {
            (
                _mm_setr_ps(r[0].t_min, r[1].t_min, r[2].t_min, r[3].t_min),
                _mm_setr_ps(r[0].t_max, r[1].t_max, r[2].t_max, r[3].t_max),
            )
        };
        [o[0], o[1], o[2], d[0], d[1], d[2], t_min, t_max]
    }
    let (lo, hi) = (half(&r[..4]), half(&r[4..]));
    let row = |c: usize| -> f32x8 { bytemuck::cast([lo[c], hi[c]]) };
    [
        row(0),
        row(1),
        row(2),
        row(3),
        row(4),
        row(5),
        row(6),
        row(7),
    ]
}

/// Eight rays' fields as lanes (see the x86-64 version).
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
pub(crate) fn ray_rows(r: &[Ray; LANES]) -> [f32x8; 8] {
    let row = |f: fn(&Ray) -> f32| f32x8::from([0, 1, 2, 3, 4, 5, 6, 7].map(|j| f(&r[j])));
    [
        row(|r| r.origin.x),
        row(|r| r.origin.y),
        row(|r| r.origin.z),
        row(|r| r.dir.x),
        row(|r| r.dir.y),
        row(|r| r.dir.z),
        row(|r| r.t_min),
        row(|r| r.t_max),
    ]
}

/// The rays of a packet that enter one leaf, as a primitive type's packet test
/// ([`crate::Primitive::intersect_packet`]) sees them: which rays still search, each ray
/// within its current interval, and where to report hits.
pub struct PacketLeaf<'a, F> {
    pub(crate) packet: &'a mut PacketRays,
    pub(crate) live: u64,
    /// The leaf's primitive ids (plain leaves; SIMD groups carry their own).
    pub(crate) ids: &'a [u32],
    pub(crate) on_hit: F,
}

impl<F: FnMut(usize, u32, PrimHit) -> Option<f32>> PacketLeaf<'_, F> {
    /// The rays still searching this leaf: bit `i` for ray `i` of the packet.
    #[inline(always)]
    pub fn rays(&self) -> u64 {
        self.live
    }

    /// Ray `i` as it searches now: `t_max` is its current limit (in a closest-hit query, the
    /// nearest hit so far).
    #[inline(always)]
    pub fn ray(&self, i: usize) -> Ray {
        self.packet.ray(i)
    }

    /// Rays `8k .. 8k + 8` of the packet in SIMD lanes, for a primitive's own eight-ray test
    /// (`k` in `0..PACKET_RAYS / 8`): lane `l` holds ray `8k + l` as [`PacketLeaf::ray`]
    /// gives it. Lanes of rays that stopped searching hold `t_max = -inf`.
    /// [`PacketLeaf::test_lanes`] runs such a test over a whole packet.
    #[inline(always)]
    pub fn lanes(&self, k: usize) -> PacketLanes {
        let p = &*self.packet;
        PacketLanes {
            origin: [p.o[0][k], p.o[1][k], p.o[2][k]],
            dir: [p.d[0][k], p.d[1][k], p.d[2][k]],
            t_min: p.t_min[k],
            t_max: p.limit[k],
            live: (self.live >> (LANES * k)) as u32 & 0xFF,
        }
    }

    /// Runs `test`, an eight-ray test of primitive `j` of the leaf, over the rays still
    /// searching, eight at a time ([`PacketLeaf::lanes`]), and reports its hits. `test` gives
    /// the lanes that hit and their `t`, `u` and `v`; lanes that do not search are ignored.
    ///
    /// A unit square at `z = 0` tested eight rays at a time:
    ///
    /// ```
    /// use quiver_rt::traverse::{FastBoxes, NoFilter, NoStats, PacketMode, PacketQuery};
    /// use quiver_rt::primitive::PacketLeaf;
    /// use quiver_rt::{Aabb, Bvh, PrimHit, Primitive, Ray, RayQuery};
    /// use glam::Vec3A;
    /// use wide::f32x8;
    ///
    /// #[derive(Clone)]
    /// struct Square;
    /// impl Primitive for Square {
    ///     fn bounds(&self) -> Aabb {
    ///         Aabb::new(Vec3A::new(0.0, 0.0, 0.0), Vec3A::new(1.0, 1.0, 0.0))
    ///     }
    ///     fn intersect(&self, r: &Ray) -> Option<PrimHit> {
    ///         let t = -r.origin.z / r.dir.z;
    ///         let (x, y) = (r.origin.x + t * r.dir.x, r.origin.y + t * r.dir.y);
    ///         let inside = (0.0..=1.0).contains(&x) && (0.0..=1.0).contains(&y);
    ///         (inside && t >= r.t_min && t <= r.t_max).then_some(PrimHit { t, u: x, v: y })
    ///     }
    ///     fn intersect_packet<F>(leaf: &[Self], rays: &mut PacketLeaf<'_, F>)
    ///     where
    ///         F: FnMut(usize, u32, PrimHit) -> Option<f32>,
    ///     {
    ///         let (zero, one) = (f32x8::splat(0.0), f32x8::splat(1.0));
    ///         for j in 0..leaf.len() {
    ///             rays.test_lanes(j, |l| {
    ///                 // The scalar test's operations, lane by lane.
    ///                 let t = -l.origin[2] / l.dir[2];
    ///                 let x = l.origin[0] + t * l.dir[0];
    ///                 let y = l.origin[1] + t * l.dir[1];
    ///                 let ok = x.simd_ge(zero) & x.simd_le(one) & y.simd_ge(zero)
    ///                     & y.simd_le(one) & t.simd_ge(l.t_min) & t.simd_le(l.t_max);
    ///                 (ok.to_bitmask(), [t, x, y])
    ///             });
    ///         }
    ///     }
    /// }
    ///
    /// let bvh = Bvh::new(&[Square]);
    /// let rays: Vec<Ray> = (0..16)
    ///     .map(|i| Ray::new(Vec3A::new(i as f32 / 10.0, 0.5, 1.0), -Vec3A::Z))
    ///     .collect();
    /// let mut hits = vec![None; rays.len()];
    /// let query = PacketQuery::new(&rays).mode(PacketMode::Always);
    /// bvh.closest_hit_packet_with::<FastBoxes, NoStats, _>(query, &mut hits, &mut NoStats, &mut NoFilter);
    /// for (r, h) in rays.iter().zip(&hits) {
    ///     assert_eq!(*h, bvh.closest_hit(r));
    /// }
    /// assert_eq!(hits.iter().filter(|h| h.is_some()).count(), 11);
    /// ```
    #[inline(always)]
    pub fn test_lanes(
        &mut self,
        j: usize,
        mut test: impl FnMut(&PacketLanes) -> (u32, [f32x8; 3]),
    ) {
        for k in 0..CHUNKS {
            let l = self.lanes(k);
            if l.live == 0 {
                continue;
            }
            let (hit, [t, u, v]) = test(&l);
            let hit = hit & l.live;
            if hit == 0 {
                continue;
            }
            let (t, u, v) = (t.to_array(), u.to_array(), v.to_array());
            for lane in bits(hit) {
                let h = PrimHit {
                    t: t[lane],
                    u: u[lane],
                    v: v[lane],
                };
                self.report(LANES * k + lane, j, h);
            }
        }
    }

    /// Ray `i` hits primitive `j` of the leaf at `hit`: a closest-hit query shortens the ray
    /// to its nearest hit so far, an any-hit query takes the ray out of [`PacketLeaf::rays`].
    #[inline(always)]
    pub fn report(&mut self, i: usize, j: usize, hit: PrimHit) {
        self.report_id(i, self.ids[j], hit)
    }

    /// [`PacketLeaf::report`] by the primitive's input index.
    #[inline(always)]
    pub(crate) fn report_id(&mut self, i: usize, id: u32, hit: PrimHit) {
        match (self.on_hit)(i, id, hit) {
            Some(limit) => self.packet.set_limit(i, limit),
            None => {
                self.packet.set_limit(i, f32::NEG_INFINITY);
                self.live &= !(1 << i);
            }
        }
    }
}

/// Eight rays of a packet in SIMD lanes ([`PacketLeaf::lanes`]).
#[derive(Clone, Copy, Debug)]
pub struct PacketLanes {
    /// Origins, one `f32x8` per axis.
    pub origin: [f32x8; 3],
    /// Directions, one `f32x8` per axis.
    pub dir: [f32x8; 3],
    /// Smallest accepted hit distances.
    pub t_min: f32x8,
    /// Largest accepted hit distances now: `t_max`, in a closest-hit query the nearest hit so
    /// far, `-inf` for a ray that stopped searching.
    pub t_max: f32x8,
    /// Bit `l` set: ray `8k + l` still searches this leaf.
    pub live: u32,
}

impl PacketLanes {
    /// Eight rays as lanes, every one live: what [`PacketLeaf::lanes`] hands a test, for
    /// testing an eight-ray test against its scalar twin.
    ///
    /// ```
    /// use quiver_rt::primitive::PacketLanes;
    /// use quiver_rt::Ray;
    /// use glam::Vec3A;
    /// let rays: [Ray; 8] = std::array::from_fn(|i| Ray::new(Vec3A::ZERO, Vec3A::X * i as f32));
    /// let lanes = PacketLanes::from_rays(&rays);
    /// assert_eq!(lanes.ray(5), rays[5]);
    /// assert_eq!(lanes.live, 0xFF);
    /// ```
    pub fn from_rays(rays: &[Ray; LANES]) -> PacketLanes {
        let f = ray_rows(rays);
        PacketLanes {
            origin: [f[0], f[1], f[2]],
            dir: [f[3], f[4], f[5]],
            t_min: f[6],
            t_max: f[7],
            live: 0xFF,
        }
    }

    /// Lane `l` (`0..8`) as a ray, within its current interval.
    #[inline]
    pub fn ray(&self, l: usize) -> Ray {
        let at = |v: &f32x8| v.to_array()[l];
        Ray::segment(
            glam::Vec3A::new(
                at(&self.origin[0]),
                at(&self.origin[1]),
                at(&self.origin[2]),
            ),
            glam::Vec3A::new(at(&self.dir[0]), at(&self.dir[1]), at(&self.dir[2])),
            at(&self.t_min),
            at(&self.t_max),
        )
    }
}
