//! Scale invariance: a scene scaled by any power of ten whose coordinates stay finite in f32
//! gives the same eye hits, the same ray counts and the same image as at scale 1 (the
//! oracle: the same scene at scale 1, traced by the same code).

use glam::Vec3A;
use quiver_lab::rays;
use quiver_rt::intersect::Watertight;
use quiver_rt::{BuildOptions, Bvh, Hit, Layout, Primitive, RayQuery, Triangle};
use quiver_scenes::accel::SceneBvh;
use quiver_scenes::primitive::{Cone, Sphere};
use quiver_scenes::render::{render, Offset, RenderConfig};
use quiver_scenes::scene::{Scene, Shape};

/// Every power of ten from 1e-30 to 1e30.
const EXPONENTS: std::ops::RangeInclusive<i32> = -30..=30;

/// A scale factor: `10^j` or `2^j`.
#[derive(Clone, Copy, Debug)]
enum Factor {
    Ten(i32),
    Two(i32),
}

impl Factor {
    fn value(self) -> f64 {
        match self {
            Factor::Ten(j) => 10f64.powi(j),
            Factor::Two(j) => 2f64.powi(j),
        }
    }
}

impl std::fmt::Display for Factor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Factor::Ten(j) => write!(f, "1e{j}"),
            Factor::Two(j) => write!(f, "2^{j}"),
        }
    }
}

/// `v` times the factor, rounded once (from f64).
fn scale_point(v: Vec3A, j: Factor) -> Vec3A {
    let f = j.value();
    Vec3A::new(
        (v.x as f64 * f) as f32,
        (v.y as f64 * f) as f32,
        (v.z as f64 * f) as f32,
    )
}

fn scale_len(x: f32, j: Factor) -> f32 {
    (x as f64 * j.value()) as f32
}

fn scale_tri(t: &Triangle, j: Factor) -> Triangle {
    Triangle {
        v: t.v.map(|p| scale_point(p, j)),
    }
}

/// The whole scene, camera and lights scaled by `10^j`.
fn scale_scene(s: &Scene, j: Factor) -> Scene {
    let mut out = s.clone();
    for o in &mut out.objects {
        o.shape = match &o.shape {
            Shape::Sphere(sp) => Shape::Sphere(Sphere {
                center: scale_point(sp.center, j),
                radius: scale_len(sp.radius, j),
            }),
            Shape::Cone(c) => Shape::Cone(Cone {
                base: scale_point(c.base, j),
                base_radius: scale_len(c.base_radius, j),
                apex: scale_point(c.apex, j),
                apex_radius: scale_len(c.apex_radius, j),
            }),
            Shape::Triangle(t) => Shape::Triangle(scale_tri(t, j)),
            Shape::Polygon(v) => Shape::Polygon(v.iter().map(|&p| scale_point(p, j)).collect()),
            Shape::Patch { verts, normals } => Shape::Patch {
                verts: verts.iter().map(|&p| scale_point(p, j)).collect(),
                normals: normals.clone(),
            },
        };
    }
    out.camera.from = scale_point(s.camera.from, j);
    out.camera.at = scale_point(s.camera.at, j);
    for l in &mut out.lights {
        l.pos = scale_point(l.pos, j);
    }
    out.hither = scale_len(s.hither, j);
    out
}

/// Eye hits of `prims` (a scene's triangles as `P`) scaled by `10^j`, every layout, against
/// the same at scale 1: the same primitive, and `t`, `u`, `v` alike to a few ulps.
fn eye_hits_match<P: Primitive>(scene: &Scene, wrap: fn(Triangle) -> P) {
    let tris = scene.triangles();
    let base: Vec<P> = tris.iter().map(|&t| wrap(t)).collect();
    let eye = rays::camera_rays(&scene.camera, 24);
    for layout in Layout::ALL {
        let want: Vec<Option<Hit>> = {
            let bvh = Bvh::build(&base, &BuildOptions::default().layout(layout)).unwrap();
            eye.iter().map(|r| bvh.closest_hit(r)).collect()
        };
        assert!(
            want.iter().any(|h| h.is_some()),
            "{}: no hits at scale 1",
            scene.name
        );
        for j in EXPONENTS.map(Factor::Ten) {
            let prims: Vec<P> = tris.iter().map(|t| wrap(scale_tri(t, j))).collect();
            let camera = scale_scene(scene, j).camera;
            let bvh = Bvh::build(&prims, &BuildOptions::default().layout(layout)).unwrap();
            for (i, (r, w)) in rays::camera_rays(&camera, 24).iter().zip(&want).enumerate() {
                let got = bvh.closest_hit(r);
                let at = format!("{} {layout} {j} ray {i}: {got:?} vs {w:?}", scene.name);
                assert_eq!(got.map(|h| h.prim), w.map(|h| h.prim), "{at}");
                if let (Some(g), Some(w)) = (got, w) {
                    let t = g.t as f64 / j.value();
                    assert!((t - w.t as f64).abs() <= 1e-5 * w.t as f64, "{at}");
                    assert!(
                        (g.u - w.u).abs() <= 1e-4 && (g.v - w.v).abs() <= 1e-4,
                        "{at}"
                    );
                }
            }
        }
    }
}

