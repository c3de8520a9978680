//! Jacco Bikker's tinybvh as a comparison engine (feature `tinybvh`): its CPU layouts
//! `BVH8_CPU` (eight-wide nodes, four-triangle SoA leaves, AVX2) and `BVH4_CPU` on the same
//! triangles and rays as quiver's kernels, so `quiver bench` and `quiver packets` can time
//! them side by side.
//!
//! tinybvh is one C++ header. build.rs compiles it, with a small C++ shim of ours
//! (`ffi/tinybvh_shim.cpp`: builds, `Intersect` and `IsOccluded` of both layouts, sizes) in one
//! translation unit at `-O3 -march=native`, from the header in the directory
//! `QUIVER_TINYBVH_HEADER_DIR` names, or else the 1.6.8 snapshot the `tinybvh-rs` crate ships
//! (whose Rust API offers neither `IsOccluded` nor `BVH4_CPU`, so only its header is used).
//! [`version`] says which header was compiled.
//!
//! ```
//! use glam::Vec3A;
//! use quiver_rt::{Ray, Triangle};
//! use quiver_lab::tinybvh::{TinyBvh, TinyLayout};
//! let tris = [Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)];
//! let bvh = TinyBvh::new(&tris, TinyLayout::Bvh8Cpu).unwrap();
//! let ray = Ray::new(Vec3A::new(0.25, 0.25, 1.0), -Vec3A::Z);
//! let (prim, t) = bvh.closest_hit(&ray).unwrap();
//! // tinybvh divides by a refined approximate reciprocal: t is 1 to within an ulp or two.
//! assert!(prim == 0 && (t - 1.0).abs() < 1e-6, "{prim} {t}");
//! assert!(bvh.any_hit(&ray));
//! ```
//!
//! tinybvh's rays have no `t_min`: a ray over `[t_min, t_max]` is handed over as one starting
//! at `origin + t_min · dir` over `[0, t_max − t_min]`, and its t moved back. Its triangle test
//! (Möller–Trumbore with an approximate reciprocal of the determinant, so t may be off in its
//! last bits) and tie rule are its own (the tests allow one disagreement with the reference in 1,000
//! rays). A NaN in a ray would make tinybvh end the process, so such rays are answered here
//! as misses without asking it; triangles with a non-finite vertex are left out of its build,
//! as quiver and Embree leave them out.

use quiver_rt::{Ray, Triangle};
use std::ffi::c_void;

/// A ray as the shim takes it.
#[repr(C)]
struct ShimRay {
    ox: f32,
    oy: f32,
    oz: f32,
    dx: f32,
    dy: f32,
    dz: f32,
    t_max: f32,
}

/// tinybvh's `bvhvec4`, which it aligns to 16 bytes (and may load as such).
#[repr(C, align(16))]
#[derive(Clone, Copy)]
struct Vec4([f32; 4]);

extern "C" {
    fn quiver_tinybvh8_build(vertices: *const f32, tris: u32) -> *mut c_void;
    fn quiver_tinybvh8_free(bvh: *mut c_void);
    fn quiver_tinybvh8_intersect(
        bvh: *const c_void,
        ray: *const ShimRay,
        t: *mut f32,
        prim: *mut u32,
    ) -> i32;
    fn quiver_tinybvh8_occluded(bvh: *const c_void, ray: *const ShimRay) -> i32;
    fn quiver_tinybvh8_bytes(bvh: *const c_void, used: *mut u64, allocated: *mut u64);
    fn quiver_tinybvh8_depth(bvh: *const c_void) -> u32;
    fn quiver_tinybvh4_depth(bvh: *const c_void) -> u32;
    fn quiver_tinybvh4_build(vertices: *const f32, tris: u32) -> *mut c_void;
    fn quiver_tinybvh4_free(bvh: *mut c_void);
    fn quiver_tinybvh4_intersect(
        bvh: *const c_void,
        ray: *const ShimRay,
        t: *mut f32,
        prim: *mut u32,
    ) -> i32;
    fn quiver_tinybvh4_occluded(bvh: *const c_void, ray: *const ShimRay) -> i32;
    fn quiver_tinybvh4_bytes(bvh: *const c_void, used: *mut u64, allocated: *mut u64);
    fn quiver_tinybvh_version(major: *mut u32, minor: *mut u32, sub: *mut u32);
    fn quiver_tinybvh_counters(out: *mut u64, reset: i32) -> i32;
}

