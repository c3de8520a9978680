//! Worlds of instances beside the same scene flattened to world-space triangles: what the
//! world tests and the instanced fuzz check judge a [`World`] by (the f64 oracle over the
//! flattened triangles, its bands widened by the transforms' rounding).

use crate::oracle::{Answer, Mismatch};
use crate::rays::random_rays;
use glam::{Affine3A, Vec3A};
use quiver_rt::{
    Aabb, BuildOptions, Hit, Instance, Motion, Ray, Triangle, World, WorldBuilder, WorldError,
    WorldHit,
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

    /// The geometries added to `b`: geometry `g` as a moving mesh of `steps[g]` where that
    /// holds two steps or more (and its triangles in [`Placements::geometries`] unused), the
    /// others still, the second as an indexed mesh. Steps the builder refuses are left for
    /// its build to report.
    fn add_geometries(&self, b: &mut WorldBuilder, steps: &[Vec<Vec<Triangle>>]) {
        for (g, tris) in self.geometries.iter().enumerate() {
            if let Some(s) = steps.get(g).filter(|s| s.len() >= 2) {
                // Refused steps hold the geometry's id with an empty one; the build reports them.
                let _ = b.add_moving_triangles(s.clone());
            } else if g == 1 {
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
        self.deforming_world(&[], motions, options).unwrap()
    }

    /// The world whose geometry `g` deforms through `steps[g]` where that holds two steps or
    /// more (a moving mesh, [`WorldBuilder::add_moving_triangles`]; its triangles in
    /// [`Placements::geometries`] are then unused; a shorter list or step list leaves the
    /// geometry still) and whose instances move by `motions` (as
    /// [`Placements::moving_world`]), every geometry built with `options`; the second
    /// geometry, if still, as a mesh.
    ///
    /// ```
    /// use quiver_rt::{BuildOptions, GeometryId, Instance, Ray, RayQuery, Triangle};
    /// use quiver_rt::glam::Vec3A;
    /// use quiver_lab::worlds::Placements;
    /// let tri = |z: f32| Triangle::new(Vec3A::new(0.0, 0.0, z), Vec3A::new(1.0, 0.0, z), Vec3A::new(0.0, 1.0, z));
    /// let p = Placements { geometries: vec![vec![tri(0.0)]], instances: vec![Instance::of(GeometryId(0))] };
    /// let steps = vec![vec![vec![tri(0.0)], vec![tri(-2.0)]]];
    /// let world = p.deforming_world(&steps, &[], &BuildOptions::default()).unwrap();
    /// let ray = Ray::new(Vec3A::new(0.2, 0.2, 1.0), -Vec3A::Z).with_time(0.5);
    /// assert_eq!(world.closest_hit(&ray).map(|h| h.t), Some(2.0));
    /// // The static scene at that time answers the same.
    /// let still = p.deformed_at(&steps, &[], 0.5).world(&BuildOptions::default());
    /// assert_eq!(still.closest_hit(&ray).map(|h| h.t), Some(2.0));
    /// ```
    ///
    /// # Errors
    /// What the build refuses: the first moving mesh's steps ([`WorldError::Steps`]: a
    /// vertex that is not finite, steps of different lengths), a motion.
    pub fn deforming_world(
        &self,
        steps: &[Vec<Vec<Triangle>>],
        motions: &[Option<Motion>],
        options: &BuildOptions,
    ) -> Result<World, WorldError> {
        let mut b = World::builder();
        self.add_geometries(&mut b, steps);
        for (i, inst) in self.instances.iter().enumerate() {
            match motions.get(i).and_then(Option::as_ref) {
                Some(m) => b.add_moving_instance(*inst, m.clone()),
                None => b.add_instance(*inst),
            };
        }
        b.build(options)
    }

    /// The scene placed where `motions` have its instances at `time` (the instances without
    /// a motion stay).
    pub fn at_time(&self, motions: &[Option<Motion>], time: f32) -> Placements {
        self.deformed_at(&[], motions, time)
    }

    /// The static scene [`Placements::deforming_world`] shows at `time`, taken as a ray's
    /// ([`clamped`]): each deforming geometry interpolated to it ([`interpolated`]), each
    /// moving instance placed where its motion has it then.
    pub fn deformed_at(
        &self,
        steps: &[Vec<Vec<Triangle>>],
        motions: &[Option<Motion>],
        time: f32,
    ) -> Placements {
        let time = clamped(time);
        let mut out = self.clone();
        for (g, s) in steps.iter().enumerate() {
            if s.len() >= 2 {
                out.geometries[g] = interpolated(s, time);
            }
        }
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

/// A shutter time as a ray takes it ([`Ray::shutter_time`]): clamped into `[0, 1]`, NaN as 0.
///
/// ```
/// use quiver_lab::worlds::clamped;
/// assert_eq!([-0.5, 0.25, 2.0, f32::NAN, f32::INFINITY].map(clamped), [0.0, 0.25, 1.0, 0.0, 1.0]);
/// ```
pub fn clamped(time: f32) -> f32 {
    Ray::new(Vec3A::ZERO, Vec3A::Z)
        .with_time(time)
        .shutter_time()
}

/// Triangles `steps` (a moving mesh's, step `j` at time `j / (S - 1)`) at shutter time `time`
/// ([`clamped`]), by the rule [`WorldBuilder::add_moving_triangles`] documents, written out
/// here apart from quiver's own: segment `k = floor(c * (S - 1))` (the last at 1),
/// `u = c * (S - 1) - k`, each vertex `a * (1 - u) + b * u` in f32. One step is a still mesh;
/// none, an empty one.
///
/// ```
/// use quiver_lab::worlds::interpolated;
/// use quiver_rt::Triangle;
/// use quiver_rt::glam::Vec3A;
/// let at = |z: f32| vec![Triangle::new(Vec3A::new(0.0, 0.0, z), Vec3A::X, Vec3A::Y)];
/// let steps = [at(0.0), at(-2.0), at(-1.0)];
/// assert_eq!(interpolated(&steps, 0.25), at(-1.0));
/// assert_eq!(interpolated(&steps, 0.75), at(-1.5));
/// assert_eq!(interpolated(&steps, 7.0), at(-1.0));
/// ```
pub fn interpolated(steps: &[Vec<Triangle>], time: f32) -> Vec<Triangle> {
    let segments = match steps {
        [] => return Vec::new(),
        [still] => return still.clone(),
        _ => steps.len() - 1,
    };
    let x = clamped(time) * segments as f32;
    let k = (x.floor() as usize).min(segments - 1);
    let u = x - k as f32;
    let lerp = |a: Vec3A, b: Vec3A| a * (1.0 - u) + b * u;
    steps[k]
        .iter()
        .zip(&steps[k + 1])
        .map(|(a, b)| {
            Triangle::new(
                lerp(a.v[0], b.v[0]),
                lerp(a.v[1], b.v[1]),
                lerp(a.v[2], b.v[2]),
            )
        })
        .collect()
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
