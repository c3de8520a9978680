//! Packet traversal of 4- and 8-wide BVHs: up to [`PACKET_RAYS`] coherent rays walk the tree
//! together, so a node is fetched once per packet instead of once per ray.
//!
//! The walk follows the *first active ray* (Wald, Boulos and Shirley, "Ray Tracing Deformable
//! Scenes Using Dynamic Bounding Volume Hierarchies", 2007): every stack entry carries the
//! index of the first ray that enters its box, and a mask of the rays that may. A node's
//! children are tested against the first ray alone (one 4- or 8-wide test); a child it misses is
//! tested against the node's other candidate rays, which yields the child's exact candidate
//! mask, so searches shrink as the packet spreads out; a child no candidate enters is skipped.
//! Before those searches an interval-arithmetic bound over all the packet's origins and
//! directions (the cull test) rejects, in one 4- or 8-wide test, the children no ray of the packet
//! can enter. At a leaf each primitive runs its own packet test over the rays that enter it
//! (triangles: 8 rays at a time in `f32x8` lanes). A packet whose rays turn out to share
//! almost no leaves (fewer than two rays per leaf visit on average) hands its remaining rays
//! to the single-ray walk, each starting from the subtrees still stacked.
//!
//! Every per-ray computation (slab test, triangle test, tie break) is the single-ray kernel's
//! operation for operation, so each ray gets exactly the single-ray answer. Incoherent rays
//! gain nothing from sharing nodes and pay for the searches; [`PacketMode::Auto`] sends such
//! packets down the single-ray kernel instead.
//!
//! The pieces, one idea a file: `bound` (the cull test), `lanes` (rays in SIMD lanes and
//! their slab tests), `node` (what the walk needs of a 4- or 8-wide node format), `walk`
//! (the first-active-ray walk and the hand-over to single rays), `leaves` (a leaf's tests over
//! the rays that enter it), `query` (a query's packets through the walk, on the lanes of the
//! BVH's instruction set); `mod.rs` holds the modes, the coherence check and the ray-by-ray
//! fallback.

mod bound;
mod lanes;
mod leaves;
mod node;
mod query;
mod walk;

pub(crate) use lanes::{PacketBuilder, RayPacket};
pub(crate) use query::{in_lanes, trace_rays, InLanes};
pub(crate) use walk::{walk, AloneIn, Visit};

use crate::geometry::Ray;
pub use crate::primitive::PACKET_RAYS;
use crate::primitive::{CHUNKS, LANES};
use crate::traverse::simd::bits;

/// How a packet query chooses between packet and single-ray traversal.
///
/// ```
/// use quiver_rt::traverse::PacketMode;
/// assert_eq!(PacketMode::default(), PacketMode::Auto);
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PacketMode {
    /// Packets of coherent rays (at least four active rays whose direction signs agree on at
    /// least two axes, or whose directions lie within about 25° of the first active ray's) go
    /// down the packet kernel; others are traced ray by ray.
    /// Rays that point alike but scatter anyway (shadow rays from far-apart points of fine
    /// geometry) are handed to the single-ray walk once the packet sees it, which keeps them
    /// near, though not always at, single-ray speed (README, "Packets").
    #[default]
    Auto,
    /// Always the packet kernel, however incoherent the rays (for tests and measurements).
    Always,
    /// Always ray by ray (the single-ray kernel behind the packet interface).
    Never,
}

impl PacketMode {
    /// How many of the active rays of `rays` a packet query in this mode traces with the
    /// packet kernel (the rest go ray by ray): the same cut into [`PACKET_RAYS`]-ray packets
    /// and the same coherence check the query makes.
    ///
    /// ```
    /// use quiver_rt::traverse::PacketMode;
    /// use quiver_rt::Ray;
    /// use glam::Vec3A;
    /// let rays = vec![Ray::new(Vec3A::ZERO, Vec3A::Z); 10];
    /// assert_eq!(PacketMode::Auto.packet_rays(&rays, None), 10);
    /// assert_eq!(PacketMode::Never.packet_rays(&rays, None), 0);
    /// let three = [true, true, true, false, false, false, false, false, false, false];
    /// assert_eq!(PacketMode::Always.packet_rays(&rays, Some(&three)), 3);
    /// // Fewer than four active rays never pay for a packet.
    /// assert_eq!(PacketMode::Auto.packet_rays(&rays, Some(&three)), 0);
    /// ```
    ///
    /// # Panics
    /// When `active` differs in length from `rays`.
    pub fn packet_rays(self, rays: &[Ray], active: Option<&[bool]>) -> u64 {
        let mut n = 0u64;
        let mut out = vec![(); rays.len()];
        let query = PacketQuery {
            rays,
            active,
            mode: self,
        };
        each_packet(query, &mut out, |_, on, packet, _| {
            if packet {
                n += u64::from(on.count_ones());
            }
        });
        n
    }
}

