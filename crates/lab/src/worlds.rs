//! Worlds of instances beside the same scene flattened to world-space triangles: what the
//! world tests and the instanced fuzz check judge a [`World`] by (the f64 oracle over the
//! flattened triangles, its bands widened by the transforms' rounding).

use crate::oracle::{Answer, Mismatch};
use crate::rays::random_rays;
use glam::Affine3A;
use quiver_rt::{
    Aabb, BuildOptions, Hit, Instance, Motion, Ray, Triangle, World, WorldBuilder, WorldHit,
};

/// A scene to instance: geometries (triangle lists; the second is given to the world as an
/// indexed mesh) and instances of them with transforms and masks.
///
/// ```
/// use quiver_rt::{BuildOptions, GeometryId, Instance, Triangle};
/// use quiver_rt::glam::{Affine3A, Vec3A};
/// use quiver_lab::worlds::Placements;
/// let tri = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
/// let p = Placements {
///     geometries: vec![vec![tri]],
///     instances: vec![Instance::of(GeometryId(0)).transform(Affine3A::from_translation(Vec3A::Z.into()))],
/// };
/// let (flat, names) = p.flattened(|_, _| true);
/// assert_eq!(flat[0].v[0], Vec3A::Z);
/// assert_eq!(names, [(0, 0, 0)]);
/// assert_eq!(p.world(&BuildOptions::default()).instances().len(), 1);
/// ```
#[derive(Clone, Debug)]
pub struct Placements {
    /// The geometries' triangles.
    pub geometries: Vec<Vec<Triangle>>,
    /// The instances.
    pub instances: Vec<Instance>,
}

impl Placements {
    /// The world, every geometry built with `options`; the second geometry as a mesh.
    pub fn world(&self, options: &BuildOptions) -> World {
        self.moving_world(&[], options)
    }

    /// The geometries added to `b`, the second as an indexed mesh.
    fn add_geometries(&self, b: &mut WorldBuilder) {
        for (g, tris) in self.geometries.iter().enumerate() {
            if g == 1 {
                let positions: Vec<[f32; 3]> = tris
                    .iter()
                    .flat_map(|t| t.v.map(|v| v.to_array()))
                    .collect();
                let indices: Vec<[u32; 3]> = (0..tris.len() as u32)
                    .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
                    .collect();
                b.add_mesh(&positions, &indices).unwrap();
            } else {
                b.add_triangles(tris.clone());
            }
        }
    }

    /// The world whose instances move by `motions` (`motions[i]` for instance `i`; a
    /// shorter list leaves the rest still), every geometry built with `options`; the second
    /// geometry as a mesh.
    ///
    /// # Panics
    /// When the world refuses a motion.
    pub fn moving_world(&self, motions: &[Option<Motion>], options: &BuildOptions) -> World {
        let mut b = World::builder();
        self.add_geometries(&mut b);
        for (i, inst) in self.instances.iter().enumerate() {
            match motions.get(i).and_then(Option::as_ref) {
                Some(m) => b.add_moving_instance(*inst, m.clone()),
                None => b.add_instance(*inst),
            };
        }
        b.build(options).unwrap()
    }

    /// The scene placed where `motions` have its instances at `time` (the instances without
    /// a motion stay).
    pub fn at_time(&self, motions: &[Option<Motion>], time: f32) -> Placements {
        let mut out = self.clone();
        for (inst, motion) in out.instances.iter_mut().zip(motions) {
            if let Some(m) = motion {
                inst.transform = m.at(time);
            }
        }
        out
    }

    /// The scene flattened instance by instance into world-space triangles, keeping those
    /// `keep(instance, prim)` accepts, and what each flattened triangle is.
    pub fn flattened(
        &self,
        keep: impl Fn(u32, u32) -> bool,
    ) -> (Vec<Triangle>, Vec<(u32, u32, u32)>) {
        let (mut out, mut names) = (Vec::new(), Vec::new());
        for (i, inst) in self.instances.iter().enumerate() {
            let g = inst.geometry.0;
            for (j, t) in self.geometries[g as usize].iter().enumerate() {
                if keep(i as u32, j as u32) {
                    out.push(Triangle::new(
                        inst.transform.transform_point3a(t.v[0]),
                        inst.transform.transform_point3a(t.v[1]),
                        inst.transform.transform_point3a(t.v[2]),
                    ));
                    names.push((i as u32, g, j as u32));
                }
            }
        }
        (out, names)
    }

    /// How much more than an f32 test of the flattened triangles the instanced path may round:
    /// a transform rounds a point to within about `cond(M)` ulps of its coordinates (the
    /// flattened vertices, and the ray brought into object space, each once), so the bands
    /// widen by `1 + 2·cond` for the worst-conditioned transform.
    pub fn slack(&self) -> f64 {
        let cond = self
            .instances
            .iter()
            .filter(|i| i.transform != Affine3A::IDENTITY)
            .map(|i| {
                let m = i.transform.matrix3;
                // Frobenius norms in f64: at scales past 1e±19 the squares over- or
                // underflow f32 (an infinite or NaN condition number marks every ray
                // ambiguous, or none).
                let f = |m: glam::Mat3A| {
                    m.to_cols_array()
                        .iter()
                        .map(|&x| (x as f64) * (x as f64))
                        .sum::<f64>()
                        .sqrt()
                };
                let inverse =
                    quiver_rt::world::invert(&i.transform).map_or(m.inverse(), |inv| inv.matrix3);
                f(m) * f(inverse) / 3.0
            })
            .fold(1.0, f64::max);
        1.0 + 2.0 * cond
    }

    /// Random rays through the scene and rays aimed at random flattened triangles.
    pub fn rays(&self, n: usize, seed: u64) -> Vec<Ray> {
        let (flat, _) = self.flattened(|_, _| true);
        let bounds = flat.iter().fold(Aabb::EMPTY, |b, t| b.union(&t.bounds()));
        let mut rays = random_rays(&bounds, n, seed);
        let from = random_rays(&bounds, n, seed + 1);
        for (k, r) in from.iter().enumerate() {
            let t = &flat[(k * 7919) % flat.len()];
            let target = (t.v[0] + t.v[1] + t.v[2]) / 3.0;
            rays.push(Ray::new(r.origin, target - r.origin));
        }
        rays
    }
}

/// Checks `got` (a world hit) against the oracle's answer over the flattened triangles
/// `names`: on a decidable ray the same instance, geometry and primitive and `t`, `u`, `v`
/// within the widened bands; on an ambiguous one an admissible hit or an allowed miss.
pub fn check(
    answer: &Answer,
    got: Option<WorldHit>,
    names: &[(u32, u32, u32)],
) -> Result<(), Mismatch> {
    let as_flat = got.map(|h| {
        let k = names
            .iter()
            .position(|&n| n == (h.instance.0, h.geometry.0, h.prim))
            .expect("a hit names a triangle of the flattened scene");
        Hit {
            t: h.t,
            prim: k as u32,
            u: h.u,
            v: h.v,
        }
    });
    answer.check(as_flat)
}
