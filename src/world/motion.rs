//! [`Motion`]: an instance that moves while the shutter is open, as two or more transforms
//! at evenly spaced times ("keys"), interpolated per ray at the ray's [`Ray::time`]
//! ([`Interpolation`]); the world box that holds it over the whole shutter; and the checks a
//! motion must pass.
//!
//! [`Ray::time`]: crate::Ray::time

use super::instance::{invert, mirrors};
use super::top::{corner_box, padded};
use super::WorldError;
use crate::geometry::Aabb;
use crate::layout::ends::pad_ends;
use glam::{Affine3A, DMat3, DQuat, DVec3, Mat3A, Quat, Vec3A};

/// The most keys a motion may have (Embree allows 129 time steps; a shutter sampled more
/// finely than this is better given as a deforming geometry).
pub const MAX_MOTION_KEYS: usize = 256;

/// How a [`Motion`] goes from one key to the next.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Interpolation {
    /// The matrices' entries, linearly: exact for translation and for scale, but a rotation
    /// between two keys shrinks on the way (a half turn passes through a flat matrix, where
    /// the instance is missed). The cheapest per ray, and what most motion data is.
    Linear,
    /// Each key split into a rotation, a scale-and-shear (upper triangular) and a
    /// translation; the rotations interpolated spherically (a constant angular speed along
    /// the shorter arc: each step between keys must turn less than half a turn), the rest
    /// linearly. A spinning wheel keeps its size.
    Decomposed,
}

/// An instance's movement over the shutter interval: `keys[k]` (object to world) is where it
/// is at time `k / (keys - 1)`, and a ray at time `t` meets it where the interpolation
/// between the two keys around `t` places it. Given to
/// [`WorldBuilder::add_moving_instance`](super::WorldBuilder::add_moving_instance) or
/// [`WorldEdit::set_motion`](super::WorldEdit::set_motion).
///
/// ```
/// use quiver_rt::glam::{Affine3A, Vec3};
/// use quiver_rt::world::{Interpolation, Motion};
/// let slide = Motion::linear(vec![
///     Affine3A::from_translation(Vec3::ZERO),
///     Affine3A::from_translation(Vec3::new(2.0, 0.0, 0.0)),
/// ]);
/// assert_eq!(slide.at(0.25).translation.x, 0.5);
/// assert_eq!(slide.at(5.0), slide.keys()[1]); // a time past the shutter is its end
/// // A quarter turn about z, decomposed: the rotation keeps the unit x axis at unit length.
/// let turn = Motion::decomposed(vec![
///     Affine3A::IDENTITY,
///     Affine3A::from_rotation_z(std::f32::consts::FRAC_PI_2),
/// ]);
/// assert_eq!(turn.interpolation(), Interpolation::Decomposed);
/// let half = turn.at(0.5).transform_vector3(Vec3::X);
/// assert!((half.length() - 1.0).abs() < 1e-6 && (half.x - half.y).abs() < 1e-6);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Motion {
    keys: Vec<Affine3A>,
    interpolation: Interpolation,
    /// Each key split for [`Interpolation::Decomposed`] (empty for linear motion).
    parts: Vec<Parts>,
}

/// A key as rotation times scale-and-shear, plus translation: `m = rotation * stretch`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Parts {
    /// A unit quaternion, its sign chosen so that it is on the near side of the previous
    /// key's (their dot product is not negative): the interpolation takes the shorter arc.
    rotation: Quat,
    /// Upper triangular; its diagonal positive but for a mirroring key's last entry.
    stretch: Mat3A,
    translation: Vec3A,
    /// Half the angle from this key's rotation to the next one's (the quaternions' angle).
    half_turn: f32,
}

impl Motion {
    /// A motion through `keys` whose matrices are interpolated entry by entry
    /// ([`Interpolation::Linear`]).
    pub fn linear(keys: Vec<Affine3A>) -> Motion {
        Motion {
            keys,
            interpolation: Interpolation::Linear,
            parts: Vec::new(),
        }
    }

    /// A motion through `keys` whose rotations turn at a constant speed
    /// ([`Interpolation::Decomposed`]).
    pub fn decomposed(keys: Vec<Affine3A>) -> Motion {
        let mut parts: Vec<Parts> = keys.iter().map(split).collect();
        for k in 1..parts.len() {
            if parts[k - 1].rotation.dot(parts[k].rotation) < 0.0 {
                parts[k].rotation = -parts[k].rotation;
            }
            let d = f64::from(parts[k - 1].rotation.dot(parts[k].rotation));
            parts[k - 1].half_turn = d.clamp(-1.0, 1.0).acos() as f32;
        }
        Motion {
            keys,
            interpolation: Interpolation::Decomposed,
            parts,
        }
    }

