//! Isotropic random lines through a box, and the walk that counts every node they pierce: the
//! measurement side of `quiver_rt::predict`'s Cauchy–Crofton identity.
//!
//! Lines meeting a convex body, drawn from the motion-invariant line measure, are made by
//! taking a point uniformly on the body's surface (by area) and a direction into the body with
//! density proportional to the cosine to the inward normal. Each such line is returned as a
//! ray from its entry point on the box's surface onward, so the ray covers everything the line
//! has inside the box.
//!
//! A closest-hit walk stops descending into boxes beyond its best hit; to count *every* node a
//! line pierces, trace it through a BVH over [`Pierce`] primitives (the real primitives'
//! boxes, never hit). Then the walk enters a node exactly when the line pierces its box, which
//! is what the identity is about.
//!
//! ```
//! use quiver_rt::predict::predict;
//! use quiver_rt::{Bvh, BuildOptions, Layout};
//! use quiver_lab::lines::{isotropic_lines, pierced, Pierce};
//! use quiver_scenes::Scene;
//! let tris = Scene::load("tetra3").unwrap().triangles();
//! let (_, tree) = Bvh::build_with_tree(&tris, &BuildOptions::default()).unwrap();
//! let options = BuildOptions::default().layout(Layout::Bvh2Dfs);
//! let ghost = Bvh::from_tree(&tree, &Pierce::of(&tris), &options).unwrap();
//! let lines = isotropic_lines(&tree.nodes[0].bounds, 20_000, 1);
//! let m = pierced(&ghost, &lines);
//! let p = predict(&tree);
//! assert!((m.nodes.mean - p.nodes).abs() < 4.0 * m.nodes.std_error);
//! ```

use glam::Vec3A;
use quiver_rt::primitive::LeafFormat;
use quiver_rt::traverse::Counters;
use quiver_rt::{Aabb, PrimHit, Primitive, Ray, RayQuery, Triangle};
use quiver_scenes::rng::Rng;
use rayon::prelude::*;
use std::marker::PhantomData;

/// `n` isotropic random lines meeting `bounds`, each as a ray starting where the line enters
/// the box (on its surface) and running to infinity. An empty box gives no lines.
pub fn isotropic_lines(bounds: &Aabb, n: usize, seed: u64) -> Vec<Ray> {
    if bounds.is_empty() {
        return Vec::new();
    }
    let e = bounds.extent();
    // Face areas per axis (a pair of faces each); the point is uniform on the whole surface.
    let areas = [e.y * e.z, e.z * e.x, e.x * e.y];
    let total: f32 = areas.iter().sum();
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|_| {
            let pick = rng.f32() * total;
            let axis = if pick < areas[0] || total == 0.0 {
                0
            } else if pick < areas[0] + areas[1] {
                1
            } else {
                2
            };
            let lower = rng.f32() < 0.5;
            let mut p = rng.in_box(bounds.min, bounds.max);
            p[axis] = if lower {
                bounds.min[axis]
            } else {
                bounds.max[axis]
            };
            let inward = if lower { 1.0 } else { -1.0 };
            Ray::new(p, cosine_direction(&mut rng, axis, inward))
        })
        .collect()
}

/// A direction about the axis `axis` (sign `inward`), with density proportional to the cosine
/// to it: a uniform point on the unit disc lifted onto the hemisphere (Malley's method).
fn cosine_direction(rng: &mut Rng, axis: usize, inward: f32) -> Vec3A {
    let r = rng.f32().sqrt();
    let phi = rng.range(0.0, std::f32::consts::TAU);
    let (a, b) = (r * phi.cos(), r * phi.sin());
    let c = (1.0 - r * r).max(0.0).sqrt() * inward;
    let mut d = Vec3A::ZERO;
    d[axis] = c;
    d[(axis + 1) % 3] = a;
    d[(axis + 2) % 3] = b;
    d
}

/// A primitive with another primitive's box that no ray ever hits: a BVH over these, laid out
/// from the real BVH's build tree, has the same nodes, and a closest-hit walk through it
/// enters every node whose box the ray pierces (the best hit never shortens the ray).
///
/// It keeps `P`'s [`Primitive::LEAF_FORMAT`], because the wide layouts collapse a tree by
/// the leaf format's cost (a group of four triangles costs one test): with another format the
/// 8-wide tree would have another shape. Its triangle, for the SIMD leaf groups, is a single
/// point (the box's centre), which no ray hits: the group test rejects a zero determinant.
#[derive(Debug)]
pub struct Pierce<P> {
    bounds: Aabb,
    of: PhantomData<fn() -> P>,
}

impl<P> Clone for Pierce<P> {
    fn clone(&self) -> Self {
        Pierce {
            bounds: self.bounds,
            of: PhantomData,
        }
    }
}