/// The tinybvh compiled in: its version macros, the header's path and an FNV-1a hash of its
/// bytes (development snapshots keep the release's number), e.g. `1.6.8 (tiny_bvh.h
/// 3f0c…, /work/tinybvh-new/tiny_bvh.h)`.
///
/// ```
/// assert!(quiver_lab::tinybvh::version().starts_with("1."));
/// ```
pub fn version() -> String {
    let (mut major, mut minor, mut sub) = (0, 0, 0);
    // SAFETY: three out-pointers to locals.
    unsafe { quiver_tinybvh_version(&mut major, &mut minor, &mut sub) };
    format!(
        "{major}.{minor}.{sub} (tiny_bvh.h {}, {})",
        env!("QUIVER_TINYBVH_HEADER_HASH"),
        env!("QUIVER_TINYBVH_HEADER")
    )
}

/// Traversal work counted by an instrumented header since the last call (which resets it):
/// `[nodes, leaves, triangle lanes tested, stack pushes]` summed over all threads, or `None`
/// when the compiled header keeps no counters (the shipped ones do not; a profiling copy of
/// the header may define `QUIVER_TINYBVH_COUNTERS` and the counters the shim reads).
pub fn take_counters() -> Option<[u64; 4]> {
    let mut out = [0u64; 4];
    // SAFETY: `out` holds the four values the shim writes.
    let kept = unsafe { quiver_tinybvh_counters(out.as_mut_ptr(), 1) };
    (kept != 0).then_some(out)
}

/// Which of tinybvh's CPU layouts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TinyLayout {
    /// `BVH8_CPU`: 256-byte eight-wide nodes, 192-byte leaves of four triangles (AVX2).
    Bvh8Cpu,
    /// `BVH4_CPU`: 128-byte four-wide nodes, the same leaves (SSE).
    Bvh4Cpu,
}

impl TinyLayout {
    /// Children per node.
    pub fn width(self) -> u32 {
        match self {
            TinyLayout::Bvh8Cpu => 8,
            TinyLayout::Bvh4Cpu => 4,
        }
    }

    /// tinybvh's class name.
    pub fn name(self) -> &'static str {
        match self {
            TinyLayout::Bvh8Cpu => "BVH8_CPU",
            TinyLayout::Bvh4Cpu => "BVH4_CPU",
        }
    }
}

/// tinybvh's far value: its "no hit yet" distance, and the longest ray it is handed.
const FAR: f32 = 1e30;

/// Entries of the fixed node stack in tinybvh's `BVH8_CPU` and `BVH4_CPU` walks, which do
/// not check it: a ray that needs more overwrites the walk's own stack frame.
const STACK: u32 = 256;

/// A tinybvh BVH over triangles; primitive IDs are indices into the slice it was built from.
pub struct TinyBvh {
    raw: *mut c_void,
    layout: TinyLayout,
    /// For each triangle tinybvh holds, its index in the caller's slice (the finite ones).
    ids: Vec<u32>,
    /// The vertices tinybvh was built from, kept alive with it: its BVH keeps a pointer.
    _vertices: Vec<Vec4>,
}

// SAFETY: after its build a tinybvh BVH is only read; `Intersect` and `IsOccluded` are `const`
// and keep their state on the caller's stack, so any number of threads may query one.
unsafe impl Send for TinyBvh {}
unsafe impl Sync for TinyBvh {}

impl Drop for TinyBvh {
    fn drop(&mut self) {
        if self.raw.is_null() {
            return;
        }
        // SAFETY: `raw` came from the matching build and is freed once.
        unsafe {
            match self.layout {
                TinyLayout::Bvh8Cpu => quiver_tinybvh8_free(self.raw),
                TinyLayout::Bvh4Cpu => quiver_tinybvh4_free(self.raw),
            }
        }
    }
}