#[test]
fn eye_hits_are_the_same_at_every_scale_fast() {
    for name in ["tetra3", "teapot2"] {
        eye_hits_match(&Scene::load(name).unwrap(), |t| t);
    }
}

#[test]
fn eye_hits_are_the_same_at_every_scale_watertight() {
    for name in ["tetra3", "teapot2"] {
        eye_hits_match(&Scene::load(name).unwrap(), Watertight);
    }
}

/// Renders of `scene` at every scale against scale 1, with either offset: at powers of two
/// (exact in f32; every layout) the same ray counts and the same pixels; at powers of ten (each coordinate
/// rounded anew, so a facing test or a shading value at a tie may land the other way) the
/// same eye hits, other ray counts within two rays or 0.2% per kind, and at most 1% of pixel
/// channels different (one corner ray decided the other way shades four pixels: 12 of 1728
/// channels).
fn renders_match(scene: &Scene, patches: bool) {
    for offset in [Offset::Epsilon, Offset::Ulps] {
        let config = RenderConfig {
            res: 24,
            two_sided: scene.two_sided_materials(),
            offset,
            ..RenderConfig::default()
        };
        let run_in = |s: &Scene, layout: Layout| {
            let options = BuildOptions::default().layout(layout);
            let bvh = if patches {
                SceneBvh::build_triangles(s, &options).unwrap()
            } else {
                SceneBvh::build(s, &options).unwrap()
            };
            render(s, &bvh, &config, &|_| {})
        };
        let run = |s: &Scene| run_in(s, Layout::default());
        let want = run(scene);
        assert!(
            want.rays.shadow > 0,
            "{}: a scene with shadow rays",
            scene.name
        );
        // Every layout: a render does not depend on the layout at scale 1 (tests/suite/render.rs).
        for layout in Layout::ALL {
            for j in (-100..=100).step_by(20).map(Factor::Two) {
                let got = run_in(&scale_scene(scene, j), layout);
                let at = format!("{} {layout} {offset:?} at {j}", scene.name);
                assert_eq!(got.rays, want.rays, "{at}");
                assert!(got.rgb == want.rgb, "{at}: pixels differ");
            }
        }
        for j in EXPONENTS.map(Factor::Ten) {
            let got = run(&scale_scene(scene, j));
            let at = format!("{} {offset:?} at {j}", scene.name);
            let (g, w) = (got.rays, want.rays);
            assert_eq!((g.eye, g.eye_hit), (w.eye, w.eye_hit), "{at}");
            for (kind, g, w) in [
                ("reflect", g.reflect, w.reflect),
                ("refract", g.refract, w.refract),
                ("shadow", g.shadow, w.shadow),
                ("blocked", g.shadow_blocked, w.shadow_blocked),
            ] {
                assert!(
                    g.abs_diff(w) <= (w / 500).max(2),
                    "{at}: {kind} rays {g} vs {w}"
                );
            }
            let diffs: Vec<i32> = got
                .rgb
                .iter()
                .zip(&want.rgb)
                .flat_map(|(a, b)| (0..3).map(move |c| (a[c] as i32 - b[c] as i32).abs()))
                .collect();
            let worst = diffs.iter().max().copied().unwrap_or(0);
            let off = diffs.iter().filter(|&&d| d > 0).count();
            assert!(
                off * 100 <= diffs.len(),
                "{at}: {off} of {} channels differ, by up to {worst}",
                diffs.len()
            );
        }
    }
}

#[test]
fn one_triangle_renders_alike_at_every_scale() {
    let text = "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 45\nhither 0.001\nresolution 17 17\n\
                b 0 0 0\nl 1 1 4\nf 1 1 1 1 0 0 0 1\np 3\n-1 -1 0\n1 -1 0\n0 1 0\n";
    let scene = quiver_scenes::scene::nff::parse(text, "one.nff").unwrap();
    renders_match(&scene, false);
}