    /// The keys, object to world, evenly spaced over the shutter.
    pub fn keys(&self) -> &[Affine3A] {
        &self.keys
    }

    /// How the keys are interpolated.
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// Bytes its keys (and their decomposed parts) take, for [`World::footprint`](super::World::footprint).
    pub(super) fn bytes(&self) -> usize {
        std::mem::size_of_val(self.keys.as_slice()) + std::mem::size_of_val(self.parts.as_slice())
    }

    /// The transform (object to world) a ray at `time` meets: `time` clamped into `[0, 1]`
    /// (NaN taken as 0, as [`Ray::shutter_time`](crate::Ray::shutter_time) does), and at a
    /// key's own time exactly that key. (A motion of one key is that key at every time, one
    /// of none the identity; neither is one a world takes.)
    #[inline(always)]
    pub fn at(&self, time: f32) -> Affine3A {
        if self.keys.len() < 2 {
            return self.keys.first().copied().unwrap_or(Affine3A::IDENTITY);
        }
        let (k, f) = self.segment(crate::geometry::shutter(time));
        if f == 0.0 {
            return self.keys[k];
        }
        if f == 1.0 {
            return self.keys[k + 1];
        }
        match self.interpolation {
            Interpolation::Linear => {
                let (a, b) = (&self.keys[k], &self.keys[k + 1]);
                let mix = |x: Vec3A, y: Vec3A| x * (1.0 - f) + y * f;
                Affine3A {
                    matrix3: Mat3A::from_cols(
                        mix(a.matrix3.x_axis, b.matrix3.x_axis),
                        mix(a.matrix3.y_axis, b.matrix3.y_axis),
                        mix(a.matrix3.z_axis, b.matrix3.z_axis),
                    ),
                    translation: mix(a.translation, b.translation),
                }
            }
            Interpolation::Decomposed => self.decomposed_at(k, f),
        }
    }

    /// The decomposed interpolation between keys `k` and `k + 1` at `f` (strictly between
    /// them): out of line, so the walks that inline a linear motion's transform do not carry
    /// the slerp's trigonometry.
    #[inline(never)]
    fn decomposed_at(&self, k: usize, f: f32) -> Affine3A {
        let (a, b) = (&self.parts[k], &self.parts[k + 1]);
        let mix = |x: Vec3A, y: Vec3A| x * (1.0 - f) + y * f;
        let stretch = Mat3A::from_cols(
            mix(a.stretch.x_axis, b.stretch.x_axis),
            mix(a.stretch.y_axis, b.stretch.y_axis),
            mix(a.stretch.z_axis, b.stretch.z_axis),
        );
        let rotation = slerp(a.rotation, b.rotation, a.half_turn, f);
        Affine3A {
            matrix3: Mat3A::from_quat(rotation) * stretch,
            translation: mix(a.translation, b.translation),
        }
    }

    /// World to object space at `time` (already clamped), or `None` where the interpolated
    /// transform has no finite f32 inverse (a linear motion through a flat matrix): no ray
    /// meets the instance then.
    #[inline(always)]
    pub(super) fn to_object(&self, time: f32) -> Option<Affine3A> {
        let inverse = self.at(time).inverse();
        inverse.is_finite().then_some(inverse)
    }

    /// The key before `time` (in `[0, 1]`) and how far past it `time` is, as a fraction of
    /// the step to the next key (the motion has two keys or more).
    #[inline(always)]
    fn segment(&self, time: f32) -> (usize, f32) {
        let steps = self.keys.len() - 1;
        let s = time * steps as f32;
        // Through u32 (`s` lies in [0, 255]): f32 to usize, an unsigned 64-bit conversion
        // that saturates, costs a dozen instructions more on x86.
        let k = (s as u32 as usize).min(steps - 1);
        (k, s - k as f32)
    }

