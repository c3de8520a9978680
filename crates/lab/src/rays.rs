//! Ray workloads shared by tests, benchmarks and the CLI: seeded incoherent rays, camera
//! rays, and the secondary rays a renderer shoots from the eye rays' hits (shadow, mirror and
//! diffuse bounce rays).
//!
//! ```
//! use quiver_lab::rays;
//! use quiver_scenes::Scene;
//! let s = Scene::load("tetra3").unwrap();
//! assert_eq!(rays::camera_rays(&s.camera, 8).len(), 64);
//! assert_eq!(rays::random_rays(&s.bounds(), 100, 1).len(), 100);
//! ```

use glam::Vec3A;
use quiver_rt::geometry::offset_ray_origin;
use quiver_rt::{Aabb, Hit, Ray, RayQuery};
use quiver_scenes::rng::Rng;
use quiver_scenes::scene::Camera;
use rayon::prelude::*;

/// `n` incoherent rays: origins uniform in `bounds` grown by half its size on every side,
/// directions uniform on the sphere. Many start inside the geometry, as secondary rays do.
pub fn random_rays(bounds: &Aabb, n: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Rng::new(seed);
    let (lo, hi) = if bounds.is_empty() {
        (Vec3A::splat(-1.0), Vec3A::ONE)
    } else {
        let pad = bounds.extent() * 0.5;
        (bounds.min - pad, bounds.max + pad)
    };
    (0..n)
        .map(|_| Ray::new(rng.in_box(lo, hi), rng.unit_vector()))
        .collect()
}

/// `rays`, each shot at its own time in the shutter (motion blur): ray `i` of `n` at
/// `(7919 i mod n) / n`, a stratified sequence that puts neighbouring rays at distant times,
/// as a renderer's pixel samples are.
///
/// ```
/// use quiver_rt::{glam::Vec3A, Ray};
/// let r = quiver_lab::rays::timed(vec![Ray::new(Vec3A::ZERO, Vec3A::Z); 4]);
/// assert_eq!(r.iter().map(|r| r.time).collect::<Vec<_>>(), [0.0, 0.75, 0.5, 0.25]);
/// ```
pub fn timed(rays: Vec<Ray>) -> Vec<Ray> {
    let n = rays.len().max(1);
    rays.into_iter()
        .enumerate()
        .map(|(i, r)| r.with_time(((i * 7919) % n) as f32 / n as f32))
        .collect()
}

/// `res × res` eye rays through pixel centres, row by row from the top.
pub fn camera_rays(camera: &Camera, res: usize) -> Vec<Ray> {
    let step = 2.0 / res as f32;
    let view = camera.view();
    (0..res * res)
        .map(|i| {
            let (x, y) = (i % res, i / res);
            view.ray(
                -1.0 + (x as f32 + 0.5) * step,
                1.0 - (y as f32 + 0.5) * step,
            )
        })
        .collect()
}

/// The same eye rays as [`camera_rays`], ordered tile by tile: `tile × tile` pixel squares,
/// left to right, top to bottom, each square row by row (partial squares at the right and
/// bottom edges when `tile` does not divide `res`). Consecutive runs of `tile²` rays are
/// coherent packets.
///
/// ```
/// use quiver_lab::rays;
/// use quiver_scenes::Scene;
/// let s = Scene::load("tetra3").unwrap();
/// let (rows, tiles) = (rays::camera_rays(&s.camera, 16), rays::camera_tiles(&s.camera, 16, 8));
/// assert_eq!(tiles[8], rows[16]); // the ninth ray of the first tile starts its second row
/// ```
pub fn camera_tiles(camera: &Camera, res: usize, tile: usize) -> Vec<Ray> {
    let rows = camera_rays(camera, res);
    let mut out = Vec::with_capacity(rows.len());
    for ty in (0..res).step_by(tile) {
        for tx in (0..res).step_by(tile) {
            for y in ty..(ty + tile).min(res) {
                out.extend_from_slice(&rows[y * res + tx..y * res + (tx + tile).min(res)]);
            }
        }
    }
    out
}

/// Shadow rays from every point where an `eye` ray hits `bvh` toward each light in turn (all
/// rays toward the first light, then the second, …, keeping the eye rays' order): segments
/// from the hit point over `[1e-4, 1 - 1e-4]` of the way to the light.
///
/// ```
/// use glam::Vec3A;
/// use quiver_rt::{Bvh, RayQuery};
/// use quiver_lab::rays;
/// use quiver_scenes::Scene;
/// let s = Scene::load("tetra3").unwrap();
/// let bvh = Bvh::new(&s.triangles());
/// let eye = rays::camera_rays(&s.camera, 16);
/// let hits = eye.iter().filter(|r| bvh.closest_hit(r).is_some()).count();
/// assert_eq!(rays::shadow_rays(&bvh, &eye, &[Vec3A::Z, Vec3A::X]).len(), 2 * hits);
/// ```
pub fn shadow_rays<Q: RayQuery<Hit = Hit> + Sync>(
    bvh: &Q,
    eye: &[Ray],
    lights: &[Vec3A],
) -> Vec<Ray> {
    let points: Vec<Vec3A> = eye
        .par_iter()
        .filter_map(|r| bvh.closest_hit(r).map(|h| r.at(h.t)))
        .collect();
    lights
        .iter()
        .flat_map(|&l| {
            points
                .iter()
                .map(move |&p| Ray::segment(p, l - p, 1e-4, 1.0 - 1e-4))
        })
        .collect()
}

