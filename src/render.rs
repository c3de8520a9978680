//! A Whitted ray tracer that follows the SPD testing procedure (Haines, Readme.txt of the
//! SPD): eye rays at pixel corners, depth limit 5 with the eye ray at depth 1, reflection rays
//! from every hit on a reflective surface, Snell refraction through every transmitter (a
//! reflection ray on total internal reflection), one shadow ray per light the surface faces,
//! Phong highlights on reflective surfaces, an ambient term.
//!
//! It simulates only what the scene calls for: a scene without reflective materials spawns no
//! secondary rays, one without transmitters no refraction rays, and a light behind a surface
//! costs no shadow ray. Shadow rays use the any-hit query.
//!
//! ```
//! use quiver::render::{render, RenderConfig};
//! use quiver::accel::SceneBvh;
//! use quiver::build::{BuildConfig, Builder};
//! use quiver::{scene::Scene, Layout};
//! let scene = Scene::load("tetra3").unwrap();
//! let (bvh, _) = SceneBvh::build(&scene, &BuildConfig::default(), Builder::Binned, Layout::Bvh4Dfs);
//! let out = render(&scene, &bvh, &RenderConfig { res: 16, ..Default::default() }, &|_| {});
//! assert_eq!(out.rays.eye, 17 * 17);
//! assert_eq!(out.rays.refract, 0); // tetra has no transmitters
//! ```

use crate::accel::SceneBvh;
use crate::geometry::{offset_ray_origin, Ray};
use crate::scene::{Material, Scene};
use crate::traverse::Counters;
use glam::Vec3A;
use rayon::prelude::*;
use std::ops::AddAssign;

/// Render settings.
#[derive(Clone, Debug)]
pub struct RenderConfig {
    /// Image width and height in pixels; `(res + 1)^2` eye rays are traced.
    pub res: u32,
    /// Deepest ray generation traced (the eye ray is depth 1).
    pub max_depth: u32,
    /// Objects whose material index is listed here are two-sided: their normal is turned to
    /// face the incoming ray (the SPD asks this of the teapot).
    pub two_sided: Vec<u32>,
    /// Count traversal work (nodes, leaves, tests) and nodes visited per eye ray.
    pub counters: bool,
    /// How secondary rays leave the surface.
    pub offset: Offset,
}

/// How a secondary ray avoids re-hitting the surface it starts on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Offset {
    /// Start at the hit point and ignore hits closer than `1e-4 * (1 + max|p|)`: what the
    /// classical tracers behind the SPD's published counts did, and the default. It skips
    /// real geometry closer than that (balls: the contacts of touching spheres).
    #[default]
    Epsilon,
    /// Move the origin a few ulps off the surface along the normal (Wächter & Binder): finds
    /// geometry however close, at any scale.
    Ulps,
}

impl Offset {
    /// A ray leaving point `p` of a surface with normal `side` (pointing to where the ray
    /// goes) in direction `dir`, up to `t_max`.
    pub fn ray(self, p: Vec3A, side: Vec3A, dir: Vec3A, t_max: f32) -> Ray {
        match self {
            Offset::Epsilon => {
                let eps = 1e-4 * (1.0 + p.abs().max_element());
                Ray::segment(p, dir, eps / dir.length(), t_max)
            }
            Offset::Ulps => Ray::segment(offset_ray_origin(p, side), dir, 0.0, t_max),
        }
    }
}

impl Default for RenderConfig {
    fn default() -> Self {
        RenderConfig {
            res: 512,
            max_depth: 5,
            two_sided: Vec::new(),
            counters: false,
            offset: Offset::Epsilon,
        }
    }
}

/// The rays a render traced, by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayCounts {
    /// Eye rays (one per pixel corner).
    pub eye: u64,
    /// Eye rays that hit an object.
    pub eye_hit: u64,
    /// Reflection rays (from reflective surfaces, and on total internal reflection).
    pub reflect: u64,
    /// Refraction rays.
    pub refract: u64,
    /// Shadow rays.
    pub shadow: u64,
    /// Shadow rays that found an occluder.
    pub shadow_blocked: u64,
}

impl RayCounts {
    /// All rays traced.
    pub fn total(&self) -> u64 {
        self.eye + self.reflect + self.refract + self.shadow
    }
}

