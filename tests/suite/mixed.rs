//! The mixed-primitive path (spheres, cones, n-gons, patch triangles in one BVH) against the
//! brute-force reference, for every layout.

use crate::common::reference_hits;
use glam::Vec3A;
use quiver_rt::builders::Builder;
use quiver_rt::{Aabb, BuildOptions, Layout, Primitive, Ray, RayQuery, Triangle};
use quiver_lab::rays;
use quiver_scenes::primitive::{Cone, PatchTriangle, Polygon, Prim, Sphere};
use quiver_scenes::rng::Rng;
use rayon::prelude::*;

/// A seeded jumble of every primitive kind in the unit cube.
fn jumble(n: usize, seed: u64) -> Vec<Prim> {
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|i| {
            let c = rng.in_box(Vec3A::ZERO, Vec3A::ONE);
            let r = rng.range(0.005, 0.05);
            match i % 5 {
                0 => Prim::Sphere(Sphere {
                    center: c,
                    radius: r,
                }),
                1 => Prim::Cone(Cone {
                    base: c,
                    base_radius: r,
                    apex: c + rng.unit_vector() * (3.0 * r),
                    apex_radius: if i % 2 == 0 { r } else { r * 0.3 },
                }),
                2 => {
                    // A star: concave, 10 vertices, in a random plane.
                    let (u, v) = {
                        let n = rng.unit_vector();
                        let u = n.any_orthonormal_vector();
                        (u, n.cross(u))
                    };
                    let verts = (0..10)
                        .map(|k| {
                            let a = k as f32 * std::f32::consts::TAU / 10.0;
                            let rr = if k % 2 == 0 { r * 2.0 } else { r * 0.8 };
                            c + (u * a.cos() + v * a.sin()) * rr
                        })
                        .collect();
                    Prim::Polygon(Polygon::new(verts))
                }
                3 => {
                    let mut p = || c + rng.in_box(Vec3A::splat(-r), Vec3A::splat(r)) * 2.0;
                    let tri = Triangle::new(p(), p(), p());
                    Prim::Patch(PatchTriangle {
                        tri,
                        normals: [Vec3A::X, Vec3A::Y, Vec3A::Z],
                    })
                }
                _ => {
                    let mut p = || c + rng.in_box(Vec3A::splat(-r), Vec3A::splat(r)) * 2.0;
                    Prim::Triangle(Triangle::new(p(), p(), p()))
                }
            }
        })
        .collect()
}

#[test]
fn every_layout_matches_the_reference_on_mixed_primitives() {
    let prims = jumble(5000, 11);
    let bounds = prims.iter().fold(Aabb::EMPTY, |a, p| a.union(&p.bounds()));
    let rays = rays::random_rays(&bounds, 30_000, 5);
    let want = reference_hits(&prims, &rays);
    let hits = want.iter().filter(|h| h.is_some()).count();
    assert!(hits > rays.len() / 20, "only {hits} hits");
    for builder in Builder::ALL {
        for layout in Layout::ALL {
            let bvh = BuildOptions::default()
                .builder(builder)
                .layout(layout)
                .build(&prims);
            rays.par_iter()
                .zip(&want)
                .enumerate()
                .for_each(|(i, (r, w))| {
                    assert_eq!(bvh.closest_hit(r), *w, "{builder} {layout} ray {i}");
                    assert_eq!(
                        bvh.any_hit(r),
                        w.is_some(),
                        "{builder} {layout} any ray {i}"
                    );
                });
        }
    }
}