/// What a packet query traces: the rays, which of them, and how ([`PacketMode`]). One value,
/// so the packet forms of [`RayQuery`](crate::RayQuery) keep one signature as options join.
///
/// ```
/// use quiver_rt::traverse::{PacketMode, PacketQuery};
/// use quiver_rt::Ray;
/// use glam::Vec3A;
/// let rays = [Ray::new(Vec3A::ZERO, Vec3A::Z); 3];
/// let on = [true, false, true];
/// let q = PacketQuery::new(&rays).active(&on).mode(PacketMode::Always);
/// assert_eq!((q.rays.len(), q.active, q.mode), (3, Some(&on[..]), PacketMode::Always));
/// assert_eq!(PacketQuery::new(&rays).mode, PacketMode::Auto);
/// ```
#[derive(Clone, Copy, Debug)]
pub struct PacketQuery<'a> {
    /// The rays, cut into packets of [`PACKET_RAYS`].
    pub rays: &'a [Ray],
    /// Which rays to trace (one flag per ray); `None` for all. Untraced rays get no hit.
    pub active: Option<&'a [bool]>,
    /// Packets or single rays.
    pub mode: PacketMode,
}

impl<'a> PacketQuery<'a> {
    /// Every ray of `rays`, in packets where they are coherent ([`PacketMode::Auto`]).
    pub fn new(rays: &'a [Ray]) -> Self {
        PacketQuery {
            rays,
            active: None,
            mode: PacketMode::Auto,
        }
    }

    /// Traces only the rays whose flag is set (one flag per ray).
    pub fn active(self, active: &'a [bool]) -> Self {
        PacketQuery {
            active: Some(active),
            ..self
        }
    }

    /// Chooses packets or single rays by `mode`.
    pub fn mode(self, mode: PacketMode) -> Self {
        PacketQuery { mode, ..self }
    }
}

/// Bit mask of the rays to trace in one packet of `n` rays.
fn active_bits(n: usize, active: Option<&[bool]>) -> u64 {
    match active {
        None if n == 64 => u64::MAX,
        None => (1u64 << n) - 1,
        Some(a) => a
            .iter()
            .enumerate()
            .fold(0, |m, (i, &on)| m | (on as u64) << i),
    }
}

/// Smallest cosine between a packet ray and the first active ray for [`PacketMode::Auto`] to
/// take the packet path when the direction signs differ on two axes.
const COHERENT_COS: f32 = 0.9;

/// Whether the active rays point closely enough the same way for a packet to pay: on at least
/// two axes every sampled direction has the same sign (a zero counts by its sign bit), or
/// every sampled direction lies within `acos(COHERENT_COS)` of the first active ray's (a
/// narrow bundle around an axis, which flips signs). The sample is every fourth active ray
/// and the last: the answer only picks the faster path (both give the same hits). The sign
/// test comes first since it is a few integer operations per ray without branches; random
/// directions fail both, most of them at the dot test's first sample.
#[inline(always)]
fn coherent(rays: &[Ray], active: u64) -> bool {
    if active.count_ones() < 4 {
        return false;
    }
    // Every fourth ray and the last, where active (at least four rays, so `n >= 4`), as bits:
    // the same samples in the same order as an index loop, with no iterator state to step.
    let n = rays.len();
    let sampled = (0x1111_1111_1111_1111 | 1 << (n - 1)) & active;
    let samples = || bits(sampled);
    // Whether two axes' sign bits are the same in every sample: set in `all`, clear in `any`.
    let shared = |all: u32, any: u32| ((all | !any) & 0b111).count_ones() >= 2;
    let (mut all, mut any) = (u32::MAX, 0u32);
    for i in samples() {
        let d = rays[i].dir;
        let sign = |c: f32| c.to_bits() >> 31;
        let signs = sign(d.x) | sign(d.y) << 1 | sign(d.z) << 2;
        all &= signs;
        any |= signs;
        if !shared(all, any) {
            break;
        }
    }
    if shared(all, any) {
        return true;
    }
    let d0 = rays[active.trailing_zeros() as usize].dir;
    let (l0, c2) = (d0.length_squared(), COHERENT_COS * COHERENT_COS);
    samples().all(|i| {
        let d = rays[i].dir;
        let dot = d.dot(d0);
        // False for NaN: such packets go ray by ray.
        dot > 0.0 && dot * dot >= c2 * l0 * d.length_squared()
    })
}