impl<P: Primitive> Pierce<P> {
    /// One per primitive of `prims`, with its box.
    pub fn of(prims: &[P]) -> Vec<Pierce<P>> {
        prims
            .iter()
            .map(|p| Pierce {
                bounds: p.bounds(),
                of: PhantomData,
            })
            .collect()
    }
}

impl<P: Primitive> Primitive for Pierce<P> {
    const LEAF_FORMAT: LeafFormat = P::LEAF_FORMAT;

    fn triangle(&self) -> Option<Triangle> {
        let c = self.bounds.center();
        Some(Triangle::new(c, c, c))
    }

    fn bounds(&self) -> Aabb {
        self.bounds
    }

    fn intersect(&self, _: &Ray) -> Option<PrimHit> {
        None
    }
}

/// Mean and its standard error (sample standard deviation over √n) of a per-ray count.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sample {
    /// Mean over the rays.
    pub mean: f64,
    /// Standard error of the mean.
    pub std_error: f64,
}

impl Sample {
    /// Mean and standard error of `xs`; zeros for an empty set.
    ///
    /// ```
    /// use quiver_lab::lines::Sample;
    /// let s = Sample::of([1.0, 2.0, 3.0, 4.0].into_iter());
    /// assert_eq!(s.mean, 2.5);
    /// assert!((s.std_error - (5.0f64 / 3.0 / 4.0).sqrt()).abs() < 1e-12);
    /// ```
    pub fn of(xs: impl Iterator<Item = f64> + Clone) -> Sample {
        let n = xs.clone().count() as f64;
        if n == 0.0 {
            return Sample::default();
        }
        let mean = xs.clone().sum::<f64>() / n;
        let var = if n > 1.0 {
            xs.map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0)
        } else {
            0.0
        };
        Sample {
            mean,
            std_error: (var / n).sqrt(),
        }
    }
}

/// Per-ray traversal work, as means with standard errors.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Work {
    /// Nodes entered (inner and leaf).
    pub nodes: Sample,
    /// Leaves entered.
    pub leaves: Sample,
    /// Ray-box tests.
    pub box_tests: Sample,
    /// Ray-primitive tests.
    pub prim_tests: Sample,
}

impl Work {
    /// The statistics of per-ray counters.
    pub fn of(per_ray: &[Counters]) -> Work {
        let s = |f: fn(&Counters) -> u64| Sample::of(per_ray.iter().map(move |c| f(c) as f64));
        Work {
            nodes: s(|c| c.nodes),
            leaves: s(|c| c.leaves),
            box_tests: s(|c| c.box_tests),
            prim_tests: s(|c| c.prim_tests),
        }
    }
}

/// Each ray's closest-hit counters, in order, traced on the current thread pool.
pub fn counters_per_ray<Q: RayQuery + Sync>(bvh: &Q, rays: &[Ray]) -> Vec<Counters> {
    rays.par_iter()
        .map(|r| {
            let mut c = Counters::default();
            bvh.closest_hit_counted(r, &mut c);
            c
        })
        .collect()
}

/// What a walk that never stops early does per ray: `ghost` is a BVH over [`Pierce`]
/// primitives.
pub fn pierced<Q: RayQuery + Sync>(ghost: &Q, rays: &[Ray]) -> Work {
    Work::of(&counters_per_ray(ghost, rays))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lines' directions follow the cosine law: the mean cosine to the inward normal of a
    /// cosine-weighted hemisphere is 2/3.
    #[test]
    fn directions_are_cosine_weighted() {
        let b = Aabb::new(Vec3A::ZERO, Vec3A::new(1.0, 2.0, 3.0));
        let lines = isotropic_lines(&b, 200_000, 3);
        let cos = Sample::of(lines.iter().map(|r| {
            let axis = (0..3)
                .find(|&a| r.origin[a] == b.min[a] || r.origin[a] == b.max[a])
                .unwrap();
            r.dir[axis].abs() as f64
        }));
        assert!((cos.mean - 2.0 / 3.0).abs() < 4.0 * cos.std_error);
    }

    /// Lines through a box pierce a box inside it with probability SA(inner) / SA(outer) —
    /// checked here on one box by the slab test, with no BVH involved.
    #[test]
    fn crofton_on_one_box() {
        let outer = Aabb::new(Vec3A::ZERO, Vec3A::new(4.0, 1.0, 2.0));
        let inner = Aabb::new(Vec3A::new(1.0, 0.2, 0.5), Vec3A::new(1.5, 0.9, 0.6));
        let lines = isotropic_lines(&outer, 400_000, 9);
        let hit = Sample::of(lines.iter().map(|r| {
            let inv = r.dir.recip();
            let t0 = (inner.min - r.origin) * inv;
            let t1 = (inner.max - r.origin) * inv;
            let near = t0.min(t1).max_element();
            let far = t0.max(t1).min_element();
            f64::from(u8::from(near <= far && far >= 0.0))
        }));
        let expected = inner.half_area() as f64 / outer.half_area() as f64;
        assert!((hit.mean - expected).abs() < 4.0 * hit.std_error);
    }
}