/// A tinybvh tree too deep for tinybvh's walk: a ray may need `need` stack entries, and the
/// walk has a fixed 256 and does not check them (so it would write past them).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TooDeep {
    /// The layout built.
    pub layout: TinyLayout,
    /// Levels of inner nodes on the deepest path.
    pub depth: u32,
    /// Stack entries a ray may need.
    pub need: u32,
}

impl std::fmt::Display for TooDeep {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "tinybvh {}: the tree is {} levels deep, so a ray may need {} stack entries, and \
             tinybvh's walk has {STACK} and does not check them",
            self.layout.name(),
            self.depth,
            self.need
        )
    }
}

impl std::error::Error for TooDeep {}

impl TinyBvh {
    /// Builds `layout` over the finite ones of `tris` with tinybvh's default builder (binned
    /// SAH on its own threads, all hardware threads above 50,000 triangles; not the rayon
    /// pool). An error when the tree is so deep that a ray could overflow the walk's fixed
    /// 256-entry stack (each inner level may push `width − 1` entries and the last a full
    /// node's `width`), which tinybvh does not check and which would corrupt memory: SPD's
    /// tetra10 is such a tree.
    ///
    /// # Panics
    /// If there are more than `u32::MAX / 3` triangles, or tinybvh cannot allocate.
    ///
    /// # Errors
    /// [`TooDeep`] for a tree a ray could overflow the walk's stack in.
    pub fn new(tris: &[Triangle], layout: TinyLayout) -> Result<TinyBvh, TooDeep> {
        let ids: Vec<u32> = (0..tris.len() as u32)
            .filter(|&i| tris[i as usize].v.iter().all(|p| p.is_finite()))
            .collect();
        assert!(
            ids.len() <= (u32::MAX / 3) as usize,
            "too many triangles for tinybvh"
        );
        let vertices: Vec<Vec4> = ids
            .iter()
            .flat_map(|&i| tris[i as usize].v)
            .map(|p| Vec4([p.x, p.y, p.z, 0.0]))
            .collect();
        // tinybvh has no empty BVH: with nothing to hold, every ray misses without asking it.
        let raw = if ids.is_empty() {
            std::ptr::null_mut()
        } else {
            let v = vertices.as_ptr().cast::<f32>();
            let n = ids.len() as u32;
            // SAFETY: `v` points at `3n` 16-byte-aligned vectors that outlive the BVH.
            let raw = unsafe {
                match layout {
                    TinyLayout::Bvh8Cpu => quiver_tinybvh8_build(v, n),
                    TinyLayout::Bvh4Cpu => quiver_tinybvh4_build(v, n),
                }
            };
            assert!(!raw.is_null(), "tinybvh: out of memory");
            raw
        };
        let bvh = TinyBvh {
            raw,
            layout,
            ids,
            _vertices: vertices,
        };
        let depth = bvh.depth();
        let w = layout.width();
        let need = (w - 1) * depth.saturating_sub(1) + w;
        if need > STACK {
            return Err(TooDeep {
                layout,
                depth,
                need,
            });
        }
        Ok(bvh)
    }

    /// Levels of inner nodes on the deepest path of the wide tree (0 for none or a root
    /// leaf).
    pub fn depth(&self) -> u32 {
        if self.raw.is_null() {
            return 0;
        }
        // SAFETY: `raw` is a live BVH of this layout.
        unsafe {
            match self.layout {
                TinyLayout::Bvh8Cpu => quiver_tinybvh8_depth(self.raw),
                TinyLayout::Bvh4Cpu => quiver_tinybvh4_depth(self.raw),
            }
        }
    }

    /// Which layout this is.
    pub fn layout(&self) -> TinyLayout {
        self.layout
    }

    /// The ray as tinybvh takes it, `None` for one it must not see (NaN) or one that is
    /// empty; and the `t_min` to add back.
    #[inline]
    fn shim_ray(&self, ray: &Ray) -> Option<(ShimRay, f32)> {
        if self.raw.is_null() {
            return None;
        }
        let o = ray.origin + ray.dir * ray.t_min;
        let t_max = (ray.t_max - ray.t_min).min(FAR);
        let ok = o.is_finite() && ray.dir.is_finite() && t_max >= 0.0;
        ok.then_some((
            ShimRay {
                ox: o.x,
                oy: o.y,
                oz: o.z,
                dx: ray.dir.x,
                dy: ray.dir.y,
                dz: ray.dir.z,
                t_max,
            },
            ray.t_min,
        ))
    }