/// Mirror reflection rays from every point where an `eye` ray hits `bvh` (built over `tris`):
/// the eye direction reflected about the hit triangle's plane, starting a relative epsilon
/// off the surface on the side the eye ray came from. The secondary rays of a renderer's
/// mirrors, in the eye rays' order.
///
/// ```
/// use quiver_rt::{Bvh, RayQuery};
/// use quiver_lab::rays;
/// use quiver_scenes::Scene;
/// let tris = Scene::load("tetra3").unwrap().triangles();
/// let s = Scene::load("tetra3").unwrap();
/// let bvh = Bvh::new(&tris);
/// let eye = rays::camera_rays(&s.camera, 16);
/// let hits = eye.iter().filter(|r| bvh.closest_hit(r).is_some()).count();
/// assert_eq!(rays::reflection_rays(&bvh, &tris, &eye).len(), hits);
/// ```
pub fn reflection_rays<Q: RayQuery<Hit = Hit> + Sync>(
    bvh: &Q,
    tris: &[quiver_rt::Triangle],
    eye: &[Ray],
) -> Vec<Ray> {
    eye.par_iter()
        .filter_map(|r| {
            let h = bvh.closest_hit(r)?;
            let t = &tris[h.prim as usize];
            let n = (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).normalize_or_zero();
            let d = r.dir - 2.0 * r.dir.dot(n) * n;
            let facing = if r.dir.dot(n) < 0.0 { n } else { -n };
            let p = r.at(h.t);
            let eps = 1e-4 * (1.0 + p.abs().max_element());
            Some(Ray::new(p + facing * eps, d))
        })
        .collect()
}

/// Diffuse bounce rays from every point where an `eye` ray hits `bvh` (built over `tris`):
/// one direction drawn from the cosine-weighted hemisphere about the hit triangle's geometric
/// normal, on the side the eye ray came from, starting at the hit point moved off the surface
/// by [`offset_ray_origin`]. The first bounce of a path tracer's diffuse surfaces, in the eye
/// rays' order. Each ray's direction comes from a generator seeded by `seed` and the eye ray's
/// index, so the set is the same on any thread count.
///
/// ```
/// use quiver_rt::{Bvh, RayQuery};
/// use quiver_lab::rays;
/// use quiver_scenes::Scene;
/// let s = Scene::load("tetra3").unwrap();
/// let tris = s.triangles();
/// let bvh = Bvh::new(&tris);
/// let eye = rays::camera_rays(&s.camera, 16);
/// let bounce = rays::diffuse_rays(&bvh, &tris, &eye, 5);
/// let hits = eye.iter().filter(|r| bvh.closest_hit(r).is_some()).count();
/// assert_eq!(bounce.len(), hits);
/// assert_eq!(bounce, rays::diffuse_rays(&bvh, &tris, &eye, 5));
/// ```
pub fn diffuse_rays<Q: RayQuery<Hit = Hit> + Sync>(
    bvh: &Q,
    tris: &[quiver_rt::Triangle],
    eye: &[Ray],
    seed: u64,
) -> Vec<Ray> {
    eye.par_iter()
        .enumerate()
        .filter_map(|(i, r)| {
            let h = bvh.closest_hit(r)?;
            let t = &tris[h.prim as usize];
            let n = (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).normalize_or_zero();
            if n == Vec3A::ZERO {
                return None;
            }
            let n = if r.dir.dot(n) < 0.0 { n } else { -n };
            // One generator per eye ray, its seed spread by SplitMix's first step.
            let mut rng = Rng::new(seed ^ (i as u64).wrapping_mul(0xD1B5_4A32_D192_ED03));
            Some(Ray::new(
                offset_ray_origin(r.at(h.t), n),
                cosine_about(n, rng.f32(), rng.f32()),
            ))
        })
        .collect()
}

/// The direction for `(u1, u2)` in `[0, 1)²` under the cosine-weighted distribution on the
/// hemisphere about the unit vector `n` (Malley's method: a uniform point on the disc lifted
/// to the hemisphere).
fn cosine_about(n: Vec3A, u1: f32, u2: f32) -> Vec3A {
    let r = u1.sqrt();
    let phi = std::f32::consts::TAU * u2;
    let z = (1.0 - u1).max(0.0).sqrt();
    // An orthonormal frame about n (Duff et al., "Building an Orthonormal Basis, Revisited").
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let x = Vec3A::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let y = Vec3A::new(b, sign + n.y * n.y * a, -n.y);
    (x * (r * phi.cos()) + y * (r * phi.sin()) + n * z).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cosine_directions_lie_in_the_hemisphere_with_mean_cosine_two_thirds() {
        // E[cos θ] under the cosine-weighted hemisphere is ∫cos²θ sinθ dθ / ∫cosθ sinθ dθ = 2/3.
        let mut rng = Rng::new(3);
        for n in [
            Vec3A::Z,
            -Vec3A::Z,
            Vec3A::new(0.3, -0.8, 0.1).normalize(),
            -Vec3A::X,
        ] {
            let k = 20_000;
            let mut sum = 0.0f64;
            for _ in 0..k {
                let d = cosine_about(n, rng.f32(), rng.f32());
                assert!((d.length() - 1.0).abs() < 1e-5, "{d}");
                let c = d.dot(n);
                assert!(c >= -1e-6, "{n} {d}");
                sum += c as f64;
            }
            let mean = sum / k as f64;
            // The mean of 20,000 draws of a variable of variance 1/18: within 0.01 of 2/3 by
            // more than five standard deviations (0.0017).
            assert!((mean - 2.0 / 3.0).abs() < 0.01, "{n}: {mean}");
        }
    }
}