impl AddAssign for RayCounts {
    fn add_assign(&mut self, o: RayCounts) {
        self.eye += o.eye;
        self.eye_hit += o.eye_hit;
        self.reflect += o.reflect;
        self.refract += o.refract;
        self.shadow += o.shadow;
        self.shadow_blocked += o.shadow_blocked;
    }
}

/// What a render produced.
#[derive(Clone, Debug)]
pub struct Rendered {
    /// Width = height in pixels.
    pub res: u32,
    /// Pixels row by row from the top, 8-bit sRGB-less RGB (the SPD's colours are used as is).
    pub rgb: Vec<[u8; 3]>,
    /// Rays traced, by kind.
    pub rays: RayCounts,
    /// Traversal work over all rays (zero unless [`RenderConfig::counters`]).
    pub work: Counters,
    /// Nodes visited by each eye ray, `(res + 1)^2` corners row by row (empty unless
    /// [`RenderConfig::counters`]).
    pub eye_nodes: Vec<u32>,
}

/// Per-corner-row accumulation.
#[derive(Default)]
struct RowOut {
    colors: Vec<Vec3A>,
    rays: RayCounts,
    work: Counters,
    eye_nodes: Vec<u32>,
}

/// Renders `scene` through `bvh` on the current rayon pool. `progress(rows)` is called as
/// corner rows complete (from worker threads). The result does not depend on the number of
/// threads: every corner is traced independently and the counts are integer sums.
pub fn render(
    scene: &Scene,
    bvh: &SceneBvh,
    config: &RenderConfig,
    progress: &(dyn Fn(usize) + Sync),
) -> Rendered {
    let n = config.res as usize + 1;
    let rows: Vec<RowOut> = (0..n)
        .into_par_iter()
        .map(|j| {
            let mut row = RowOut::default();
            for i in 0..n {
                let sx = -1.0 + 2.0 * i as f32 / config.res as f32;
                let sy = 1.0 - 2.0 * j as f32 / config.res as f32;
                let mut ray = scene.camera.ray(sx, sy);
                ray.t_min = scene.hither.max(0.0);
                let mut tracer = Tracer {
                    scene,
                    bvh,
                    config,
                    rays: RayCounts {
                        eye: 1,
                        ..Default::default()
                    },
                    work: Counters::default(),
                    eye_nodes: 0,
                };
                row.colors.push(tracer.trace(&ray, 1));
                row.rays += tracer.rays;
                row.work += tracer.work;
                if config.counters {
                    row.eye_nodes.push(tracer.eye_nodes as u32);
                }
            }
            progress(1);
            row
        })
        .collect();
    let mut rays = RayCounts::default();
    let mut work = Counters::default();
    let mut eye_nodes = Vec::new();
    for r in &rows {
        rays += r.rays;
        work += r.work;
        eye_nodes.extend_from_slice(&r.eye_nodes);
    }
    let res = config.res as usize;
    let mut rgb = Vec::with_capacity(res * res);
    for y in 0..res {
        for x in 0..res {
            let c = (rows[y].colors[x]
                + rows[y].colors[x + 1]
                + rows[y + 1].colors[x]
                + rows[y + 1].colors[x + 1])
                * 0.25;
            rgb.push(to_rgb8(c));
        }
    }
    Rendered {
        res: config.res,
        rgb,
        rays,
        work,
        eye_nodes,
    }
}

fn to_rgb8(c: Vec3A) -> [u8; 3] {
    let q = |x: f32| (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    [q(c.x), q(c.y), q(c.z)]
}

/// Ambient light as a fraction of each surface's colour.
const AMBIENT: f32 = 0.1;

struct Tracer<'a> {
    scene: &'a Scene,
    bvh: &'a SceneBvh,
    config: &'a RenderConfig,
    rays: RayCounts,
    work: Counters,
    /// Nodes the last eye ray visited.
    eye_nodes: u64,
}