    /// The nearest hit (`Intersect`) as (triangle index, t).
    #[inline]
    pub fn closest_hit(&self, ray: &Ray) -> Option<(u32, f32)> {
        let (r, t_min) = self.shim_ray(ray)?;
        let (mut t, mut prim) = (0.0f32, 0u32);
        // SAFETY: `raw` is a live BVH of this layout; the out-pointers are local.
        let hit = unsafe {
            match self.layout {
                TinyLayout::Bvh8Cpu => quiver_tinybvh8_intersect(self.raw, &r, &mut t, &mut prim),
                TinyLayout::Bvh4Cpu => quiver_tinybvh4_intersect(self.raw, &r, &mut t, &mut prim),
            }
        };
        (hit != 0).then(|| (self.ids[prim as usize], t + t_min))
    }

    /// Whether anything lies on the ray (`IsOccluded`).
    #[inline]
    pub fn any_hit(&self, ray: &Ray) -> bool {
        let Some((r, _)) = self.shim_ray(ray) else {
            return false;
        };
        // SAFETY: as in `closest_hit`.
        unsafe {
            match self.layout {
                TinyLayout::Bvh8Cpu => quiver_tinybvh8_occluded(self.raw, &r) != 0,
                TinyLayout::Bvh4Cpu => quiver_tinybvh4_occluded(self.raw, &r) != 0,
            }
        }
    }

    /// Bytes of the node and leaf array the traversal reads (nodes and four-triangle leaves
    /// interleaved, in 64-byte blocks): `(used, allocated)`. The binary and wide BVHs the
    /// layout was converted from, which tinybvh keeps inside the object but does not read
    /// while tracing, are not counted.
    pub fn bytes(&self) -> (usize, usize) {
        if self.raw.is_null() {
            return (0, 0);
        }
        let (mut used, mut allocated) = (0u64, 0u64);
        // SAFETY: as in `closest_hit`.
        unsafe {
            match self.layout {
                TinyLayout::Bvh8Cpu => quiver_tinybvh8_bytes(self.raw, &mut used, &mut allocated),
                TinyLayout::Bvh4Cpu => quiver_tinybvh4_bytes(self.raw, &mut used, &mut allocated),
            }
        }
        (used as usize, allocated as usize)
    }

