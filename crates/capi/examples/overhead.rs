//! The C API's cost per ray against the Rust call it wraps: the same BVH and the same rays,
//! traced one at a time through `Bvh::closest_hit` / `any_hit` and through `qv_bvh_closest_hit`
//! / `qv_bvh_any_hit` (called as C calls them), in interleaved rounds; medians and their ratio.
//!
//! `cargo run --release -p quiver-capi --example overhead [GRID] [RES] [ROUNDS]`: a height
//! field of GRID² quads (two triangles each) seen by a RES² camera (eye rays) and by rays to
//! one light from every eye hit (shadow rays).

use quiver_capi::{
    qv_bvh_any_hit, qv_bvh_build_indexed, qv_bvh_closest_hit, qv_bvh_free, QvBvh, QvHit, QvRay,
    QvStatus,
};
use quiver_rt::glam::Vec3A;
use quiver_rt::{Bvh, Ray, RayQuery};
use std::hint::black_box;
use std::time::Instant;

/// A rolling height field over [0, 1]², `n` quads a side.
fn terrain(n: usize) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let h =
        |x: f32, y: f32| 0.05 * ((9.0 * x).sin() * (7.0 * y).cos() + (23.0 * (x + y)).sin() * 0.3);
    let mut v = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (i as f32 / n as f32, j as f32 / n as f32);
            v.push([x, y, h(x, y)]);
        }
    }
    let at = |i: usize, j: usize| (j * (n + 1) + i) as u32;
    let mut t = Vec::new();
    for j in 0..n {
        for i in 0..n {
            t.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            t.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    (v, t)
}

/// A camera above the field looking across it, `res`² rays in 8 × 8 tiles.
fn eye_rays(res: usize) -> Vec<Ray> {
    let eye = Vec3A::new(0.5, -0.4, 0.6);
    let fwd = (Vec3A::new(0.5, 0.5, 0.0) - eye).normalize();
    let right = fwd.cross(Vec3A::Z).normalize();
    let up = right.cross(fwd);
    let mut rays = Vec::with_capacity(res * res);
    for ty in (0..res).step_by(8) {
        for tx in (0..res).step_by(8) {
            for y in ty..(ty + 8).min(res) {
                for x in tx..(tx + 8).min(res) {
                    let sx = (x as f32 + 0.5) / res as f32 * 2.0 - 1.0;
                    let sy = 1.0 - (y as f32 + 0.5) / res as f32 * 2.0;
                    rays.push(Ray::new(eye, fwd + 0.6 * (sx * right + sy * up)));
                }
            }
        }
    }
    rays
}

fn to_c(r: &Ray) -> QvRay {
    QvRay {
        org: r.origin.into(),
        t_min: r.t_min,
        dir: r.dir.into(),
        t_max: r.t_max,
        mask: r.mask,
        time: r.time,
    }
}

fn median(mut x: Vec<f64>) -> f64 {
    x.sort_by(f64::total_cmp);
    x[x.len() / 2]
}

fn main() {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse().unwrap())
        .collect();
    let (grid, res, rounds) = (
        *args.first().unwrap_or(&400),
        *args.get(1).unwrap_or(&1024),
        *args.get(2).unwrap_or(&7),
    );
    let (verts, tris) = terrain(grid);
    let bvh = Bvh::from_mesh(&verts, &tris).unwrap();
    let mut handle: *mut QvBvh = std::ptr::null_mut();
    // SAFETY: the buffers are live for the call and hold the counts given, packed.
    let status = unsafe {
        qv_bvh_build_indexed(
            verts.as_ptr().cast(),
            verts.len(),
            12,
            tris.as_ptr().cast(),
            tris.len(),
            12,
            &mut handle,
        )
    };
    assert_eq!(status, QvStatus::Ok);
    let eye = eye_rays(res);
    let light = Vec3A::new(2.0, 3.0, 4.0);
    let shadow: Vec<Ray> = eye
        .iter()
        .filter_map(|r| {
            let h = bvh.closest_hit(r)?;
            let p = r.origin + h.t * r.dir;
            Some(Ray::segment(p, light - p, 1e-3, 1.0))
        })
        .collect();
    println!(
        "{} triangles, {} eye rays ({res}²), {} shadow rays, {rounds} rounds",
        tris.len(),
        eye.len(),
        shadow.len()
    );
    for (name, rays) in [("eye", &eye), ("shadow", &shadow)] {
        let c_rays: Vec<QvRay> = rays.iter().map(to_c).collect();
        let (mut rust_c, mut capi_c, mut rust_a, mut capi_a) = (vec![], vec![], vec![], vec![]);
        for _ in 0..rounds {
            let t = Instant::now();
            for r in rays.iter() {
                black_box(bvh.closest_hit(black_box(r)));
            }
            rust_c.push(t.elapsed().as_secs_f64());
            let t = Instant::now();
            let mut hit = QvHit {
                t: 0.0,
                u: 0.0,
                v: 0.0,
                prim: 0,
                geometry: 0,
                instance: 0,
            };
            for r in c_rays.iter() {
                // SAFETY: a live handle, one readable ray, one writable hit.
                black_box(unsafe { qv_bvh_closest_hit(handle, black_box(r), &mut hit) });
                black_box(&hit);
            }
            capi_c.push(t.elapsed().as_secs_f64());
            let t = Instant::now();
            for r in rays.iter() {
                black_box(bvh.any_hit(black_box(r)));
            }
            rust_a.push(t.elapsed().as_secs_f64());
            let t = Instant::now();
            let mut occ = 0;
            for r in c_rays.iter() {
                // SAFETY: a live handle, one readable ray, one writable int.
                black_box(unsafe { qv_bvh_any_hit(handle, black_box(r), &mut occ) });
                black_box(occ);
            }
            capi_a.push(t.elapsed().as_secs_f64());
        }
        let n = rays.len() as f64 / 1e6;
        let (rc, cc, ra, ca) = (
            median(rust_c),
            median(capi_c),
            median(rust_a),
            median(capi_a),
        );
        println!(
            "{name:6} closest: rust {:.2} Mrays/s, C API {:.2} Mrays/s, C/rust time {:.3}",
            n / rc,
            n / cc,
            cc / rc
        );
        println!(
            "{name:6} any:     rust {:.2} Mrays/s, C API {:.2} Mrays/s, C/rust time {:.3}",
            n / ra,
            n / ca,
            ca / ra
        );
    }
    // SAFETY: the handle from the build, freed once.
    unsafe { qv_bvh_free(handle) };
}
