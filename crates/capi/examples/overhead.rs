//! The C API's cost per ray against the Rust call it wraps: one BVH built from the same
//! vertex and index buffers both ways, the same rays, traced one at a time through
//! `Bvh::closest_hit` / `any_hit` and through `qv_bvh_closest_hit` / `qv_bvh_any_hit` (called
//! as C calls them), in interleaved rounds; medians and their ratio.
//!
//! `cargo run --release -p quiver-capi --example overhead [SCENE ...]`: each SCENE (a
//! quiver-scenes name, default `teapot40 tetra8 lattice6 balls4`) with the bench's ray kinds,
//! eye rays of a 1024² camera in 8 × 8 tiles (`RES`), shadow rays to the first light, diffuse
//! bounce rays and incoherent rays; `ROUNDS` rounds (default 7).
//!
//! Two Rust baselines: the call on rays already made (`Ray`s in memory), and a Rust caller
//! holding the same 40-byte ray records C passes, making each `Ray` and writing each hit
//! record as the C API does: the ratio to the second is what the API itself adds.
//!
//! The Rust and the C loop each call their own copy of the kernel (a generic kernel is
//! compiled into every crate that uses it), so the times also differ by where the linker put
//! each copy. Instructions do not: under callgrind, `--toggle-collect='overhead::rust_*'` and
//! `'overhead::c_*'` with `ROUNDS=1` count each loop's instructions, the API's own cost.

use quiver_capi::{
    qv_bvh_any_hit, qv_bvh_build_indexed, qv_bvh_closest_hit, qv_bvh_free, QvBvh, QvHit, QvRay,
    QvStatus,
};
use quiver_lab::rays;
use quiver_rt::{Bvh, Ray, RayQuery};
use quiver_scenes::scene::tessellate::DEFAULT_RESOLUTION;
use quiver_scenes::Scene;
use std::hint::black_box;
use std::time::Instant;

fn env(name: &str, default: usize) -> usize {
    std::env::var(name).map_or(default, |v| v.parse().expect(name))
}

fn main() {
    let mut names: Vec<String> = std::env::args().skip(1).collect();
    if names.is_empty() {
        names = ["teapot40", "tetra8", "lattice6", "balls4"]
            .map(String::from)
            .to_vec();
    }
    let (res, rounds) = (env("RES", 1024), env("ROUNDS", 7));
    println!("C/Rust time per ray, medians of {rounds} interleaved rounds, {res}² eye rays");
    for name in &names {
        scene(name, res, rounds);
    }
}

