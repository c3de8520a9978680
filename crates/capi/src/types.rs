//! The plain structs C passes and receives, and their conversions to and from the core's
//! types.

use crate::error::{Failure, QvStatus};
use quiver_rt::glam::{Affine3A, Vec3A};
use quiver_rt::point::PointHit;
use quiver_rt::world::WorldPointHit;
use quiver_rt::{BuildOptions, Hit, Layout, Ray, WorldHit};
use std::ffi::{c_char, c_int, c_void, CStr};

/// The id a hit reports where it names nothing: no hit, or the geometry and instance of a
/// hit in a lone BVH (`UINT32_MAX`, `QV_INVALID_ID` in C).
pub const QV_INVALID_ID: u32 = u32::MAX;

/// A ray: points `org + t * dir` for `t` in `[t_min, t_max]` (closed), seen only by world
/// instances whose mask shares a bit with `mask` (a lone BVH ignores the mask).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QvRay {
    /// The origin.
    pub org: [f32; 3],
    /// The start of the interval (negative values count as 0).
    pub t_min: f32,
    /// The direction, not necessarily unit length: `t` is in its units.
    pub dir: [f32; 3],
    /// The end of the interval (`INFINITY` for no end).
    pub t_max: f32,
    /// Which instances the ray sees (`0xFFFFFFFF`: all).
    pub mask: u32,
    /// When in the shutter the ray is shot, 0 to 1 (moving instances are met where they are
    /// then; clamped, NaN as 0; a static scene ignores it).
    pub time: f32,
}

impl QvRay {
    /// The core's ray.
    pub(crate) fn to_ray(self) -> Ray {
        Ray::segment(
            Vec3A::from(self.org),
            Vec3A::from(self.dir),
            self.t_min,
            self.t_max,
        )
        .with_mask(self.mask)
        .with_time(self.time)
    }
}

/// A hit: distance, barycentrics and what was hit; on a miss `prim`, `geometry` and
/// `instance` are [`QV_INVALID_ID`], `t` is infinite and `u`, `v` are 0.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QvHit {
    /// Distance along the ray, in units of its direction.
    pub t: f32,
    /// Barycentric weight of the triangle's second vertex.
    pub u: f32,
    /// Barycentric weight of the triangle's third vertex.
    pub v: f32,
    /// The triangle: its index in the mesh's index buffer.
    pub prim: u32,
    /// The geometry hit (worlds); [`QV_INVALID_ID`] for a lone BVH.
    pub geometry: u32,
    /// The instance hit (worlds); [`QV_INVALID_ID`] for a lone BVH.
    pub instance: u32,
}

impl QvHit {
    /// The record of a miss.
    pub const MISS: QvHit = QvHit {
        t: f32::INFINITY,
        u: 0.0,
        v: 0.0,
        prim: QV_INVALID_ID,
        geometry: QV_INVALID_ID,
        instance: QV_INVALID_ID,
    };

    /// A lone BVH's hit, or the miss record.
    pub(crate) fn of_bvh(hit: Option<Hit>) -> QvHit {
        hit.map_or(QvHit::MISS, |h| QvHit {
            t: h.t,
            u: h.u,
            v: h.v,
            prim: h.prim,
            ..QvHit::MISS
        })
    }

    /// A world's hit, or the miss record.
    pub(crate) fn of_world(hit: Option<WorldHit>) -> QvHit {
        hit.map_or(QvHit::MISS, |h| QvHit {
            t: h.t,
            u: h.u,
            v: h.v,
            prim: h.prim,
            geometry: h.geometry.0,
            instance: h.instance.0,
        })
    }
}

/// The nearest point of a BVH's or a world's triangles to a query point; on a miss (nothing
/// within the distance asked) `prim`, `geometry` and `instance` are [`QV_INVALID_ID`],
/// `distance` infinite and the rest 0.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QvPointHit {
    /// The point on the triangle.
    pub point: [f32; 3],
    /// Its distance from the query point.
    pub distance: f32,
    /// Barycentric weight of the triangle's second vertex at `point`.
    pub u: f32,
    /// Barycentric weight of the third vertex.
    pub v: f32,
    /// The triangle: its index in the mesh's index buffer.
    pub prim: u32,
    /// Worlds: the triangle's geometry. A lone BVH: [`QV_INVALID_ID`].
    pub geometry: u32,
    /// Worlds: the triangle's instance. A lone BVH: [`QV_INVALID_ID`].
    pub instance: u32,
}

impl QvPointHit {
    /// The record of no point.
    const MISS: QvPointHit = QvPointHit {
        point: [0.0; 3],
        distance: f32::INFINITY,
        u: 0.0,
        v: 0.0,
        prim: QV_INVALID_ID,
        geometry: QV_INVALID_ID,
        instance: QV_INVALID_ID,
    };