/// A small sphere or cone seen from far away (the SPD tree's twigs: radius 0.002 at distance
/// 5) is hit on its surface: the hit point's distance from the centre (sphere) or from the
/// axis (cone), in f64, equals the radius to within f32 rounding of the point, and the point
/// lies in the primitive's own box, which the BVH culls by.
#[test]
fn small_distant_spheres_and_cones_are_hit_on_their_surface() {
    let mut rng = Rng::new(21);
    let d64 = |v: Vec3A| glam::DVec3::new(v.x as f64, v.y as f64, v.z as f64);
    let mut hits = 0;
    for _ in 0..2000 {
        let c = rng.in_box(Vec3A::splat(-1.0), Vec3A::ONE);
        let r = rng.range(0.001, 0.003);
        let axis = rng.unit_vector() * (4.0 * r);
        let sphere = Prim::Sphere(Sphere {
            center: c,
            radius: r,
        });
        let cone = Prim::Cone(Cone {
            base: c,
            base_radius: r,
            apex: c + axis,
            apex_radius: r,
        });
        // From 5 units away, aimed within the radius of the centre.
        let from = c + rng.unit_vector() * 5.0;
        let aim = c + rng.in_box(Vec3A::splat(-r), Vec3A::splat(r)) * 0.9;
        let ray = Ray::new(from, aim - from);
        for prim in [&sphere, &cone] {
            let Some(h) = prim.intersect(&ray) else {
                continue;
            };
            hits += 1;
            let p = ray.at(h.t);
            // The point's own rounding: a few ulps of coordinates of size ~6.
            let tol = 8.0 * 6.0 * f32::EPSILON as f64;
            let off = match prim {
                Prim::Sphere(_) => ((d64(p) - d64(c)).length() - r as f64).abs(),
                _ => {
                    let w = d64(axis).normalize();
                    let q = d64(p) - d64(c);
                    let s = q.dot(w);
                    ((q - w * s).length() - r as f64).abs()
                }
            };
            assert!(off <= tol, "{prim:?} {ray:?}: {off} off the surface");
            let b = prim.bounds();
            let inside = (p.cmpge(b.min - tol as f32) & p.cmple(b.max + tol as f32)).all();
            assert!(inside, "{prim:?} {ray:?}: {p} outside {b:?}");
        }
    }
    assert!(hits > 2000, "only {hits} hits");
}

/// Distance from `p` to the nearest edge of the closed polygon `verts`.
fn edge_distance(p: Vec3A, verts: &[Vec3A]) -> f32 {
    (0..verts.len())
        .map(|i| {
            let (a, b) = (verts[i], verts[(i + 1) % verts.len()]);
            let t = ((p - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
            (a + (b - a) * t - p).length()
        })
        .fold(f32::INFINITY, f32::min)
}

#[test]
fn polygons_traced_as_pieces_are_hit_where_the_polygon_is() {
    // The gears' 144-vertex concave faces (and every other polygon of the scene) as the
    // renderer traces them, against the even-odd polygon test: rays aimed at random points
    // of each face's box from random directions must hit the pieces exactly where they hit
    // the polygon, at the same distance, except within a rounding band of the outline.
    let scene = quiver_scenes::Scene::load("gears2").unwrap();
    let mut rng = Rng::new(17);
    let (mut checked, mut hits) = (0, 0);
    for o in &scene.objects {
        let quiver_scenes::scene::Shape::Polygon(verts) = &o.shape else {
            continue;
        };
        let poly = Polygon::new(verts.clone());
        let mut tris = Vec::new();
        quiver_scenes::scene::tessellate::polygon_triangles(verts, &mut tris);
        let pieces: Vec<Prim> = tris
            .into_iter()
            .map(|tri| {
                Prim::Piece(quiver_scenes::primitive::PolygonPiece {
                    tri,
                    normal: poly.normal(),
                })
            })
            .collect();
        let b = poly.bounds();
        let size = b.extent().max_element();
        for _ in 0..200 {
            let target = rng.in_box(b.min, b.max);
            let dir = rng.unit_vector();
            let ray = Ray::new(target - dir * size, dir);
            let want = poly.intersect(&ray);
            let got = pieces
                .iter()
                .filter_map(|p| p.intersect(&ray))
                .min_by(|a, b| a.t.total_cmp(&b.t));
            checked += 1;
            hits += want.is_some() as u32;
            // The face's vertices are coplanar only up to f32 rounding of coordinates of
            // magnitude `m`: the pieces' planes and the polygon's Newell plane differ by a
            // few ulps of `m`, which a ray crossing at cosine `c` sees stretched by 1 / c.
            let m = b.min.abs().max(b.max.abs()).max_element();
            let c = poly.normal().dot(dir).abs();
            let tol = 1e-5 * m / c;
            match (want, got) {
                (Some(w), Some(g)) => {
                    assert!((w.t - g.t).abs() <= tol, "{ray:?}: t {} vs {}", w.t, g.t)
                }
                (None, None) => {}
                (w, g) => {
                    let t = w.or(g).unwrap().t;
                    let d = edge_distance(ray.at(t), verts);
                    assert!(d <= tol, "{ray:?}: {w:?} vs {g:?}, {d} from the outline");
                }
            }
        }
    }
    assert!(
        checked > 1000 && hits > checked / 10,
        "{checked} rays, {hits} hits"
    );
}