impl Tracer<'_> {
    /// Closest hit; with counters on, through the counting kernel (a per-ray choice: the plain
    /// kernel itself carries no counting code).
    fn closest(&mut self, ray: &Ray) -> Option<crate::Hit> {
        if self.config.counters {
            self.bvh.closest_hit_counted(ray, &mut self.work)
        } else {
            self.bvh.closest_hit(ray)
        }
    }

    fn occluded(&mut self, ray: &Ray) -> bool {
        if self.config.counters {
            self.bvh.any_hit_counted(ray, &mut self.work)
        } else {
            self.bvh.any_hit(ray)
        }
    }

    /// Colour seen along `ray`, a ray of generation `depth`.
    fn trace(&mut self, ray: &Ray, depth: u32) -> Vec3A {
        let before = self.work.nodes;
        let found = self.closest(ray);
        if depth == 1 {
            self.eye_nodes = self.work.nodes - before;
        }
        let Some(hit) = found else {
            return self.scene.background;
        };
        if depth == 1 {
            self.rays.eye_hit += 1;
        }
        let object = self.bvh.object_of(hit.prim);
        let m = self.scene.materials[self.scene.objects[object as usize].material as usize];
        let p = ray.at(hit.t);
        let d = ray.dir.normalize();
        // The outward normal decides entering or leaving a transmitter; the shading normal
        // turns toward the viewer on two-sided surfaces: transmitters (NFF: "objects with
        // T > 0 are two-sided") and the materials the config lists (the teapot).
        let outward = self.bvh.normal(ray, &hit);
        let material = self.scene.objects[object as usize].material;
        let two_sided = m.t > 0.0 || self.config.two_sided.contains(&material);
        let n = if two_sided && outward.dot(d) > 0.0 {
            -outward
        } else {
            outward
        };
        let offset = self.config.offset;
        let mut color = m.color * AMBIENT;
        let intensity = 1.0 / (self.scene.lights.len().max(1) as f32).sqrt();
        for l in &self.scene.lights {
            let to_light = l.pos - p;
            // No shadow ray toward a light behind the surface (SPD rule 10, transmitters too).
            if n.dot(to_light) <= 0.0 {
                continue;
            }
            self.rays.shadow += 1;
            // Up to just short of the light.
            let shadow = offset.ray(p, n, to_light, 1.0);
            if self.occluded(&shadow) {
                self.rays.shadow_blocked += 1;
                continue;
            }
            color += shade(&m, n, to_light.normalize(), d) * l.color * intensity;
        }
        if depth >= self.config.max_depth {
            return color;
        }
        // Facing the incoming ray, for reflection and refraction.
        let (nf, entering) = if outward.dot(d) < 0.0 {
            (outward, true)
        } else {
            (-outward, false)
        };
        let reflect_dir = d - nf * (2.0 * d.dot(nf));
        // Reflective and transmitting surfaces both spawn reflection rays (SPD rule 8; the
        // gears' glass has Ks = 0 and still reflects).
        let reflect = m.ks > 0.0 || m.t > 0.0;
        // The reflected ray carries Ks, and on total internal reflection also the T the
        // refracted ray would have carried.
        let mut reflect_weight = m.ks;
        if m.t > 0.0 {
            let eta = if entering { 1.0 / m.ior } else { m.ior };
            let cos_i = -d.dot(nf);
            let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
            if k >= 0.0 {
                self.rays.refract += 1;
                let dir = d * eta + nf * (eta * cos_i - k.sqrt());
                let r = offset.ray(p, -nf, dir, f32::INFINITY);
                color += self.trace(&r, depth + 1) * m.t;
            } else {
                // Total internal reflection: the reflection ray takes the transmitted share.
                reflect_weight += m.t;
            }
        }
        if reflect {
            self.rays.reflect += 1;
            let r = offset.ray(p, nf, reflect_dir, f32::INFINITY);
            color += self.trace(&r, depth + 1) * reflect_weight;
        }
        color
    }
}

/// Diffuse plus, on reflective surfaces, a Phong highlight.
fn shade(m: &Material, n: Vec3A, l: Vec3A, d: Vec3A) -> Vec3A {
    let mut c = m.color * (m.kd * n.dot(l).max(0.0));
    if m.ks > 0.0 {
        let r = l - n * (2.0 * l.dot(n));
        let spec = r.dot(d).max(0.0).powf(m.shine.max(1.0));
        c += Vec3A::splat(m.ks * spec);
    }
    c
}
