//! quiver's default kernel on a scene from `to_bin.py`, one thread: 1024² eye rays in 8x8
//! tiles, a shadow ray and a cosine bounce from every eye hit (see run.sh). Environment:
//! PROBE_SCENE (the .bin), PROBE_RES (1024), PROBE_REPS (5, medians printed in Mrays/s),
//! PROBE_MODE=count (one pass of each kind in `k_*`, for callgrind), PROBE_DUMP=FILE (the
//! rays, for the peers' harness).
use q::glam::Vec3A;
use q::{Bvh, Ray, RayQuery, Triangle};
use std::time::Instant;

fn read(path: &str) -> (Vec<Triangle>, [f32; 13]) {
    let b = std::fs::read(path).unwrap();
    let f = |i: usize| f32::from_le_bytes(b[i..i + 4].try_into().unwrap());
    let n = u32::from_le_bytes(b[0..4].try_into().unwrap()) as usize;
    let mut head = [0f32; 13];
    for (k, h) in head.iter_mut().enumerate() {
        *h = f(4 + 4 * k);
    }
    let base = 4 + 52;
    let tris = (0..n)
        .map(|t| {
            let v = |j: usize| {
                let o = base + 36 * t + 12 * j;
                Vec3A::new(f(o), f(o + 4), f(o + 8))
            };
            Triangle::new(v(0), v(1), v(2))
        })
        .collect();
    (tris, head)
}

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32) / (1u64 << 24) as f32
    }
}

fn eye_rays(h: &[f32; 13], res: usize) -> Vec<Ray> {
    let from = Vec3A::new(h[0], h[1], h[2]);
    let at = Vec3A::new(h[3], h[4], h[5]);
    let up = Vec3A::new(h[6], h[7], h[8]);
    let w = (at - from).normalize();
    let u = w.cross(up).normalize();
    let v = u.cross(w);
    let k = (h[9].to_radians() / 2.0).tan();
    let mut rays = Vec::with_capacity(res * res);
    for ty in (0..res).step_by(8) {
        for tx in (0..res).step_by(8) {
            for y in ty..(ty + 8).min(res) {
                for x in tx..(tx + 8).min(res) {
                    let sx = ((x as f32 + 0.5) / res as f32 * 2.0 - 1.0) * k;
                    let sy = (1.0 - (y as f32 + 0.5) / res as f32 * 2.0) * k;
                    rays.push(Ray::new(from, (w + u * sx + v * sy).normalize()));
                }
            }
        }
    }
    rays
}

/// Shadow rays to the light and cosine bounce rays from every eye hit.
fn secondary(
    bvh: &Bvh,
    tris: &[Triangle],
    eye: &[Ray],
    light: Vec3A,
    size: f32,
) -> (Vec<Ray>, Vec<Ray>) {
    let mut shadow = Vec::new();
    let mut diffuse = Vec::new();
    let mut rng = Rng(7);
    for r in eye {
        let Some(hit) = bvh.closest_hit(r) else {
            continue;
        };
        let t = &tris[hit.prim as usize];
        let p = r.origin + r.dir * hit.t;
        let mut n = (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).normalize_or_zero();
        if n.dot(r.dir) > 0.0 {
            n = -n;
        }
        let o = p + n * (size * 1e-5);
        let d = light - o;
        shadow.push(Ray {
            t_max: 1.0 - 1e-4,
            ..Ray::new(o, d)
        });
        let (a, b) = (rng.next(), rng.next());
        let (r1, phi) = (a.sqrt(), b * std::f32::consts::TAU);
        let tu = if n.x.abs() > 0.5 { Vec3A::Y } else { Vec3A::X }
            .cross(n)
            .normalize();
        let tv = n.cross(tu);
        let dir = tu * (r1 * phi.cos()) + tv * (r1 * phi.sin()) + n * (1.0 - a).max(0.0).sqrt();
        diffuse.push(Ray::new(o, dir.normalize()));
    }
    (shadow, diffuse)
}

#[inline(never)]
fn k_eye(b: &Bvh, r: &[Ray]) -> usize {
    r.iter().filter(|r| b.closest_hit(r).is_some()).count()
}
#[inline(never)]
fn k_shadow(b: &Bvh, r: &[Ray]) -> usize {
    r.iter().filter(|r| b.any_hit(r)).count()
}
#[inline(never)]
fn k_diffuse(b: &Bvh, r: &[Ray]) -> usize {
    r.iter().filter(|r| b.closest_hit(r).is_some()).count() + 1
}

fn main() {
    let scene = std::env::var("PROBE_SCENE").unwrap_or("data/interior.bin".into());
    let mode = std::env::var("PROBE_MODE").unwrap_or("time".into());
    let res: usize = std::env::var("PROBE_RES").map_or(1024, |v| v.parse().unwrap());
    let reps: usize = std::env::var("PROBE_REPS").map_or(5, |v| v.parse().unwrap());
    let (tris, h) = read(&scene);
    let bvh = Bvh::new(&tris);
    let lo = tris
        .iter()
        .fold(Vec3A::splat(f32::MAX), |m, t| m.min(t.v[0]));
    let hi = tris
        .iter()
        .fold(Vec3A::splat(f32::MIN), |m, t| m.max(t.v[0]));
    let size = (hi - lo).max_element();
    let eye = eye_rays(&h, res);
    let (shadow, diffuse) = secondary(&bvh, &tris, &eye, Vec3A::new(h[10], h[11], h[12]), size);
    if let Ok(path) = std::env::var("PROBE_DUMP") {
        let mut out = Vec::new();
        for set in [&eye, &shadow, &diffuse] {
            out.extend_from_slice(&(set.len() as u32).to_le_bytes());
        }
        for set in [&eye, &shadow, &diffuse] {
            for r in set.iter() {
                for x in [
                    r.origin.x, r.origin.y, r.origin.z, r.dir.x, r.dir.y, r.dir.z, r.t_min, r.t_max,
                ] {
                    out.extend_from_slice(&x.to_le_bytes());
                }
            }
        }
        std::fs::write(path, out).unwrap();
    }
    if mode == "count" {
        let a = k_eye(&bvh, &eye) + k_shadow(&bvh, &shadow) + k_diffuse(&bvh, &diffuse);
        println!(
            "answers {a} ({} eye, {} shadow, {} diffuse)",
            eye.len(),
            shadow.len(),
            diffuse.len()
        );
        return;
    }
    let kinds: [(&str, &[Ray], fn(&Bvh, &[Ray]) -> usize); 3] = [
        ("eye", &eye, k_eye),
        ("shadow", &shadow, k_shadow),
        ("diffuse", &diffuse, k_diffuse),
    ];
    let mut times = vec![Vec::new(); 3];
    for _ in 0..reps {
        for (i, (_, rays, k)) in kinds.iter().enumerate() {
            let s = Instant::now();
            std::hint::black_box(k(&bvh, rays));
            times[i].push(rays.len() as f64 / s.elapsed().as_secs_f64() / 1e6);
        }
    }
    let mut out = format!(
        "{} tris={} isa={:?}",
        scene,
        tris.len(),
        std::env::var("QUIVER_ISA").ok()
    );
    for (i, (name, ..)) in kinds.iter().enumerate() {
        times[i].sort_by(|a, b| a.partial_cmp(b).unwrap());
        out += &format!(" {name}={:.2}", times[i][reps / 2]);
    }
    println!("{out}");
}