#[test]
fn spd_scenes_render_alike_at_every_scale() {
    for (name, patches) in [
        ("balls1", false),
        ("tetra2", false),
        ("teapot2", true),
        ("tree2", false),
    ] {
        renders_match(&Scene::load(name).unwrap(), patches);
    }
}

/// A triangle far from unit size hit head-on, alone (the BVH traces it in its own scaled
/// frame) and as the brute-force reference tests it (`Triangle::intersect`, `Watertight`,
/// in their own units): a finite `t`, the f64 oracle's to 1e-5, and the BVH's in every
/// layout. Before the scalar tests rescaled out-of-range products, 1e15 gave `t = inf` and
/// 1e30 a miss.
#[test]
fn one_triangle_at_the_edge_of_f32() {
    for s in [1e15f32, 1e20, 1e30, 1e35, 1e-30] {
        let tris = [Triangle::new(
            Vec3A::new(0.0, 0.0, s),
            Vec3A::new(s, 0.1 * s, s),
            Vec3A::new(0.2 * s, s, 1.1 * s),
        )];
        let wt = [Watertight(tris[0])];
        let oracle = quiver_lab::oracle::Oracle::new(&tris);
        for dir in [Vec3A::Z, Vec3A::new(0.1, 0.0, 1.0) * s] {
            let ray = quiver_rt::Ray::new(Vec3A::new(0.3 * s, 0.25 * s, -s), dir);
            let want = oracle.closest_hit(&ray).hit.expect("the oracle hits").t;
            let fast = quiver_rt::traverse::reference::closest_hit(&tris, &ray);
            let water = quiver_rt::traverse::reference::closest_hit(&wt, &ray);
            for (name, got) in [("fast", fast), ("watertight", water)] {
                let t = got.unwrap_or_else(|| panic!("{s} {name}: missed")).t;
                assert!(t.is_finite(), "{s} {name}: t = {t}");
                let err = (t as f64 - want).abs() / want;
                assert!(err <= 1e-5, "{s} {name}: t = {t}, oracle {want}");
            }
            for layout in Layout::ALL {
                let options = BuildOptions::default().layout(layout);
                assert_eq!(
                    Bvh::build(&tris, &options).unwrap().closest_hit(&ray),
                    fast,
                    "{s} {layout}"
                );
                let w = Bvh::build(&wt, &options)
                    .unwrap()
                    .closest_hit(&ray)
                    .map(|h| h.t);
                let err = (w.unwrap_or(f32::NAN) as f64 - want).abs() / want;
                assert!(err <= 1e-5, "{s} {layout} watertight: {w:?}, oracle {want}");
            }
            assert_eq!(quiver_rt::Bvh::new(&tris).closest_hit(&ray), fast, "{s}");
        }
    }
}

/// Scenes of extents where half areas overflow f32 (1e19 and beyond): every builder
/// finishes with a valid tree of finite SAH cost, and `Aabb::half_area` stays finite. Both
/// through `BuildOptions` (which builds a scene all of one size in a scaled frame) and
/// straight on the world boxes (no frame: the builders' own f32 areas), and for a scene that
/// mixes 1e30 with unit sizes.
#[test]
fn huge_scenes_build_valid_trees_with_finite_costs() {
    use quiver_rt::builders::{build, prim_bounds, BuildConfig, Builder};
    let grid = |s: f32| -> Vec<Triangle> {
        (0..64)
            .map(|i| {
                let p = Vec3A::new((i % 4) as f32, (i / 4 % 4) as f32, (i / 16) as f32) * s;
                Triangle::new(p, p + Vec3A::X * 0.5 * s, p + Vec3A::Y * 0.5 * s)
            })
            .collect()
    };
    let huge = quiver_rt::Aabb::new(Vec3A::splat(-3e38), Vec3A::splat(3e38));
    assert_eq!(huge.half_area(), f32::MAX);
    assert!(huge.half_area_f64().is_finite());
    let config = BuildConfig::default();
    for s in [1e19f32, 1e25, 1e30, 1e37] {
        let mut mixed = grid(s);
        mixed.extend(grid(1.0));
        for tris in [grid(s), mixed] {
            let bounds = prim_bounds(&tris);
            for builder in Builder::ALL {
                let (_, tree) =
                    Bvh::build_with_tree(&tris, &BuildOptions::default().builder(builder)).unwrap();
                let raw = build(&bounds, &config, builder).unwrap();
                for (how, tree) in [("options", tree), ("boxes", raw)] {
                    tree.check(&bounds, &config)
                        .unwrap_or_else(|e| panic!("{s} {builder:?} {how}: {e}"));
                    let cost = tree.sah_cost(&config);
                    assert!(cost.is_finite(), "{s} {builder:?} {how}: cost {cost}");
                }
            }
        }
    }
}