    /// Why `self` cannot move instance `instance`, if it cannot (what
    /// [`WorldBuilder::build`](super::WorldBuilder::build) reports): fewer than two keys or
    /// more than [`MAX_MOTION_KEYS`], a key [`invert`] refuses, keys that mirror and keys
    /// that do not (the motion would pass through a flat matrix), or, decomposed, a step that
    /// turns half a turn or more (no shorter arc to take).
    ///
    /// ```
    /// use quiver_rt::glam::Affine3A;
    /// use quiver_rt::{Motion, WorldError};
    /// let once = Motion::linear(vec![Affine3A::IDENTITY]);
    /// let why = "fewer than two keys";
    /// assert_eq!(once.check(3), Err(WorldError::Motion { instance: 3, key: None, why }));
    /// ```
    ///
    /// # Errors
    /// [`WorldError::Motion`] naming `instance`, and the key at fault where one is.
    pub fn check(&self, instance: usize) -> Result<(), WorldError> {
        let error =
            |key: Option<usize>, why: &'static str| WorldError::Motion { instance, key, why };
        if self.keys.len() < 2 {
            return Err(error(None, "fewer than two keys"));
        }
        if self.keys.len() > MAX_MOTION_KEYS {
            return Err(error(None, "more keys than MAX_MOTION_KEYS"));
        }
        let mirrored = mirrors(&self.keys[0]);
        for (k, key) in self.keys.iter().enumerate() {
            invert(key).map_err(|why| error(Some(k), why))?;
            if mirrors(key) != mirrored {
                return Err(error(
                    Some(k),
                    "mirrors where the first key does not, or the other way",
                ));
            }
        }
        for (k, p) in self.parts.iter().enumerate() {
            if !(p.rotation.is_finite() && p.stretch.is_finite() && p.translation.is_finite()) {
                return Err(error(Some(k), "not split into rotation and scale in f32"));
            }
        }
        let near_half = (std::f64::consts::FRAC_PI_2 * (1.0 - 1e-6)) as f32;
        let steps = self.parts.len().saturating_sub(1);
        match (0..steps).find(|&k| self.parts[k].half_turn >= near_half) {
            Some(k) => Err(error(
                Some(k),
                "turns half a turn or more before the next key",
            )),
            None => Ok(()),
        }
    }

    /// The world box of an object box `b` over the whole motion (padded as a static
    /// instance's is, for the rounding of either transform).
    pub(super) fn world_box(&self, b: &Aabb) -> Aabb {
        if b.is_empty() {
            return Aabb::EMPTY;
        }
        let mut out = Aabb::EMPTY;
        match self.interpolation {
            // Each point of the object moves along straight lines between its places at
            // the keys: the keys' boxes hold it.
            Interpolation::Linear => self
                .keys
                .iter()
                .for_each(|m| out = out.union(&corner_box(m, b))),
            Interpolation::Decomposed => {
                for k in 0..self.parts.len() - 1 {
                    out = out.union(&turning_box(&self.parts[k], &self.parts[k + 1], b));
                }
            }
        }
        padded(out)
    }

    /// Boxes at the shutter's two ends whose linear interpolation at every time holds object
    /// box `b` where the motion places it then (for the top level's moving boxes,
    /// [`crate::layout::ends`]), padded for the walk's rounding as [`Motion::world_box`] is.
    ///
    /// Each step between keys is held by a box that moves linearly over it (linear motion:
    /// the keys' own boxes, since every point moves on a straight line between its places
    /// at them; decomposed: the step's box over its whole arc, still): the ends start as
    /// the first and last of these and both move out by what any step's box still exceeds
    /// at either of its times, which keeps every step inside, since two linear bounds that
    /// hold at a step's two times hold between them.
    pub(super) fn end_boxes(&self, b: &Aabb) -> [Aabb; 2] {
        if b.is_empty() {
            return [Aabb::EMPTY; 2];
        }
        let steps = self.keys.len() - 1;
        // Step k's boxes at its start and its end.
        let step: Vec<[Aabb; 2]> = match self.interpolation {
            Interpolation::Linear => (0..steps)
                .map(|k| {
                    [
                        corner_box(&self.keys[k], b),
                        corner_box(&self.keys[k + 1], b),
                    ]
                })
                .collect(),
            Interpolation::Decomposed => (0..steps)
                .map(|k| turning_box(&self.parts[k], &self.parts[k + 1], b))
                .map(|s| [s, s])
                .collect(),
        };
        let d = |v: Vec3A| DVec3::new(v.x.into(), v.y.into(), v.z.into());
        let (mut lo, mut hi) = (
            [d(step[0][0].min), d(step[steps - 1][1].min)],
            [d(step[0][0].max), d(step[steps - 1][1].max)],
        );
        for (k, s) in step.iter().enumerate() {
            for (j, held) in s.iter().enumerate() {
                let t = (k + j) as f64 / steps as f64;
                let over_lo = (lo[0] * (1.0 - t) + lo[1] * t - d(held.min)).max(DVec3::ZERO);
                let over_hi = (d(held.max) - hi[0] * (1.0 - t) - hi[1] * t).max(DVec3::ZERO);
                lo = [lo[0] - over_lo, lo[1] - over_lo];
                hi = [hi[0] + over_hi, hi[1] + over_hi];
            }
        }
        // Rounded outwards to f32 (a relative step), then padded for the walk's arithmetic.
        let out = |v: DVec3, dir: f64| {
            let v = v + v.abs() * (dir * f64::from(f32::EPSILON));
            Vec3A::new(v.x as f32, v.y as f32, v.z as f32)
        };
        let end = |j: usize| padded(Aabb::new(out(lo[j], -1.0), out(hi[j], 1.0)));
        pad_ends([end(0), end(1)])
    }
}