    /// How many of `rays` hit (closest hit, or any hit with `any`), traced on the current
    /// thread pool in the tasks the other engines' timed loops use
    /// ([`crate::measure::count_hits`]).
    pub fn count_hits(&self, rays: &[Ray], any: bool) -> usize {
        if any {
            crate::measure::count_hits(rays, |r| self.any_hit(r))
        } else {
            crate::measure::count_hits(rays, |r| self.closest_hit(r).is_some())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rays;
    use glam::Vec3A;
    use quiver_rt::traverse::reference;
    use quiver_scenes::Scene;
    use rayon::prelude::*;

    /// Rays where tinybvh and the brute-force reference differ: another primitive, a t off by
    /// more than 1e-4 relative, hit against miss, or any-hit answers that differ.
    fn disagreements(bvh: &TinyBvh, tris: &[Triangle], rays: &[Ray]) -> (usize, usize) {
        let closest = rays
            .par_iter()
            .filter(|r| {
                let e = bvh.closest_hit(r);
                let q = reference::closest_hit(tris, r).map(|h| (h.prim, h.t));
                !match (e, q) {
                    (None, None) => true,
                    (Some((ep, et)), Some((qp, qt))) => {
                        ep == qp && (et - qt).abs() <= 1e-4 * qt.abs().max(et.abs())
                    }
                    _ => false,
                }
            })
            .count();
        let any = rays
            .par_iter()
            .filter(|r| bvh.any_hit(r) != reference::any_hit(tris, r))
            .count();
        (closest, any)
    }

    fn check_scene(name: &str, layout: TinyLayout) {
        let s = Scene::load(name).unwrap();
        let tris = s.triangles();
        let bvh = TinyBvh::new(&tris, layout).unwrap();
        println!("{name} {}: depth {}", layout.name(), bvh.depth());
        let camera = rays::camera_rays(&s.camera, 128);
        let mut lights: Vec<_> = s.lights.iter().map(|l| l.pos).collect();
        lights.push(s.camera.from);
        let shadow = rays::shadow_rays(&quiver_rt::Bvh::new(&tris), &camera, &lights);
        for (kind, set) in [
            ("random", rays::random_rays(&s.bounds(), 20_000, 5)),
            ("shadow", shadow),
            ("camera", camera),
        ] {
            let hits = set.iter().filter(|r| bvh.closest_hit(r).is_some()).count();
            let (closest, any) = disagreements(&bvh, &tris, &set);
            println!(
                "{name} {} {kind}: {} rays, {hits} hits, {closest} closest / {any} any-hit disagreements",
                layout.name(),
                set.len()
            );
            assert!(hits > 0, "{name} {kind}: no ray hits anything");
            let allowed = set.len() / 1000;
            assert!(closest <= allowed && any <= allowed, "{name} {kind}");
        }
        let (used, allocated) = bvh.bytes();
        assert!(used > 0 && used <= allocated && used % 64 == 0);
    }

    #[test]
    fn tinybvh_agrees_with_reference_on_tetra6() {
        check_scene("tetra6", TinyLayout::Bvh8Cpu);
        check_scene("tetra6", TinyLayout::Bvh4Cpu);
    }

    #[test]
    fn tinybvh_agrees_with_reference_on_soup() {
        check_scene("soup2000", TinyLayout::Bvh8Cpu);
        check_scene("soup2000", TinyLayout::Bvh4Cpu);
    }

    #[test]
    fn tinybvh_above_its_threaded_build_threshold_agrees_too() {
        // Above tinybvh's 50,000-triangle threshold its build runs on threads of its own.
        check_scene("tetra8", TinyLayout::Bvh8Cpu);
    }

    #[test]
    fn tinybvh_refuses_trees_deeper_than_its_stack() {
        // tetra10's tinybvh tree overflowed the walk's stack (a segfault in `quiver bench`):
        // the build now says so instead.
        let tris = Scene::load("tetra10").unwrap().triangles();
        let e = TinyBvh::new(&tris, TinyLayout::Bvh8Cpu)
            .err()
            .expect("refused");
        println!("{e}");
        assert!(e.need > 256, "{e}");
        assert!(
            e.to_string()
                .contains("stack entries, and tinybvh's walk has 256"),
            "{e}"
        );
    }

    #[test]
    fn tinybvh_segments_empty_input_and_non_finite_triangles() {
        let t = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
        let bad = Triangle::new(Vec3A::splat(f32::NAN), Vec3A::X, Vec3A::Y);
        for layout in [TinyLayout::Bvh8Cpu, TinyLayout::Bvh4Cpu] {
            let bvh = TinyBvh::new(&[bad, t], layout).unwrap();
            let down =
                |t_min, t_max| Ray::segment(Vec3A::new(0.25, 0.25, 2.0), -Vec3A::Z, t_min, t_max);
            // The plane is at t = 2: inside [1, 3], not inside [0, 1.5] or [2.5, 9].
            let (prim, t) = bvh.closest_hit(&down(1.0, 3.0)).unwrap();
            assert!(prim == 1 && (t - 2.0).abs() < 1e-6, "{prim} {t}");
            assert_eq!(bvh.closest_hit(&down(0.0, 1.5)), None);
            assert_eq!(bvh.closest_hit(&down(2.5, 9.0)), None);
            assert!(bvh.any_hit(&down(1.0, 3.0)) && !bvh.any_hit(&down(0.0, 1.5)));
            let nan = Ray::new(Vec3A::splat(f32::NAN), -Vec3A::Z);
            assert_eq!(bvh.closest_hit(&nan), None);
            assert!(!bvh.any_hit(&nan));
            let empty = TinyBvh::new(&[bad], layout).unwrap();
            assert_eq!(empty.closest_hit(&down(0.0, 9.0)), None);
            assert_eq!(empty.bytes(), (0, 0));
        }
    }
}