/// One BVH over unit triangles and triangles at 1e15, 1e20, 1e30 and f32::MAX / 4 (each
/// ahead of the origin along its own axis) and at 1e-30 (beside the origin): too spread to be
/// scaled as a whole, so the SIMD leaf groups see the raw sizes, where the fast and the watertight
/// arithmetic overflow (huge) or underflow (tiny). Every layout and instruction set, closest, any
/// and counted queries, packets in both modes, answer exactly what the scalar tests answer
/// (`quiver_rt::traverse::reference`, which rescales), and the reference is the f64 oracle's on
/// every decidable ray; every far triangle is hit. Before far groups, the 4- and 8-wide layouts
/// missed the far triangles.
#[test]
fn mixed_scales_in_one_bvh_answer_as_the_scalar_tests() {
    use crate::common::{each_isa, packet_answers};
    use quiver_rt::traverse::{reference, Counters, PacketMode};
    use quiver_rt::Ray;
    let mut tris: Vec<Triangle> = (0..16)
        .map(|i| {
            let p = Vec3A::new((i % 4) as f32, (i / 4) as f32, 0.0) - 1.5;
            Triangle::new(p, p + Vec3A::X * 0.8, p + Vec3A::Y * 0.8)
        })
        .collect();
    // A large triangle at distance `s` along `axis` (sign `sign`), spanning about 110°; at
    // s = f32::MAX / 4 its coordinates reach 2s, its extent 3s: finite, their sum is not.
    let ahead = |s: f32, axis: usize, sign: f32| {
        let at = |a: f32, b: f32, c: f32| {
            let mut v = [0.0; 3];
            v[axis] = sign * c * s;
            v[(axis + 1) % 3] = a * s;
            v[(axis + 2) % 3] = b * s;
            Vec3A::from(v)
        };
        Triangle::new(at(-1.0, -1.0, 1.0), at(2.0, -1.0, 1.1), at(-1.0, 2.0, 1.2))
    };
    let huge = [
        (1e15f32, 2, 1.0),
        (1e20, 2, -1.0),
        (1e30, 0, 1.0),
        (f32::MAX / 4.0, 0, -1.0),
    ];
    let mut far: Vec<u32> = Vec::new();
    for (s, axis, sign) in huge {
        far.push(tris.len() as u32);
        tris.push(ahead(s, axis, sign));
    }
    let tiny = 1e-30f32;
    for k in 0..4 {
        let p = Vec3A::new(k as f32 * 4.0 * tiny, 0.0, -0.5);
        far.push(tris.len() as u32);
        tris.push(Triangle::new(p, p + Vec3A::X * tiny, p + Vec3A::Y * tiny));
    }
    // Coherent bundles of eight toward every far triangle, then rays in every direction.
    let mut rays: Vec<Ray> = Vec::new();
    for (s, axis, sign) in huge {
        for j in 0..16 {
            let mut d = [
                0.05 * (j % 4) as f32 - 0.1,
                0.05 * (j / 4) as f32 - 0.1,
                0.0,
            ];
            d.rotate_right(axis + 1);
            d[axis] = sign;
            rays.push(Ray::new(
                Vec3A::new(0.1, 0.2, 0.3) * (j as f32) + 3.0 * s.min(1.0),
                Vec3A::from(d),
            ));
        }
    }
    for k in 0..4 {
        for j in 0..8 {
            let o = Vec3A::new(
                (k as f32 * 4.0 + 0.2 + 0.05 * j as f32) * tiny,
                0.3 * tiny,
                -1.0,
            );
            rays.push(Ray::new(o, Vec3A::Z));
        }
    }
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
    };
    for _ in 0..1024 {
        let o = Vec3A::new(next(), next(), next()) * 3.0;
        let d = Vec3A::new(next(), next(), next());
        rays.push(Ray::new(o, d));
    }

    let oracle = quiver_lab::oracle::Oracle::new(&tris);
    let want: Vec<_> = rays
        .iter()
        .map(|r| reference::closest_hit(&tris, r))
        .collect();
    for (ray, w) in rays.iter().zip(&want) {
        let answer = oracle.closest_hit(ray);
        if answer.is_decidable() {
            answer
                .check(*w)
                .unwrap_or_else(|e| panic!("reference on {ray:?}: {e}"));
        }
    }
    for prim in &far {
        assert!(
            want.iter().flatten().any(|h| h.prim == *prim),
            "triangle {prim} is never hit"
        );
    }
    let wt: Vec<Watertight> = tris.iter().copied().map(Watertight).collect();
    let want_wt: Vec<_> = rays
        .iter()
        .map(|r| reference::closest_hit(&wt, r))
        .collect();
    for prim in &far {
        assert!(
            want_wt.iter().flatten().any(|h| h.prim == *prim),
            "watertight: {prim} never hit"
        );
    }
    fn check<P: Primitive>(prims: &[P], rays: &[Ray], want: &[Option<Hit>], what: &str) {
        let occluded: Vec<bool> = rays.iter().map(|r| reference::any_hit(prims, r)).collect();
        for layout in Layout::ALL {
            let laid_out = Bvh::build(prims, &BuildOptions::default().layout(layout)).unwrap();
            each_isa(&laid_out, |bvh, isa| {
                let at = format!("{what} {layout} {isa}");
                for (i, ray) in rays.iter().enumerate() {
                    assert_eq!(bvh.closest_hit(ray), want[i], "{at}: ray {i} {ray:?}");
                    assert_eq!(bvh.any_hit(ray), occluded[i], "{at}: any, ray {i}");
                    let mut c = Counters::default();
                    assert_eq!(
                        bvh.closest_hit_counted(ray, &mut c),
                        want[i],
                        "{at}: counted"
                    );
                    assert_eq!(
                        bvh.any_hit_counted(ray, &mut c),
                        occluded[i],
                        "{at}: counted any"
                    );
                }
                for mode in [PacketMode::Always, PacketMode::Auto] {
                    let (hits, occ) = packet_answers(bvh, rays, mode);
                    assert_eq!(hits, want, "{at}: packets {mode:?}");
                    assert_eq!(occ, occluded, "{at}: packets {mode:?} any");
                }
            });
        }
    }
    check(&tris, &rays, &want, "fast");
    check(&wt, &rays, &want_wt, "watertight");

    // The same triangles as one geometry of a world, placed as they are: the world answers
    // what the reference answers. Before world boxes were padded in halves, the f32::MAX / 4
    // triangle's box overflowed to infinity and the world dropped the whole instance.
    for layout in Layout::ALL {
        let mut b = quiver_rt::World::builder();
        let g = b.add_triangles(tris.clone());
        b.add_instance(quiver_rt::Instance::of(g));
        let world = b
            .build(&BuildOptions::default().layout(layout))
            .expect("a world");
        for (i, ray) in rays.iter().enumerate() {
            let got = world.closest_hit(ray).map(|h| (h.prim, h.t, h.u, h.v));
            let w = want[i].map(|h| (h.prim, h.t, h.u, h.v));
            assert_eq!(got, w, "world {layout}: ray {i}");
            assert_eq!(
                world.any_hit(ray),
                want[i].is_some(),
                "world {layout}: any, ray {i}"
            );
        }
    }

    // Refit into far groups and out again: a BVH over unit-sized stand-ins for the far
    // triangles, refit to the mixed scene, answers as the reference does there, and back home.
    let home: Vec<Triangle> = (0..tris.len())
        .map(|i| match far.iter().position(|&f| f as usize == i) {
            Some(k) => {
                let p = Vec3A::new(6.0 + k as f32, 0.0, 0.0);
                Triangle::new(p, p + Vec3A::X, p + Vec3A::Y)
            }
            None => tris[i],
        })
        .collect();
    let want_home: Vec<_> = rays
        .iter()
        .map(|r| reference::closest_hit(&home, r))
        .collect();
    for layout in crate::common::WIDE {
        let mut bvh = Bvh::build(&home, &BuildOptions::default().layout(layout)).unwrap();
        for (prims, want, what) in [
            (&tris, &want, "refit far"),
            (&home, &want_home, "refit home"),
        ] {
            bvh.refit(prims).expect("same count, finite");
            for (i, ray) in rays.iter().enumerate() {
                assert_eq!(bvh.closest_hit(ray), want[i], "{what} {layout}: ray {i}");
            }
        }
    }
}