/// Cuts the query's rays into packets and hands each to `run(rays, active bits, use packets,
/// out)`, after checking lengths and deciding by the query's mode whether the packet path
/// pays; a packet with a `t_min` below zero or NaN is handed over with it raised to zero.
#[inline(always)]
pub(crate) fn each_packet<T>(
    query: PacketQuery<'_>,
    out: &mut [T],
    mut run: impl FnMut(&[Ray], u64, bool, &mut [T]),
) {
    let PacketQuery { rays, active, mode } = query;
    assert_eq!(rays.len(), out.len(), "one answer slot per ray");
    if let Some(a) = active {
        assert_eq!(rays.len(), a.len(), "one active flag per ray");
    }
    for (c, (rays, out)) in rays
        .chunks(PACKET_RAYS)
        .zip(out.chunks_mut(PACKET_RAYS))
        .enumerate()
    {
        let from = c * PACKET_RAYS;
        let on = active_bits(rays.len(), active.map(|a| &a[from..from + rays.len()]));
        // A t_min below zero or NaN counts as zero, as for single rays: such a packet is
        // traced as a copy with the interval raised (one comparison per ray otherwise).
        let raised: [Ray; PACKET_RAYS];
        let rays = if rays.iter().all(|r| r.t_min >= 0.0) {
            rays
        } else {
            raised = std::array::from_fn(|i| rays[i.min(rays.len() - 1)].raised_t_min());
            &raised[..rays.len()]
        };
        let packet = match mode {
            PacketMode::Always => true,
            PacketMode::Never => false,
            PacketMode::Auto => coherent(rays, on),
        };
        run(rays, on, packet, out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3A;

    fn fan(n: usize, spread: f32) -> Vec<Ray> {
        (0..n)
            .map(|i| {
                let a = spread * (i as f32 / n as f32 - 0.5);
                Ray::new(Vec3A::ZERO, Vec3A::new(a.sin(), 0.0, a.cos()))
            })
            .collect()
    }

    #[test]
    fn active_bits_cover_partial_and_full_packets() {
        assert_eq!(active_bits(64, None), u64::MAX);
        assert_eq!(active_bits(63, None), u64::MAX >> 1);
        assert_eq!(active_bits(1, None), 1);
        let flags: Vec<bool> = (0..64).map(|i| i == 0 || i == 63).collect();
        assert_eq!(active_bits(64, Some(&flags)), 1 | 1 << 63);
    }

    #[test]
    fn packets_are_coherent_when_direction_signs_agree_on_two_axes() {
        let deg = std::f32::consts::PI / 180.0;
        // A fan around +z in the xz plane: x changes sign, y (zero) and z do not.
        assert!(coherent(&fan(64, 80.0 * deg), u64::MAX));
        // Directions into every octant (rays 4k point into octant k mod 8) are not ...
        let octants: Vec<Ray> = (0..64)
            .map(|i| {
                let k = i / 4;
                let s = |bit: usize| if k >> bit & 1 == 0 { 1.0 } else { -1.0 };
                Ray::new(Vec3A::ZERO, Vec3A::new(s(0), s(1), s(2)))
            })
            .collect();
        assert!(!coherent(&octants, u64::MAX));
        // ... unless the active rays share two signs: octants 0 and 1 differ in x only.
        assert!(coherent(&octants, 0xFF));
        // Octants 0 and 3 differ in x and y.
        assert!(!coherent(&octants, 0xF | 0xF << 12));
        // Fewer than four active rays never pay.
        assert!(!coherent(&fan(64, 0.0), 0b111));
        // A ray pointing back flips every sign.
        let mut back = fan(64, 0.0);
        back[4].dir = -back[4].dir;
        assert!(!coherent(&back, u64::MAX));
        // A narrow bundle around -z flips the signs of x and y and still pays: within 25°.
        let around = |spread: f32| -> Vec<Ray> {
            (0..64)
                .map(|i| {
                    let a = spread * i as f32 / 64.0;
                    let (x, y) = (a.cos(), a.sin());
                    Ray::new(Vec3A::ZERO, Vec3A::new(x * 0.1, y * 0.1, -1.0))
                })
                .collect()
        };
        assert!(coherent(&around(std::f32::consts::TAU), u64::MAX));
        let wide: Vec<Ray> = around(std::f32::consts::TAU)
            .into_iter()
            .map(|r| Ray::new(r.origin, r.dir * Vec3A::new(10.0, 10.0, 1.0)))
            .collect();
        assert!(!coherent(&wide, u64::MAX));
    }
}