/// How many rotations along each step's arc are boxed: the arc between two of them strays
/// from their chord by at most `1 - cos(half_turn / ARC_STEPS)` of the radius (under 0.5%).
const ARC_STEPS: usize = 16;

/// The world box of object box `b` while the motion goes from key `a` to key `z`: the
/// translations' box plus the box of the rotated scale-and-shear box along the arc.
fn turning_box(a: &Parts, z: &Parts, b: &Aabb) -> Aabb {
    let d = |v: Vec3A| DVec3::new(v.x.into(), v.y.into(), v.z.into());
    let dm = |m: &Mat3A| DMat3::from_cols(d(m.x_axis), d(m.y_axis), d(m.z_axis));
    let corners = |lo: DVec3, hi: DVec3| {
        (0..8).map(move |k| {
            DVec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            )
        })
    };
    // Scale and shear move each point on a straight line: both ends' boxes hold it.
    let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    for s in [dm(&a.stretch), dm(&z.stretch)] {
        for c in corners(d(b.min), d(b.max)) {
            lo = lo.min(s * c);
            hi = hi.max(s * c);
        }
    }
    let radius = corners(lo, hi).map(|c| c.length()).fold(0.0, f64::max);
    let q = |r: Quat| DQuat::from_xyzw(r.x.into(), r.y.into(), r.z.into(), r.w.into()).normalize();
    let (qa, qz, half) = (q(a.rotation), q(z.rotation), f64::from(a.half_turn));
    let (mut rlo, mut rhi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    for j in 0..=ARC_STEPS {
        let f = j as f64 / ARC_STEPS as f64;
        let r = DMat3::from_quat(slerp64(qa, qz, half, f));
        for c in corners(lo, hi) {
            rlo = rlo.min(r * c);
            rhi = rhi.max(r * c);
        }
    }
    // Off the chords: the sagitta of the widest arc, and a margin for the f32 rotation
    // matrices of the walk (a few ulps of the radius).
    let off = radius * (1.0 - (half / ARC_STEPS as f64).cos()) + radius * 1e-6;
    let (ta, tz) = (d(a.translation), d(z.translation));
    let down = |v: DVec3| Vec3A::new(v.x as f32, v.y as f32, v.z as f32);
    let lo = rlo - DVec3::splat(off) + ta.min(tz);
    let hi = rhi + DVec3::splat(off) + ta.max(tz);
    // Rounded outwards by a relative f32 step.
    let out = |v: DVec3, dir: f64| down(v + v.abs() * (dir * f64::from(f32::EPSILON)));
    Aabb::new(out(lo, -1.0), out(hi, 1.0))
}

/// The spherical interpolation of unit quaternions `a` and `b` (on the same side) that are
/// `half` apart, at `f` in `[0, 1]`, normalised: a rotation on the arc from `a` to `b`.
#[inline(always)]
fn slerp(a: Quat, b: Quat, half: f32, f: f32) -> Quat {
    let s = half.sin();
    let q = if s < 1e-4 {
        a * (1.0 - f) + b * f
    } else {
        a * (((1.0 - f) * half).sin() / s) + b * ((f * half).sin() / s)
    };
    q.normalize()
}