/// One scene's rows: closest and any hit for each ray kind.
fn scene(name: &str, res: usize, rounds: usize) {
    let scene = Scene::load(name)
        .expect("scene")
        .into_patches(DEFAULT_RESOLUTION);
    let tris = scene.triangles();
    let verts: Vec<[f32; 3]> = tris.iter().flat_map(|t| t.v.map(|v| v.into())).collect();
    let index: Vec<[u32; 3]> = (0..tris.len() as u32)
        .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
        .collect();
    let bvh = Bvh::from_mesh(&verts, &index).expect("build");
    let mut handle: *mut QvBvh = std::ptr::null_mut();
    // SAFETY: the buffers are live for the call and hold the counts given, packed.
    let status = unsafe {
        qv_bvh_build_indexed(
            verts.as_ptr().cast(),
            verts.len(),
            12,
            index.as_ptr().cast(),
            index.len(),
            12,
            &mut handle,
        )
    };
    assert_eq!(status, QvStatus::Ok);
    let eye = rays::camera_tiles(&scene.camera, res, 8);
    let light = scene.lights.first().map_or(scene.camera.from, |l| l.pos);
    let kinds = [
        ("shadow", rays::shadow_rays(&bvh, &eye, &[light])),
        ("diffuse", rays::diffuse_rays(&bvh, &tris, &eye, 7)),
        (
            "incoherent",
            rays::random_rays(&scene.bounds(), eye.len() / 4, 11),
        ),
        ("eye", eye),
    ];
    println!("{name} ({} triangles)", tris.len());
    for (kind, rays) in &kinds {
        let c_rays: Vec<QvRay> = rays.iter().map(to_c).collect();
        let mut times = [(); 6].map(|_| Vec::new());
        for _ in 0..rounds {
            let loops: [&dyn Fn(); 6] = [
                &|| rust_closest(&bvh, rays),
                &|| rust_closest_records(&bvh, &c_rays),
                &|| c_closest(handle, &c_rays),
                &|| rust_any(&bvh, rays),
                &|| rust_any_records(&bvh, &c_rays),
                &|| c_any(handle, &c_rays),
            ];
            for (t, f) in times.iter_mut().zip(loops) {
                let start = Instant::now();
                f();
                t.push(start.elapsed().as_secs_f64());
            }
        }
        let [rc, rrc, cc, ra, rra, ca] = times.map(median);
        let rate = |s: f64| rays.len() as f64 / s / 1e6;
        println!(
            "  {kind:10} {:>8} rays  closest: Rust {:6.2} records {:6.2} C {:6.2} Mrays/s, \
             C/Rust {:.3} C/records {:.3}   any: Rust {:6.2} records {:6.2} C {:6.2} Mrays/s, \
             C/Rust {:.3} C/records {:.3}",
            rays.len(),
            rate(rc),
            rate(rrc),
            rate(cc),
            cc / rc,
            cc / rrc,
            rate(ra),
            rate(rra),
            rate(ca),
            ca / ra,
            ca / rra
        );
    }
    // SAFETY: the handle from the build, freed once.
    unsafe { qv_bvh_free(handle) };
}

#[inline(never)]
fn rust_closest(bvh: &Bvh, rays: &[Ray]) {
    for r in rays {
        black_box(bvh.closest_hit(black_box(r)));
    }
}

#[inline(never)]
fn rust_any(bvh: &Bvh, rays: &[Ray]) {
    for r in rays {
        black_box(bvh.any_hit(black_box(r)));
    }
}

/// A ray record as a Rust caller holding C's records makes it.
#[inline]
fn ray_of(r: &QvRay) -> Ray {
    Ray::segment(r.org.into(), r.dir.into(), r.t_min, r.t_max)
        .with_mask(r.mask)
        .with_time(r.time)
}

#[inline(never)]
fn rust_closest_records(bvh: &Bvh, rays: &[QvRay]) {
    for r in rays {
        let hit = match bvh.closest_hit(&ray_of(black_box(r))) {
            Some(h) => QvHit {
                t: h.t,
                u: h.u,
                v: h.v,
                prim: h.prim,
                ..miss()
            },
            None => miss(),
        };
        black_box(&hit);
    }
}

#[inline(never)]
fn rust_any_records(bvh: &Bvh, rays: &[QvRay]) {
    for r in rays {
        black_box(i32::from(bvh.any_hit(&ray_of(black_box(r)))));
    }
}

fn miss() -> QvHit {
    QvHit {
        t: f32::INFINITY,
        u: 0.0,
        v: 0.0,
        prim: u32::MAX,
        geometry: u32::MAX,
        instance: u32::MAX,
    }
}

#[inline(never)]
fn c_closest(handle: *const QvBvh, rays: &[QvRay]) {
    let mut hit = miss();
    for r in rays {
        // SAFETY: a live handle, one readable ray, one writable hit.
        black_box(unsafe { qv_bvh_closest_hit(handle, black_box(r), &mut hit) });
        black_box(&hit);
    }
}

#[inline(never)]
fn c_any(handle: *const QvBvh, rays: &[QvRay]) {
    let mut occluded = 0;
    for r in rays {
        // SAFETY: a live handle, one readable ray, one writable int.
        black_box(unsafe { qv_bvh_any_hit(handle, black_box(r), &mut occluded) });
        black_box(occluded);
    }
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