    /// A BVH's answer, or the miss record.
    pub(crate) fn of(hit: Option<PointHit>) -> QvPointHit {
        hit.map_or(QvPointHit::MISS, |h| QvPointHit {
            point: h.point.into(),
            distance: h.distance,
            u: h.u,
            v: h.v,
            prim: h.prim,
            ..QvPointHit::MISS
        })
    }

    /// A world's answer, or the miss record.
    pub(crate) fn of_world(hit: Option<WorldPointHit>) -> QvPointHit {
        hit.map_or(QvPointHit::MISS, |h| QvPointHit {
            point: h.point.into(),
            distance: h.distance,
            u: h.u,
            v: h.v,
            prim: h.prim,
            geometry: h.geometry.0,
            instance: h.instance.0,
        })
    }
}

/// A geometry's hit filter: called with the `user` pointer given with it and a candidate hit
/// (valid only during the call); returns nonzero to keep the candidate, 0 to pass through it.
/// It runs on any thread, several at once (see `qv_world_builder_set_filter`).
pub type QvFilterFn =
    Option<unsafe extern "C" fn(user: *mut c_void, candidate: *const QvHit) -> c_int>;

/// An object-to-world transform from 12 floats, a 3×4 matrix in row-major order: row `r` is
/// `m[4r..4r + 4]`, the last column the translation.
pub(crate) fn affine_of_rows(m: &[f32; 12]) -> Affine3A {
    Affine3A::from_cols_array(&[
        m[0], m[4], m[8], // first column
        m[1], m[5], m[9], // second column
        m[2], m[6], m[10], // third column
        m[3], m[7], m[11], // translation
    ])
}

/// A build preset, [`QvBuildOptions::quality`]'s values.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum QvQuality {
    /// `BuildOptions::default()`: binned SAH.
    Default = 0,
    /// `BuildOptions::fast()`: the LBVH builder, several times faster to build.
    Fast = 1,
    /// `BuildOptions::high_quality()`: spatial splits, slower to build, faster to trace
    /// where triangles are long or overlap.
    High = 2,
}

impl QvQuality {
    /// Every preset, in the order of their values.
    pub(crate) const ALL: [QvQuality; 3] = [QvQuality::Default, QvQuality::Fast, QvQuality::High];
}

/// How a BVH is built: a preset and, optionally, a layout other than the preset's.
///
/// `quality` is a `uint32_t` rather than the C enum so that a value outside [`QvQuality`]
/// arrives as a number to refuse, not as an invalid Rust enum.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct QvBuildOptions {
    /// A [`QvQuality`] value.
    pub quality: u32,
    /// NULL for the preset's layout, else a NUL-terminated layout name as quiver's CLI spells
    /// it (`Layout::name`: `"bvh8-dfs"`, `"bvh4-quant"`, `"bvh2-dfs"`, ...).
    pub layout: *const c_char,
}

/// The core's build options for the C options at `options` (NULL: the defaults); refusals
/// name `options.quality` or `options.layout`.
///
/// # Safety
/// `options` is NULL or readable for one `QvBuildOptions`, whose `layout` is NULL or a
/// NUL-terminated string.
pub(crate) unsafe fn options_of(
    options: *const QvBuildOptions,
) -> Result<BuildOptions<'static>, Failure> {
    let bad = |why: String| Failure::new(QvStatus::InvalidArgument, why);
    if options.is_null() {
        return Ok(BuildOptions::default());
    }
    // SAFETY: not NULL (checked), readable (the caller's contract); read unaligned, as a C
    // caller may hand any address, and every bit pattern is a valid `QvBuildOptions`.
    let o = unsafe { options.read_unaligned() };
    let preset = match QvQuality::ALL.get(o.quality as usize) {
        Some(QvQuality::Default) => BuildOptions::default(),
        Some(QvQuality::Fast) => BuildOptions::fast(),
        Some(QvQuality::High) => BuildOptions::high_quality(),
        None => {
            return Err(bad(format!(
                "options.quality: {} is not a QvQuality (0 default, 1 fast, 2 high)",
                o.quality
            )))
        }
    };
    if o.layout.is_null() {
        return Ok(preset);
    }
    // SAFETY: not NULL (checked), NUL-terminated (the caller's contract).
    let name = unsafe { CStr::from_ptr(o.layout) };
    let name = name
        .to_str()
        .map_err(|_| bad("options.layout: not UTF-8".to_string()))?;
    let layout: Layout = name.parse().map_err(|e: quiver_rt::names::ParseError| {
        bad(format!(
            "options.layout: unknown layout '{}': expected one of {}",
            e.given,
            e.expected.join(", ")
        ))
    })?;
    Ok(preset.layout(layout))
}