/// [`slerp`] in f64, for the bounds.
fn slerp64(a: DQuat, b: DQuat, half: f64, f: f64) -> DQuat {
    let s = half.sin();
    let q = if s < 1e-9 {
        a * (1.0 - f) + b * f
    } else {
        a * (((1.0 - f) * half).sin() / s) + b * ((f * half).sin() / s)
    };
    q.normalize()
}

/// Key `m` split as `rotation * stretch` (Gram–Schmidt on its columns, in f64) plus its
/// translation. A mirroring key keeps a proper rotation: its mirror goes into the stretch's
/// last diagonal entry.
fn split(m: &Affine3A) -> Parts {
    let d = |v: Vec3A| DVec3::new(v.x.into(), v.y.into(), v.z.into());
    let (c0, c1, c2) = (
        d(m.matrix3.x_axis),
        d(m.matrix3.y_axis),
        d(m.matrix3.z_axis),
    );
    let r00 = c0.length();
    let q0 = c0 / r00;
    let r01 = q0.dot(c1);
    let v1 = c1 - q0 * r01;
    let r11 = v1.length();
    let q1 = v1 / r11;
    let (r02, r12) = (q0.dot(c2), q1.dot(c2));
    let v2 = c2 - q0 * r02 - q1 * r12;
    let mut r22 = v2.length();
    let mut q2 = v2 / r22;
    if q0.cross(q1).dot(q2) < 0.0 {
        q2 = -q2;
        r22 = -r22;
    }
    let rotation = DQuat::from_mat3(&DMat3::from_cols(q0, q1, q2)).normalize();
    let f = |x: f64, y: f64, z: f64| Vec3A::new(x as f32, y as f32, z as f32);
    Parts {
        rotation: Quat::from_xyzw(
            rotation.x as f32,
            rotation.y as f32,
            rotation.z as f32,
            rotation.w as f32,
        ),
        stretch: Mat3A::from_cols(f(r00, 0.0, 0.0), f(r01, r11, 0.0), f(r02, r12, r22)),
        translation: m.translation,
        half_turn: 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// The box the top level's walk meets at `t`, computed as it computes it: the change
    /// rounded to f32, then `start + t * delta`.
    fn at(ends: &[Aabb; 2], t: f32) -> Aabb {
        let (dlo, dhi) = (ends[1].min - ends[0].min, ends[1].max - ends[0].max);
        Aabb::new(ends[0].min + dlo * t, ends[0].max + dhi * t)
    }

    #[test]
    fn the_end_boxes_hold_the_instance_at_every_time() {
        let mut rng = Rng::new(7);
        let mut unit = || rng.in_box(Vec3A::ZERO, Vec3A::ONE);
        let mut tightened = 0;
        for case in 0..200 {
            let lo = (unit() - 0.5) * 10.0;
            let b = Aabb::new(lo, lo + unit() * 3.0 + 0.01);
            let keys_n = 2 + case % 4;
            let axis = glam::Vec3::from(unit() - 0.5).normalize_or(glam::Vec3::Y);
            let turn = unit().x * 0.45 * std::f32::consts::TAU;
            let keys: Vec<Affine3A> = (0..keys_n)
                .map(|k| {
                    let drift = glam::Vec3::from(unit() - 0.5) * 8.0 * (1 + case % 3) as f32;
                    let grow = glam::Vec3::from(unit()) + 0.5;
                    Affine3A::from_translation(drift)
                        * Affine3A::from_quat(Quat::from_axis_angle(axis, turn * k as f32))
                        * Affine3A::from_scale(grow)
                })
                .collect();
            let m = match case % 2 {
                0 => Motion::linear(keys),
                _ => Motion::decomposed(keys),
            };
            let ends = m.end_boxes(&b);
            let whole = m.world_box(&b);
            for j in 0..=1000 {
                let t = j as f32 / 1000.0;
                let held = at(&ends, t);
                let placed = corner_box(&m.at(t), &b);
                assert!(
                    held.contains(&placed),
                    "case {case} at {t}: {placed:?} outside {held:?}"
                );
            }
            // Where the instance travels farther than its size, the box at a time is
            // smaller than the box over the whole shutter (what the ends are for).
            tightened += usize::from(at(&ends, 0.5).half_area() < 0.9 * whole.half_area());
        }
        assert!(tightened > 100, "{tightened} of 200 motions tightened");
    }
}
