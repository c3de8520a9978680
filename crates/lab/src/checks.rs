//! Self-checks driven by arbitrary bytes: what the cargo-fuzz targets in `fuzz/` run, and what
//! `tests/fuzz_regressions.rs` replays for every committed reproducer. Each panics (the
//! fuzzer's signal) only when quiver is wrong: a crash, or, where the input is finite, an
//! answer the independent f64 oracle ([`crate::oracle`]) does not admit.
//!
//! ```
//! quiver_lab::checks::build_and_trace(&[0u8; 200]);
//! quiver_lab::checks::packets_against_oracle(&[9u8; 300]);
//! quiver_lab::checks::nff_round_trip(b"f 1 1 1 1 0 0 0 1\ns 0 0 0 1\n");
//! quiver_lab::checks::analytic_lanes(&[7u8; 400]);
//! quiver_lab::checks::obj_load(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
//! quiver_lab::checks::render_nff(b"v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 45\nhither 1\nresolution 8 8\nl 1 1 5\nf 1 1 1 1 0 0 0 1\ns 0 0 0 1\n");
//! ```

use crate::oracle::{Answer, Oracle};
use glam::Vec3A;
use quiver_rt::builders::{BuildConfig, Builder};
use quiver_rt::intersect::Watertight;
use quiver_rt::traverse::{
    BoxTest, ConservativeBoxes, FastBoxes, Filter, NoFilter, NoStats, PacketMode, PacketQuery,
};
use quiver_rt::{BuildOptions, Bvh, Isa, Layout, Primitive, Ray, RayQuery, Triangle};

/// Reads little-endian f32s from the bytes; NaN, infinities, huge and subnormal values all
/// come through as they are.
fn floats(data: &[u8]) -> Vec<f32> {
    data.chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

/// What one fuzz input chooses, each from a byte (or bit) of its own so that every
/// combination is reachable: layout, largest leaf (1 to 16), builder, intersector, and whether
/// its numbers are tame.
#[derive(Clone, Copy, Debug)]
struct Setup {
    layout: Layout,
    max_leaf: usize,
    builder: Builder,
    watertight: bool,
    /// Every coordinate finite and zero or of magnitude `2^-20..2^21` (the input's floats with
    /// their exponents clamped): the domain where an f32 kernel has a rounding model, so the
    /// oracle judges every answer. Raw inputs (NaN, infinities, subnormals, 1e38) are held to
    /// what holds everywhere: no panic, valid trees, bit-identical instruction sets, packets
    /// that answer only their active rays.
    tame: bool,
}

/// Exponent bound of tame numbers (see [`Setup::tame`]).
const TAME_EXPONENT: i32 = 20;

/// `x` made tame: non-finite and tiny values become zero, others keep sign and mantissa with
/// the exponent clamped to `±TAME_EXPONENT`.
fn tame(x: f32) -> f32 {
    if !x.is_finite() || x.abs() < 2f32.powi(-TAME_EXPONENT) {
        return 0.0;
    }
    let bits = x.to_bits();
    let e = (((bits >> 23) & 0xff) as i32 - 127).clamp(-TAME_EXPONENT, TAME_EXPONENT);
    f32::from_bits((bits & 0x807f_ffff) | (((e + 127) as u32) << 23))
}

/// Bytes before the floats: triangle count, then the [`Setup`] bytes.
const HEADER: usize = 5;

/// The setup, triangles and rays of a fuzz input: byte 0 the number of triangles (up to 63),
/// bytes 1–4 the [`Setup`] (byte 4: bit 0 watertight, bit 1 tame), then little-endian f32s, nine per triangle and eight per ray
/// (origin, direction, and the interval's ends in either order).
fn fuzz_input(data: &[u8]) -> Option<(Setup, Vec<Triangle>, Vec<Ray>)> {
    if data.len() < HEADER {
        return None;
    }
    let setup = Setup {
        layout: Layout::ALL[data[1] as usize % Layout::ALL.len()],
        max_leaf: 1 + data[2] as usize % 16,
        builder: Builder::ALL[data[3] as usize % Builder::ALL.len()],
        watertight: data[4] & 1 == 1,
        tame: data[4] & 2 == 2,
    };
    let mut f = floats(&data[HEADER..]);
    if setup.tame {
        f.iter_mut().for_each(|x| *x = tame(*x));
    }
    let tris: Vec<Triangle> = f
        .chunks_exact(9)
        .take(data[0] as usize % 64)
        .map(|c| {
            Triangle::new(
                Vec3A::new(c[0], c[1], c[2]),
                Vec3A::new(c[3], c[4], c[5]),
                Vec3A::new(c[6], c[7], c[8]),
            )
        })
        .collect();
    let rest = &f[(tris.len() * 9).min(f.len())..];
    let rays: Vec<Ray> = rest
        .chunks_exact(8)
        .map(|c| {
            let (t0, t1) = (c[6].abs(), c[7].abs());
            Ray::segment(
                Vec3A::new(c[0], c[1], c[2]),
                Vec3A::new(c[3], c[4], c[5]),
                t0.min(t1),
                t0.max(t1),
            )
        })
        .collect();
    Some((setup, tris, rays))
}

/// The BVH a setup asks for over `tris`, as fast or watertight triangles, with its tree
/// checked against the build's invariants.
fn fuzz_bvh<P: Primitive>(setup: Setup, tris: &[Triangle], wrap: fn(Triangle) -> P) -> Bvh<P> {
    let prims: Vec<P> = tris.iter().map(|&t| wrap(t)).collect();
    let config = BuildConfig {
        max_leaf_size: setup.max_leaf,
        ..BuildConfig::default()
    };
    let (bvh, tree) = Bvh::build_with_tree(
        &prims,
        &BuildOptions::default()
            .builder(setup.builder)
            .layout(setup.layout)
            .config(config.clone()),
    )
    .unwrap();
    tree.check(&quiver_rt::builders::prim_bounds(&prims), &config)
        .expect("tree invariants");
    bvh
}

/// True for a ray the oracle can judge: every number finite (NaN or infinite rays have no
/// f64 answer; they must only not crash).
fn judgeable(r: &Ray) -> bool {
    r.origin.is_finite() && r.dir.is_finite() && r.t_min.is_finite() && !r.t_max.is_nan()
}

/// Triangles and rays from the bytes, a BVH as the input's setup bytes choose. Nothing may
/// panic, trees must be valid and every instruction set must give bit-identical answers; on
/// tame inputs every query must also answer as the independent f64 oracle
/// ([`crate::oracle`]) admits — the same primitive, `t`, `u` and `v` on decidable rays, one of
/// the admissible answers on rays in its tie or edge band — any-hit must agree, and packets
/// must give the single-ray answer.
pub fn build_and_trace(data: &[u8]) {
    let Some((setup, tris, rays)) = fuzz_input(data) else {
        return;
    };
    if setup.watertight {
        trace_against_oracle(setup, &tris, &rays, fuzz_bvh(setup, &tris, Watertight));
    } else {
        trace_against_oracle(setup, &tris, &rays, fuzz_bvh(setup, &tris, |t| t));
    }
}

fn trace_against_oracle<P: Primitive>(setup: Setup, tris: &[Triangle], rays: &[Ray], bvh: Bvh<P>) {
    let oracle = Oracle::new(tris);
    let answers: Vec<Option<Answer>> = rays
        .iter()
        .map(|r| (setup.tame && judgeable(r)).then(|| oracle.closest_hit(r)))
        .collect();
    for (r, answer) in rays.iter().zip(&answers) {
        let got = bvh.closest_hit(r);
        let any = bvh.any_hit(r);
        if let Some(answer) = answer {
            if let Err(e) = answer.check(got) {
                panic!("{setup:?} {r:?}: {e}");
            }
            if answer.is_decidable() {
                assert_eq!(any, answer.hit.is_some(), "{setup:?} any-hit {r:?}");
            }
        }
    }
    if setup.tame {
        same_in_packets(&bvh, rays, &answers, &format!("{setup:?}"));
    }
    same_on_every_isa(&bvh, rays, &format!("{setup:?}"));
}

/// Packets against the oracle: triangles and rays from the bytes as for [`build_and_trace`],
/// traced as packets (some rays inactive, chosen by the rays' own bits): every inactive ray
/// must get no answer, and on tame inputs every active ray's packet answer must be one the
/// oracle admits.
pub fn packets_against_oracle(data: &[u8]) {
    let Some((setup, tris, rays)) = fuzz_input(data) else {
        return;
    };
    if setup.watertight {
        packets_check(setup, &tris, &rays, &fuzz_bvh(setup, &tris, Watertight));
    } else {
        packets_check(setup, &tris, &rays, &fuzz_bvh(setup, &tris, |t| t));
    }
}

/// A hit's fields as bits, so NaN and signed zeros compare exactly.
fn hit_bits(h: Option<quiver_rt::Hit>) -> Option<(u32, u32, u32, u32)> {
    h.map(|h| (h.t.to_bits(), h.prim, h.u.to_bits(), h.v.to_bits()))
}

fn packets_check<P: Primitive>(setup: Setup, tris: &[Triangle], rays: &[Ray], bvh: &Bvh<P>) {
    let active: Vec<bool> = rays.iter().map(|r| r.origin.x.to_bits() % 7 != 3).collect();
    let mut hits = vec![None; rays.len()];
    let mut occluded = vec![false; rays.len()];
    let oracle = Oracle::new(tris);
    // Every input, tame or raw: the portable lanes give the AVX2 lanes' answers bit for bit
    // (the same operations in the same order).
    let portable = bvh.clone().with_isa(Isa::Portable);
    portable.closest_hit_packet_with::<FastBoxes, _, _>(
        PacketQuery::new(rays)
            .active(&active)
            .mode(PacketMode::Always),
        &mut hits,
        &mut NoStats,
        &mut NoFilter,
    );
    let on_portable = hits.clone();
    bvh.closest_hit_packet_with::<FastBoxes, _, _>(
        PacketQuery::new(rays)
            .active(&active)
            .mode(PacketMode::Always),
        &mut hits,
        &mut NoStats,
        &mut NoFilter,
    );
    for (i, (a, b)) in hits.iter().zip(&on_portable).enumerate() {
        assert_eq!(
            hit_bits(*a),
            hit_bits(*b),
            "{setup:?} AVX2 vs portable packet ray {i}"
        );
    }
    for mode in [PacketMode::Always, PacketMode::Auto] {
        bvh.closest_hit_packet_with::<FastBoxes, _, _>(
            PacketQuery::new(rays).active(&active).mode(mode),
            &mut hits,
            &mut NoStats,
            &mut NoFilter,
        );
        bvh.any_hit_packet_with::<FastBoxes, _, _>(
            PacketQuery::new(rays).active(&active).mode(mode),
            &mut occluded,
            &mut NoStats,
            &mut NoFilter,
        );
        for (i, r) in rays.iter().enumerate() {
            if !active[i] {
                assert!(
                    hits[i].is_none() && !occluded[i],
                    "{setup:?} inactive ray {i} answered"
                );
                continue;
            }
            if setup.tame && judgeable(r) {
                let answer = oracle.closest_hit(r);
                if let Err(e) = answer.check(hits[i]) {
                    panic!("{setup:?} {mode:?} packet ray {i} {r:?}: {e}");
                }
                if answer.is_decidable() {
                    assert_eq!(
                        occluded[i],
                        answer.hit.is_some(),
                        "{setup:?} packet any {r:?}"
                    );
                    // Where f32 rounding cannot change the answer, the packet's is the single
                    // ray's bit for bit. (In a band, a hit the rounding puts outside its leaf
                    // box is found or not depending on the order leaves are visited, which a
                    // packet's first ray sets: fuzz/artifacts/packets/crash-942a…, a 1.5e6
                    // triangle hit 0.03 before its box.)
                    let single =
                        bvh.closest_hit_with::<FastBoxes, _, _>(r, &mut NoStats, &mut NoFilter);
                    assert_eq!(
                        hit_bits(hits[i]),
                        hit_bits(single),
                        "{setup:?} {mode:?} packet vs single ray {i} {r:?}"
                    );
                }
            }
        }
    }
}

/// Whether every number that decides where a scene's rays go (object bounds, lights, the
/// camera) is finite and at most `2^TAME_EXPONENT` in magnitude: where packets and single rays
/// must draw the same image. Beyond it a rounded hit can lie outside its leaf's box (a
/// triangle 1e7 across hit at a vertex it shares, its `t` 40 ulps early), and which of two
/// such hits a walk keeps depends on the order it visits leaves, which packets and single rays
/// choose differently: the undecidable rays [`packets_against_oracle`] exempts, here for a
/// whole scene (fuzz/artifacts/render/crash-2e1d…: a mirror ray in a scene with a sphere of
/// radius 1.7e7).
fn tame_scene(scene: &quiver_scenes::Scene) -> bool {
    let limit = 2f32.powi(TAME_EXPONENT);
    let ok = |v: Vec3A| v.is_finite() && v.abs().max_element() <= limit;
    let b = scene.bounds();
    (b.is_empty() || (ok(b.min) && ok(b.max)))
        && scene.lights.iter().all(|l| ok(l.pos))
        && ok(scene.camera.from)
        && ok(scene.camera.at)
}

/// Small NFF scenes from the bytes, rendered: parsing and rendering must not panic, and packets
/// on and off must trace the same rays and draw the same image wherever the scene is tame
/// (object bounds, lights and camera finite and within `2^20`: beyond that a rounded hit can
/// lie outside its leaf's box, and which of two such hits a walk keeps depends on its leaf
/// order). Scenes over a size limit are skipped (the fuzzer's time goes into variety, not
/// into one big render).
pub fn render_nff(data: &[u8]) {
    use quiver_scenes::accel::SceneBvh;
    use quiver_scenes::render::{render, RenderConfig};
    let text = String::from_utf8_lossy(data);
    let Ok(scene) = quiver_scenes::scene::nff::parse(&text, "fuzz.nff") else {
        return;
    };
    if scene.objects.len() > 64 || scene.lights.len() > 8 {
        return;
    }
    for patches in [false, true] {
        let scene = if patches {
            scene.clone().into_patches(4)
        } else {
            scene.clone()
        };
        let bvh = if patches {
            SceneBvh::build_triangles(&scene, &BuildOptions::default())
        } else {
            SceneBvh::build(&scene, &BuildOptions::default())
        }
        .expect("the default options are in range");
        let run = |packets: bool| {
            let config = RenderConfig {
                res: 8,
                max_depth: 3,
                two_sided: scene.two_sided_materials(),
                packets,
                ..RenderConfig::default()
            };
            render(&scene, &bvh, &config, &|_| {})
        };
        let (on, off) = (run(true), run(false));
        if tame_scene(&scene) {
            assert_eq!(on.rays, off.rays, "patches {patches}: ray counts");
            assert_eq!(on.rgb, off.rgb, "patches {patches}: pixels");
        }
    }
}

/// A sphere's and a cone's eight-ray tests (`intersect_lanes`, what packets run) give each
/// lane exactly the scalar test's answer, bit for bit, on any numbers: the bytes make a
/// sphere, a cone and eight rays, NaN, infinities and all, and a second round repeats them
/// with tame numbers (as [`packets_against_oracle`] tames them), where most rays meet the
/// shapes: each ray aims at the shape's centre.
pub fn analytic_lanes(data: &[u8]) {
    use quiver_rt::primitive::PacketLanes;
    use quiver_scenes::primitive::{Cone, Sphere};
    let f = floats(data);
    if f.len() < 12 + 8 * 8 {
        return;
    }
    for tamed in [false, true] {
        let g = |i: usize| if tamed { tame(f[i]) } else { f[i] };
        let v = |i: usize| Vec3A::new(g(i), g(i + 1), g(i + 2));
        let sphere = Sphere {
            center: v(0),
            radius: g(3).abs(),
        };
        let cone = Cone {
            base: v(4),
            base_radius: g(7).abs(),
            apex: v(8),
            apex_radius: g(11).abs(),
        };
        let rays: [Ray; 8] = std::array::from_fn(|k| {
            let at = 12 + 8 * k;
            let (o, d) = (v(at), v(at + 3));
            // Tame rays point from their origin toward the shapes, off by `d`.
            let d = if tamed {
                (sphere.center + cone.base) * 0.5 - o + d * 0.01
            } else {
                d
            };
            Ray::segment(o, d, g(at + 6), g(at + 7))
        });
        let lanes = PacketLanes::from_rays(&rays);
        let lane_answers = [
            ("sphere", sphere.intersect_lanes(&lanes)),
            ("cone", cone.intersect_lanes(&lanes)),
        ];
        for (what, (mask, t)) in lane_answers {
            let t = t.to_array();
            for (l, r) in rays.iter().enumerate() {
                let want = match what {
                    "sphere" => sphere.intersect(r),
                    _ => cone.intersect(r),
                };
                let got = (mask >> l & 1 == 1).then(|| t[l].to_bits());
                assert_eq!(got, want.map(|h| h.t.to_bits()), "{what} lane {l}: {r:?}");
            }
        }
    }
}

/// Every ray's closest hit from `q`, traced in packets (`PacketMode::Always`) with box test
/// `B` through `filter`.
fn closest_in_packets<B: BoxTest, Q: RayQuery, F: Filter<Q::Hit>>(
    q: &Q,
    rays: &[Ray],
    filter: &mut F,
) -> Vec<Option<Q::Hit>> {
    let mut hits: Vec<Option<Q::Hit>> = rays.iter().map(|_| None).collect();
    q.closest_hit_packet_with::<B, _, _>(
        PacketQuery::new(rays).mode(PacketMode::Always),
        &mut hits,
        &mut NoStats,
        filter,
    );
    hits
}

/// The portable and the best supported kernels give bit-identical answers for every ray,
/// rounding artifacts included: they compute the same floats.
fn same_on_every_isa<P: Primitive>(bvh: &Bvh<P>, rays: &[Ray], what: &str) {
    let portable = bvh.clone().with_isa(Isa::Portable);
    let best = bvh.clone().with_isa(Isa::best());
    for r in rays {
        assert_eq!(portable.closest_hit(r), best.closest_hit(r), "{what} {r:?}");
        assert_eq!(portable.any_hit(r), best.any_hit(r), "{what} any {r:?}");
    }
}

/// The packet kernels give every ray exactly the single-ray answer, with some rays inactive —
/// except on a ray the oracle finds ambiguous, where both answers must be admissible: the two
/// kernels visit leaves in different orders, so a box pruned at one's current best distance
/// may hold an admissible hit the other tested first.
fn same_in_packets<P: Primitive>(
    bvh: &Bvh<P>,
    rays: &[Ray],
    answers: &[Option<Answer>],
    what: &str,
) {
    let active: Vec<bool> = (0..rays.len()).map(|i| i % 5 != 3).collect();
    let mut hits = vec![None; rays.len()];
    let mut occluded = vec![false; rays.len()];
    let mode = PacketMode::Always;
    bvh.closest_hit_packet_with::<FastBoxes, _, _>(
        PacketQuery::new(rays).active(&active).mode(mode),
        &mut hits,
        &mut NoStats,
        &mut NoFilter,
    );
    bvh.any_hit_packet_with::<FastBoxes, _, _>(
        PacketQuery::new(rays).active(&active).mode(mode),
        &mut occluded,
        &mut NoStats,
        &mut NoFilter,
    );
    for (i, r) in rays.iter().enumerate() {
        let (want, want_any) = match active[i] {
            true => (bvh.closest_hit(r), bvh.any_hit(r)),
            false => (None, false),
        };
        match &answers[i] {
            Some(a) if active[i] && !a.is_decidable() => {
                if let Err(e) = a.check(hits[i]) {
                    panic!("{what} packet closest {r:?}: {e}");
                }
            }
            _ => {
                assert_eq!(hits[i], want, "{what} packet closest {r:?}");
                assert_eq!(occluded[i], want_any, "{what} packet any {r:?}");
            }
        }
    }
}

/// NFF text from the bytes: parsing must not panic, and what parses must write and read back
/// to the same scene.
pub fn nff_round_trip(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    if let Ok(scene) = quiver_scenes::scene::nff::parse(&text, "fuzz.nff") {
        let mut out = Vec::new();
        quiver_scenes::scene::nff::write(&scene, &mut out).expect("writing to memory");
        let back =
            quiver_scenes::scene::nff::parse(std::str::from_utf8(&out).expect("utf-8"), "back.nff")
                .expect("own output parses");
        assert_eq!(back.objects.len(), scene.objects.len());
        for (a, b) in back.objects.iter().zip(&scene.objects) {
            // The writer writes the materials objects use, so compare them through the objects.
            assert_eq!(a.shape, b.shape);
            assert_eq!(
                back.materials[a.material as usize],
                scene.materials[b.material as usize]
            );
        }
        assert_eq!(back.lights, scene.lights);
    }
}

/// An OBJ file with the bytes as content: see [`mesh_load`].
pub fn obj_load(data: &[u8]) {
    mesh_load(data, "obj");
}

/// A PLY file with the bytes as content (`.ply.gz` when they start with gzip's magic, so the
/// inflating path is fuzzed too): see [`mesh_load`]. A first byte of 0xFF (no PLY, gzip or
/// glTF file starts so) selects the structure-aware mode instead ([`ply_structured`]).
///
/// ```
/// quiver_lab::checks::ply_load(b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
///     property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\n\
///     end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
/// ```
pub fn ply_load(data: &[u8]) {
    if let Some((0xFF, rest)) = data.split_first() {
        return ply_structured_load(rest);
    }
    mesh_load(
        data,
        if data.starts_with(&[0x1f, 0x8b]) {
            "ply.gz"
        } else {
            "ply"
        },
    );
}

/// A glTF file with the bytes as content (`.glb` when they start with `glTF`, else `.gltf`):
/// see [`mesh_load`]. A first byte of 0xFF selects the structure-aware mode instead
/// ([`gltf_structured`]).
///
/// ```
/// quiver_lab::checks::gltf_load(br#"{"asset": {"version": "2.0"}}"#);
/// ```
pub fn gltf_load(data: &[u8]) {
    if let Some((0xFF, rest)) = data.split_first() {
        return gltf_structured_load(rest);
    }
    mesh_load(
        data,
        if data.starts_with(b"glTF") {
            "glb"
        } else {
            "gltf"
        },
    );
}

/// A mesh file with the bytes as content and the extension `ext`, loaded strictly and with
/// non-finite primitives dropped: neither may panic; what loads must have groups in object
/// order, non-empty, disjoint and within the objects, a dropping load must keep every
/// triangle of a strict one, and a loaded mesh must build and trace, judged by the oracle.
pub fn mesh_load(data: &[u8], ext: &str) {
    use quiver_scenes::scene::{LoadOptions, NonFinite, Scene};
    use std::sync::atomic::{AtomicUsize, Ordering};
    static N: AtomicUsize = AtomicUsize::new(0);
    // A directory of its own, so a relative glTF buffer URI finds nothing by accident.
    let dir = std::env::temp_dir().join(format!(
        "quiver-fuzz-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    let path = dir.join(format!("input.{ext}"));
    if std::fs::create_dir_all(&dir).is_err() || std::fs::write(&path, data).is_err() {
        return;
    }
    let spec = path.to_str().unwrap_or_default();
    let loaded = Scene::load(spec);
    let lax = LoadOptions::default().non_finite(NonFinite::Drop);
    let dropping = Scene::load_with(spec, &lax);
    let _ = std::fs::remove_dir_all(&dir);
    for scene in loaded.iter().chain(dropping.iter().map(|(s, _)| s)) {
        let mut end = 0;
        for g in &scene.groups {
            assert!(
                g.objects.start >= end && g.objects.start < g.objects.end,
                "{g:?} after {end}"
            );
            end = g.objects.end;
        }
        assert!(
            end as usize <= scene.objects.len(),
            "groups past the objects"
        );
    }
    match (&loaded, &dropping) {
        (Ok(strict), Ok((lax, report))) => {
            assert!(
                report.is_empty(),
                "a strict load succeeded, yet the lax one dropped"
            );
            assert_eq!(strict.objects, lax.objects);
        }
        (Ok(_), Err(e)) => panic!("a strict load succeeded, yet the lax one failed: {e}"),
        _ => {}
    }
    if let Ok(scene) = loaded {
        let tris = scene.triangles();
        let bvh = Bvh::new(&tris);
        let ray = scene.camera.ray(0.0, 0.0);
        let tame_coord = |x: f32| x == 0.0 || x.abs() == tame(x).abs();
        let is_tame = tris
            .iter()
            .flat_map(|t| t.v)
            .chain([ray.origin, ray.dir])
            .all(|p| p.to_array().into_iter().all(tame_coord));
        if is_tame {
            // Judged by the independent oracle, as `build_and_trace` judges tame input.
            if let Err(e) = Oracle::new(&tris)
                .closest_hit(&ray)
                .check(bvh.closest_hit(&ray))
            {
                panic!("{ray:?}: {e}");
            }
        }
    }
}

/// Worlds of instances against the flattened oracle: triangles and rays from the bytes as
/// for [`build_and_trace`], the triangles dealt round-robin into one to three geometries
/// (the second given as an indexed mesh) placed by one to eight instances whose geometry,
/// mask and transform (identity, or a rotation, an uneven scale of 1/4 to 4 that may mirror,
/// and a move) come from the input's last bytes, read backwards; rays carry one of three
/// masks and, if the input says so, a filter rejects every third (instance, primitive). Nothing
/// may panic and both instruction sets must agree bit for bit; on tame inputs every closest
/// hit, single and in packets, names the instance, geometry and primitive the f64 oracle
/// finds over the flattened scene with the masked and rejected triangles left out (bands
/// widened by the transforms' rounding), and any-hit agrees on decidable rays. Then bytes
/// further on set instances moving, and the moving world at each ray's time must answer as
/// the scene placed at that time (`moving_against_rebuilt`); bytes further still make
/// geometries moving meshes of 2 to 5 steps (drifted, scaled and jittered: they change
/// shape), some instances moving too, and every ray must answer as the f64 oracle over the
/// scene with each mesh interpolated to the ray's time admits, point queries as the point
/// oracle does (`deforming_against_oracle`). Both motion checks shoot rays at times out of
/// the shutter and NaN too, which must answer as their clamp (`Ray::shutter_time`) into
/// `[0, 1]`. And the bytes after the instances' drive a sequence of edits, and the edited
/// world must answer as the same state built afresh (`edits_against_rebuilt`).
///
/// ```
/// quiver_lab::checks::instanced_against_oracle(&[7u8; 500]);
/// ```
pub fn instanced_against_oracle(data: &[u8]) {
    instanced_judged(data);
}

/// [`instanced_against_oracle`], reporting what its moving meshes' check did
/// ([`deforming_against_oracle`]): what the test of the seeds that reach them reads.
fn instanced_judged(data: &[u8]) -> Deformed {
    use crate::worlds::{check, Placements};
    use glam::{Affine3A, Quat, Vec3};
    use quiver_rt::{GeometryId, Instance, WorldHit};
    let Some((setup, tris, rays)) = fuzz_input(data) else {
        return Deformed::default();
    };
    let control: Vec<u8> = data[HEADER..].iter().rev().copied().collect();
    let byte = |k: usize| control.get(k).copied().unwrap_or(0);
    let geometries_n = 1 + (data[4] >> 2) as usize % 3;
    let instances_n = 1 + (data[4] >> 4) as usize % 8;
    let filtering = data[4] & 0x80 != 0;
    let mut geometries = vec![Vec::new(); geometries_n];
    for (k, t) in tris.iter().enumerate() {
        geometries[k % geometries_n].push(*t);
    }
    let instances: Vec<Instance> = (0..instances_n)
        .map(|i| {
            let b = |k: usize| byte(12 * i + k);
            let unit = |x: u8| x as f32 / 255.0;
            let geometry = GeometryId(b(0) as u32 % geometries_n as u32);
            let mask = [u32::MAX, 0b01, 0b10, 0b11][b(1) as usize % 4];
            let transform = if b(2) % 4 == 0 {
                Affine3A::IDENTITY
            } else {
                let axis = Vec3::new(unit(b(3)) - 0.5, unit(b(4)) - 0.5, unit(b(5)) - 0.5)
                    .normalize_or(Vec3::Z);
                let angle = unit(b(6)) * std::f32::consts::TAU;
                let mut scale = Vec3::new(b(7) as f32, b(8) as f32, b(9) as f32) / 68.0 + 0.25;
                if b(2) & 4 != 0 {
                    scale.x = -scale.x;
                }
                let at = Vec3::new(b(10) as f32 - 128.0, b(11) as f32 - 128.0, b(3) as f32) / 16.0;
                Affine3A::from_scale_rotation_translation(
                    scale,
                    Quat::from_axis_angle(axis, angle),
                    at,
                )
            };
            Instance::of(geometry).transform(transform).mask(mask)
        })
        .collect();
    let placements = Placements {
        geometries,
        instances,
    };
    let config = BuildConfig {
        max_leaf_size: setup.max_leaf,
        ..BuildConfig::default()
    };
    let options = BuildOptions::default()
        .builder(setup.builder)
        .layout(setup.layout)
        .config(config);
    let world = placements.world(&options);
    let portable = placements.world(&options.clone().isa(Isa::Portable));
    let ray_masks = [u32::MAX, 0b01, 0b10];
    let rays: Vec<Ray> = rays
        .iter()
        .enumerate()
        .map(|(i, r)| r.with_mask(ray_masks[i % 3]))
        .collect();
    let keep = |instance: u32, prim: u32| !(filtering && (instance * 7 + prim).is_multiple_of(3));
    let mut filter = |h: &WorldHit| keep(h.instance.0, h.prim);
    // One oracle per ray mask: the flattened scene without the masked and rejected triangles.
    let judged: Vec<_> = ray_masks
        .iter()
        .map(|&m| {
            let (flat, names) = placements
                .flattened(|i, p| placements.instances[i as usize].mask & m != 0 && keep(i, p));
            (Oracle::with_slack(&flat, placements.slack()), names)
        })
        .collect();
    let hits = closest_in_packets::<FastBoxes, _, _>(&world, &rays, &mut filter);
    for (i, r) in rays.iter().enumerate() {
        let got = world.closest_hit_filtered(r, &mut filter);
        let any = world.any_hit_filtered(r, &mut filter);
        assert_eq!(
            got,
            portable.closest_hit_filtered(r, &mut filter),
            "isa {r:?}"
        );
        assert_eq!(
            any,
            portable.any_hit_filtered(r, &mut filter),
            "isa any {r:?}"
        );
        if !(setup.tame && judgeable(r)) {
            continue;
        }
        let (oracle, names) = &judged[i % 3];
        let answer = oracle.closest_hit(r);
        if let Err(e) = check(&answer, got, names) {
            panic!("{setup:?} {placements:?} {r:?}: {e}");
        }
        if let Err(e) = check(&answer, hits[i], names) {
            panic!("{setup:?} {placements:?} packet {r:?}: {e}");
        }
        if answer.is_decidable() {
            assert_eq!(any, answer.hit.is_some(), "{setup:?} any-hit {r:?}");
        }
    }
    let motion = control.get(128..).unwrap_or(&[]);
    moving_against_rebuilt(motion, &placements, &options, &rays, setup.tame);
    let deforming = control.get(160..).unwrap_or(&[]);
    let judged = deforming_against_oracle(deforming, &placements, &options, &rays, setup.tame);
    let ops = control.get(96..).unwrap_or(&[]);
    edits_against_rebuilt(ops, placements, &options, &rays, setup.tame);
    judged
}

/// Motions for `instances` from `bytes`, two an instance: none, a drift and growth between
/// two keys, or a decomposed turn of up to 0.45 of a turn a step about an axis the bytes
/// pick, over three keys.
fn fuzz_motions(bytes: &[u8], instances: &[quiver_rt::Instance]) -> Vec<Option<quiver_rt::Motion>> {
    use glam::{Affine3A, Vec3};
    use quiver_rt::Motion;
    let byte = |k: usize| bytes.get(k).copied().unwrap_or(0);
    instances
        .iter()
        .enumerate()
        .map(|(i, inst)| {
            let (kind, v) = (byte(2 * i), byte(2 * i + 1));
            let base = inst.transform;
            let amount = (kind / 3) as f32 / 85.0;
            match kind % 3 {
                0 => None,
                1 => {
                    let drift = Vec3::new(v as f32 / 32.0 - 4.0, (v % 7) as f32 * 0.5, 1.0);
                    let grow = Affine3A::from_scale(Vec3::splat(1.0 + amount));
                    Some(Motion::linear(vec![
                        base,
                        Affine3A::from_translation(drift) * base * grow,
                    ]))
                }
                _ => {
                    let axis = [Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE.normalize()][v as usize % 4];
                    let step = amount * 0.45 * std::f32::consts::TAU;
                    let lift = Affine3A::from_translation(Vec3::new(0.0, v as f32 / 64.0, 0.0));
                    Some(Motion::decomposed(vec![
                        base,
                        Affine3A::from_axis_angle(axis, step) * base,
                        lift * Affine3A::from_axis_angle(axis, 2.0 * step) * base,
                    ]))
                }
            }
        })
        .collect()
}

/// The times the motion checks shoot rays at, by a ray's index mod 3: shutter times 0, one
/// between (from a byte: a segment boundary of a mesh of 2 to 5 steps, or `byte / 255`) and
/// 1, the ends mostly carried as times out of the shutter that a ray takes as them
/// ([`quiver_rt::Ray::shutter_time`]: below 0 or NaN for 0, above 1 for 1), cycling through
/// them from an offset another byte picks: never a miss.
struct FuzzTimes {
    /// The shutter times, 0, between, 1.
    shutter: [f32; 3],
    /// Where ray `i`'s out-of-shutter time starts in the cycle.
    skew: usize,
}

impl FuzzTimes {
    fn new(between: u8, skew: u8) -> FuzzTimes {
        let between = match between {
            b if b < 40 => [0.25, 0.5, 0.75, 1.0 / 3.0, 2.0 / 3.0][b as usize % 5],
            b => b as f32 / 255.0,
        };
        FuzzTimes {
            shutter: [0.0, between, 1.0],
            skew: skew as usize,
        }
    }

    /// The time ray `i` carries: one standing for `shutter[i % 3]`.
    fn of_ray(&self, i: usize) -> f32 {
        const BELOW: [f32; 6] = [0.0, -0.5, f32::NEG_INFINITY, f32::NAN, -0.0, -3e38];
        const ABOVE: [f32; 5] = [1.0, 2.0, f32::INFINITY, 1.000_000_1, 3e38];
        let k = i / 3 + self.skew;
        match i % 3 {
            0 => BELOW[k % BELOW.len()],
            1 => self.shutter[1],
            _ => ABOVE[k % ABOVE.len()],
        }
    }

    /// `rays`, ray `i` at [`FuzzTimes::of_ray`]`(i)`.
    fn shoot(&self, rays: &[Ray]) -> Vec<Ray> {
        let rays: Vec<Ray> = rays
            .iter()
            .enumerate()
            .map(|(i, r)| r.with_time(self.of_ray(i)))
            .collect();
        for (i, r) in rays.iter().enumerate() {
            assert_eq!(r.shutter_time(), self.shutter[i % 3], "{r:?}");
        }
        rays
    }
}

/// What each flattened triangle is: (instance, geometry, primitive).
type Names = Vec<(u32, u32, u32)>;

/// The f64 oracles over scenes placed at the shutter times, one per (time, ray mask), each
/// made when first asked for: a ray's answer over the placed scene with the instances its
/// mask leaves out left out.
struct PlacedOracles<'a> {
    placed: &'a [crate::worlds::Placements],
    made: Vec<((usize, u32), Oracle, Names)>,
}

impl<'a> PlacedOracles<'a> {
    fn new(placed: &'a [crate::worlds::Placements]) -> Self {
        PlacedOracles {
            placed,
            made: Vec::new(),
        }
    }

    /// The oracle's answer for `r` over `placed[which]`, and the flattened triangles' names.
    fn answer(&mut self, which: usize, r: &Ray) -> (Answer, &[(u32, u32, u32)]) {
        let key = (which, r.mask);
        let k = match self.made.iter().position(|m| m.0 == key) {
            Some(k) => k,
            None => {
                let p = &self.placed[which];
                let (flat, names) = p.flattened(|i, _| p.instances[i as usize].mask & r.mask != 0);
                self.made
                    .push((key, Oracle::with_slack(&flat, p.slack()), names));
                self.made.len() - 1
            }
        };
        let (_, oracle, names) = &self.made[k];
        (oracle.closest_hit(r), names)
    }
}

/// The instances of `placements` set moving by `bytes` ([`fuzz_motions`]), the rays (whose
/// masks repeat every three) shot at three shutter times ([`FuzzTimes`]: 0, one the bytes
/// pick and 1, in turn; carried as times out of the shutter and NaN too). Nothing may panic
/// and both instruction sets agree bit for bit; on tame inputs every closest hit, single and
/// in packets, is an answer the f64 oracle over the scene placed at the ray's clamped time
/// admits, the single one is the static world's built at that time or (where the two walks'
/// top levels meet tied instances in other orders) both are admitted, and any hit agrees
/// with the oracle on decidable rays.
fn moving_against_rebuilt(
    bytes: &[u8],
    placements: &crate::worlds::Placements,
    options: &BuildOptions,
    rays: &[Ray],
    tame: bool,
) {
    let byte = |k: usize| bytes.get(k).copied().unwrap_or(0);
    let motions = fuzz_motions(bytes, &placements.instances);
    if motions.iter().all(Option::is_none) {
        return;
    }
    let n = placements.instances.len();
    let times = FuzzTimes::new(byte(2 * n), byte(2 * n + 1));
    let rays = times.shoot(rays);
    let world = placements.moving_world(&motions, options);
    let portable = placements.moving_world(&motions, &options.clone().isa(Isa::Portable));
    let hits = closest_in_packets::<ConservativeBoxes, _, _>(&world, &rays, &mut NoFilter);
    let placed: Vec<_> = times
        .shutter
        .iter()
        .map(|&t| placements.at_time(&motions, t))
        .collect();
    let fresh: Vec<_> = placed.iter().map(|p| p.world(options)).collect();
    let mut oracles = PlacedOracles::new(&placed);
    for (i, r) in rays.iter().enumerate() {
        let got = world.closest_hit(r);
        assert_eq!(got, portable.closest_hit(r), "isa {r:?}");
        assert_eq!(world.any_hit(r), portable.any_hit(r), "isa any {r:?}");
        if !(tame && judgeable(r)) {
            continue;
        }
        let (answer, names) = oracles.answer(i % 3, r);
        let want = fresh[i % 3].closest_hit(r);
        let admitted = |h| crate::worlds::check(&answer, h, names).is_ok();
        assert!(
            got == want || (admitted(got) && admitted(want)),
            "{placements:?} {motions:?} {r:?}: {got:?} moving, {want:?} built at the time"
        );
        for (what, h) in [("single", got), ("packet", hits[i])] {
            if let Err(e) = crate::worlds::check(&answer, h, names) {
                panic!("{placements:?} {motions:?} {what} {r:?}: {e}");
            }
        }
        if answer.is_decidable() {
            assert_eq!(world.any_hit(r), answer.hit.is_some(), "any-hit {r:?}");
        }
    }
}

/// Bytes a geometry's deformation takes in [`deforming_against_oracle`]: a kind, then four a
/// step after the first.
const DEFORM_BYTES: usize = 17;

/// `tris` deforming by `bytes` into 2 to 5 steps, or still (`None`, for a first byte of 0
/// mod 3). Step 0 is `tris`; each later one moves the one before about the box of `tris`:
/// a drift of up to half the box's size along each axis, a scale of 1/2 to 3/2, and every
/// vertex jittered by up to a quarter of the box's size (from a generator the bytes seed),
/// so triangles change shape too; a jitter byte of 0 mod 8 repeats the step before.
fn fuzz_steps(tris: &[Triangle], bytes: &[u8]) -> Option<Vec<Vec<Triangle>>> {
    use quiver_scenes::rng::Rng;
    let byte = |k: usize| bytes.get(k).copied().unwrap_or(0);
    let kind = byte(0);
    if kind % 3 == 0 {
        return None;
    }
    let bounds = tris
        .iter()
        .fold(quiver_rt::Aabb::EMPTY, |b, t| b.union(&t.bounds()));
    let centre = (bounds.min + bounds.max) * 0.5;
    let size = (bounds.max - bounds.min).max_element();
    let mut steps = vec![tris.to_vec()];
    for j in 1..2 + (kind / 3) as usize % 4 {
        let b: [u8; 4] = std::array::from_fn(|k| byte(1 + 4 * (j - 1) + k));
        let last = &steps[j - 1];
        if b[3].is_multiple_of(8) {
            steps.push(last.clone());
            continue;
        }
        let signed = |x: u8| x as f32 / 255.0 - 0.5;
        let drift = Vec3A::new(signed(b[0]), signed(b[1]), signed(b[0] ^ b[1])) * size;
        let scale = 0.5 + b[2] as f32 / 255.0;
        let jitter = size * (b[3] / 8) as f32 / 31.0 * 0.25;
        let mut rng = Rng::new(u64::from_le_bytes([
            b[0], b[1], b[2], b[3], kind, j as u8, 0, 0,
        ]));
        let mut moved = |p: Vec3A| {
            centre + (p - centre) * scale + drift + rng.in_box(-Vec3A::ONE, Vec3A::ONE) * jitter
        };
        let next = last
            .iter()
            .map(|t| Triangle::new(moved(t.v[0]), moved(t.v[1]), moved(t.v[2])))
            .collect();
        steps.push(next);
    }
    Some(steps)
}

/// Moving meshes against the oracle: each geometry of `placements` deforming by `bytes`
/// ([`DEFORM_BYTES`] a geometry from byte 3, [`fuzz_steps`]: 2 to 5 steps of drift, scale and
/// jitter, or still) and, if byte 2 says so, the instances moving too ([`fuzz_motions`], from
/// the bytes after the geometries'), the rays shot at three shutter times ([`FuzzTimes`],
/// bytes 0 and 1; carried as times out of the shutter and NaN too). Nothing may panic; steps
/// with a vertex that is not finite are refused, naming the first (the geometry is then left
/// still); both instruction sets agree bit for bit, single rays and packets; on tame inputs
/// every closest hit, single and in packets, is one the f64 oracle over the scene placed at
/// the ray's clamped time ([`crate::worlds::Placements::deformed_at`]) admits, any hit agrees
/// with it on decidable rays, and a point query from each of the first two rays' origins
/// (within its `t_max`, at its time) answers as the point oracle over that scene admits.
/// Reports what it did.
fn deforming_against_oracle(
    bytes: &[u8],
    placements: &crate::worlds::Placements,
    options: &BuildOptions,
    rays: &[Ray],
    tame: bool,
) -> Deformed {
    use crate::point_oracle::PointOracle;
    use quiver_rt::WorldError;
    let byte = |k: usize| bytes.get(k).copied().unwrap_or(0);
    let geometry_bytes = |g: usize| bytes.get(3 + DEFORM_BYTES * g..).unwrap_or(&[]);
    let mut steps: Vec<Vec<Vec<Triangle>>> = (placements.geometries.iter().enumerate())
        .map(|(g, tris)| fuzz_steps(tris, geometry_bytes(g)).unwrap_or_default())
        .collect();
    let mut did = Deformed::default();
    if steps.iter().all(Vec::is_empty) {
        return did;
    }
    let motions = match byte(2) & 1 {
        1 => fuzz_motions(geometry_bytes(3), &placements.instances),
        _ => Vec::new(),
    };
    let times = FuzzTimes::new(byte(0), byte(1));
    let rays = times.shoot(rays);
    let finite = |s: &[Triangle]| s.iter().all(Triangle::is_finite);
    let refused = |s: &Vec<Vec<Triangle>>| !s.iter().all(|s| finite(s));
    let world = match placements.deforming_world(&steps, &motions, options) {
        Ok(w) => w,
        Err(e) => {
            let g = steps.iter().position(refused);
            let g = g.unwrap_or_else(|| panic!("{e}: refused finite steps"));
            let step = steps[g].iter().position(|s| !finite(s));
            let why = "a vertex that is not finite";
            assert_eq!(
                e,
                WorldError::Steps {
                    geometry: g,
                    step,
                    why
                }
            );
            for s in &mut steps {
                if refused(s) {
                    s.clear();
                    did.refused += 1;
                }
            }
            if steps.iter().all(Vec::is_empty) {
                return did;
            }
            placements
                .deforming_world(&steps, &motions, options)
                .unwrap()
        }
    };
    let portable =
        (placements.deforming_world(&steps, &motions, &options.clone().isa(Isa::Portable)))
            .unwrap();
    let hits = closest_in_packets::<FastBoxes, _, _>(&world, &rays, &mut NoFilter);
    let on_portable = closest_in_packets::<FastBoxes, _, _>(&portable, &rays, &mut NoFilter);
    assert_eq!(hits, on_portable, "isa packets");
    let placed: Vec<_> = times
        .shutter
        .iter()
        .map(|&t| placements.deformed_at(&steps, &motions, t))
        .collect();
    let mut oracles = PlacedOracles::new(&placed);
    did.meshes = steps.iter().filter(|s| !s.is_empty()).count();
    for (i, r) in rays.iter().enumerate() {
        let got = world.closest_hit(r);
        let any = world.any_hit(r);
        assert_eq!(got, portable.closest_hit(r), "isa {r:?}");
        assert_eq!(any, portable.any_hit(r), "isa any {r:?}");
        if i < 2 {
            let hit = world.closest_point_at(r.origin, r.t_max, r.time);
            let tame_point = tame && r.origin.is_finite() && r.t_max >= 0.0;
            if tame_point {
                let oracle = PointOracle::for_placements(&placed[i % 3]);
                if let Err(e) = oracle.check_world(r.origin, r.t_max, hit.as_ref()) {
                    panic!("{placements:?} {steps:?} {motions:?} point at {r:?}: {e}");
                }
                did.points += 1;
            }
        }
        if !(tame && judgeable(r)) {
            continue;
        }
        let (answer, names) = oracles.answer(i % 3, r);
        for (what, h) in [("single", got), ("packet", hits[i])] {
            if let Err(e) = crate::worlds::check(&answer, h, names) {
                panic!("{placements:?} {steps:?} {motions:?} {what} {r:?}: {e}");
            }
        }
        if answer.is_decidable() {
            assert_eq!(any, answer.hit.is_some(), "any-hit {r:?}");
        }
        did.hits += usize::from(got.is_some());
    }
    did
}

/// What [`deforming_against_oracle`] did: how many geometries it traced as moving meshes and
/// how many it saw refused (a vertex not finite), how many hits and point queries the
/// oracles judged.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Deformed {
    meshes: usize,
    refused: usize,
    hits: usize,
    points: usize,
}

/// A random sequence of structural edits (from `ops`, three bytes each: remove, add, move,
/// re-mask or replace an instance; replace a geometry by part of its triangles; rebuild one
/// with another layout; rebuild the top level) made to the world of `placements` in two
/// edits; nothing may panic, a refused edit must be the error its state calls for, and on
/// tame inputs the edited world answers every ray (single, packets; closest and any hit)
/// exactly as the same state built afresh does, or (closest hit) where the two differ, each
/// with a hit the f64 oracle over the edited scene admits.
fn edits_against_rebuilt(
    ops: &[u8],
    mut state: crate::worlds::Placements,
    options: &BuildOptions,
    rays: &[Ray],
    tame: bool,
) {
    use glam::{Affine3A, Vec3};
    use quiver_rt::{GeometryId, Instance, InstanceId, World, WorldError, WorldHit};
    let mut world = state.world(options);
    let mut own: Vec<Option<BuildOptions>> = vec![None; state.geometries.len()];
    let mut removed = vec![false; state.instances.len()];
    let count = ops.first().map_or(0, |&b| b as usize % 10);
    let op = |k: usize| -> [u8; 3] {
        std::array::from_fn(|j| ops.get(1 + 3 * k + j).copied().unwrap_or(0))
    };
    for half in [0..count / 2, count / 2..count] {
        let mut edit = world.edit();
        for k in half {
            let [kind, a, b] = op(k);
            let (n, gn) = (state.instances.len(), state.geometries.len());
            let i = a as usize % n.max(1);
            let g = a as usize % gn;
            let shift = Affine3A::from_translation(Vec3::new(b as f32 / 16.0 - 8.0, 0.5, 0.0));
            let live = i < n && !removed[i];
            let expect_live = |r: Result<(), WorldError>| match (live, r) {
                (true, r) => r.unwrap(),
                (false, r) => assert!(
                    matches!(
                        r,
                        Err(WorldError::Removed { .. } | WorldError::NoInstance { .. })
                    ),
                    "edit of instance {i} of {n}"
                ),
            };
            match kind % 8 {
                0 => {
                    expect_live(edit.remove_instance(InstanceId(i as u32)));
                    if live {
                        removed[i] = true;
                    }
                }
                1 => {
                    let inst = Instance::of(GeometryId((b as usize % gn) as u32)).transform(shift);
                    assert_eq!(edit.add_instance(inst), Ok(InstanceId(n as u32)));
                    state.instances.push(inst);
                    removed.push(false);
                }
                2 => {
                    let r = edit.set_transform(InstanceId(i as u32), shift);
                    expect_live(r);
                    if live {
                        state.instances[i].transform = shift;
                    }
                }
                3 => {
                    expect_live(edit.set_mask(InstanceId(i as u32), b as u32 % 4));
                    if live {
                        state.instances[i].mask = b as u32 % 4;
                    }
                }
                4 => {
                    let part: Vec<Triangle> = state.geometries[g]
                        .iter()
                        .step_by(1 + b as usize % 3)
                        .copied()
                        .collect();
                    let o = options
                        .clone()
                        .layout(Layout::ALL[b as usize % Layout::ALL.len()]);
                    edit.replace_triangles(GeometryId(g as u32), part.clone(), &o)
                        .unwrap();
                    state.geometries[g] = part;
                    own[g] = Some(o);
                }
                5 => {
                    let o = options
                        .clone()
                        .layout(Layout::ALL[b as usize % Layout::ALL.len()]);
                    edit.rebuild_geometry(GeometryId(g as u32), &o).unwrap();
                    own[g] = Some(o);
                }
                6 => edit.rebuild_top(),
                _ => {
                    let inst = Instance::of(GeometryId((b as usize % gn) as u32)).mask(0b01);
                    expect_live(edit.set_instance(InstanceId(i as u32), inst));
                    if live {
                        state.instances[i] = inst;
                    }
                }
            }
        }
        edit.commit();
    }
    if !tame {
        for r in rays {
            let _ = (world.closest_hit(r), world.any_hit(r));
        }
        return;
    }
    let live: Vec<u32> = (0..state.instances.len() as u32)
        .filter(|&i| !removed[i as usize])
        .collect();
    // The state's geometries, each with its own options, and the instances `which`.
    let built = |which: &[u32]| {
        let mut b = World::builder();
        for (g, tris) in state.geometries.iter().enumerate() {
            let id = b.add_triangles(tris.clone());
            if let Some(o) = &own[g] {
                b.set_options(id, o).unwrap();
            }
        }
        for &i in which {
            b.add_instance(state.instances[i as usize]);
        }
        b.build(options).unwrap()
    };
    let fresh = built(&live);
    let renamed = |h: WorldHit| WorldHit {
        instance: InstanceId(live[h.instance.0 as usize]),
        ..h
    };
    // Conservative boxes, as the single-ray queries use: the plain slab test may cull a box
    // entered at exactly the limit, so of two instances hit at one distance which is kept
    // would depend on the order the walk meets them.
    let hits = closest_in_packets::<ConservativeBoxes, _, _>(&world, rays, &mut NoFilter);
    // Where the edited world and the rebuilt one differ, both answers must be ones the f64
    // oracle over the edited scene admits: the walks meet instances in other orders, and a
    // far, ill-conditioned triangle's computed distance can fall short of its own box's entry
    // by more than the box test's slack, so one walk may cull a hit another keeps (two
    // instances tied at one distance, or a hit at t = 0 against one at 1e-12).
    let slack = state.slack();
    let admitted = |h: Option<WorldHit>, r: &Ray| {
        let (flat, names) = state.flattened(|i, _| {
            !removed[i as usize] && state.instances[i as usize].mask & r.mask != 0
        });
        let answer = Oracle::with_slack(&flat, slack).closest_hit(r);
        crate::worlds::check(&answer, h, &names).is_ok()
    };
    let same = |got: Option<WorldHit>, want: Option<WorldHit>, r: &Ray| {
        got == want || (judgeable(r) && admitted(got, r) && admitted(want, r))
    };
    for (i, r) in rays.iter().enumerate() {
        let want = fresh.closest_hit(r).map(renamed);
        let got = world.closest_hit(r);
        assert!(
            same(got, want, r),
            "edited world, ray {r:?}: {got:?}, rebuilt {want:?}"
        );
        assert!(
            same(hits[i], want, r),
            "edited world, packet, ray {r:?}: {:?}, rebuilt {want:?}",
            hits[i]
        );
        assert_eq!(
            world.any_hit(r),
            fresh.any_hit(r),
            "edited world, any hit, ray {r:?}"
        );
    }
}

/// Bytes read in order; zero once they run out, so every input decodes to something.
struct ByteReader<'a>(&'a [u8]);

impl ByteReader<'_> {
    fn u8(&mut self) -> u8 {
        let (&b, rest) = self.0.split_first().unwrap_or((&0, &[]));
        self.0 = rest;
        b
    }

    /// Usually a small number (below 32), sometimes (a byte of 250 or more) any `u32`: node
    /// links, leaf ranges and primitive indices both plausible and wild.
    fn index(&mut self) -> u32 {
        match self.u8() {
            b if b >= 250 => u32::from_le_bytes([self.u8(), self.u8(), self.u8(), self.u8()]),
            b => b as u32 % 32,
        }
    }

    /// A coordinate on a grid of 1/8 within ±16: shared vertices, edges and coplanar
    /// triangles are common, and no product of lengths leaves f32's range.
    fn coord(&mut self) -> f32 {
        self.u8() as i8 as f32 / 8.0
    }

    fn point(&mut self) -> Vec3A {
        Vec3A::new(self.coord(), self.coord(), self.coord())
    }
}

/// A build tree from the bytes in one of three ways (byte 2, low two bits): node by node with
/// arbitrary kinds, links, leaf ranges and index array (mostly invalid); a random shape built
/// valid (any leaf sizes, empty leaves, chains deeper than the kernels' stacks allow); or a
/// builder's tree with a few of its links, ranges or indices changed.
fn fuzz_tree(
    b: &mut ByteReader<'_>,
    mode: u8,
    tris: &[Triangle],
) -> quiver_rt::builders::BuildTree {
    use quiver_rt::builders::{BuildNode, NodeKind};
    let bounds = quiver_rt::builders::prim_bounds(tris);
    let finite: Vec<u32> = (0..tris.len() as u32)
        .filter(|&i| bounds[i as usize].is_finite())
        .collect();
    match mode % 3 {
        0 => {
            let nodes = (0..b.u8() % 40)
                .map(|_| {
                    let leaf = b.u8() & 1 == 1;
                    let (x, y) = (b.index(), b.index());
                    let kind = match leaf {
                        true => NodeKind::Leaf { first: x, count: y },
                        false => NodeKind::Inner { left: x, right: y },
                    };
                    let (lo, hi) = (b.point(), b.point());
                    BuildNode {
                        bounds: quiver_rt::Aabb::new(lo, hi),
                        kind,
                    }
                })
                .collect();
            let prim_indices = (0..b.u8() % 24).map(|_| b.index()).collect();
            quiver_rt::builders::BuildTree {
                nodes,
                prim_indices,
                dropped: b.index() as usize,
            }
        }
        1 => {
            // Finite primitives in an order the bytes choose, handed out leaf by leaf.
            let mut order = finite.clone();
            for i in (1..order.len()).rev() {
                order.swap(i, b.u8() as usize % (i + 1));
            }
            let mut nodes: Vec<BuildNode> = Vec::new();
            let mut used = 0usize;
            // Preorder by an explicit stack of parents waiting for their right child.
            let mut pending: Vec<(usize, usize)> = vec![(usize::MAX, 0)];
            while let Some((parent, depth)) = pending.pop() {
                let i = nodes.len();
                if parent != usize::MAX {
                    if let NodeKind::Inner { right, .. } = &mut nodes[parent].kind {
                        *right = i as u32;
                    }
                }
                // A chain (byte of 240 or more) goes past the stacks' depth; otherwise split
                // about half the time while the node budget lasts.
                let mut d = depth;
                let mut node = i;
                let chain = b.u8() >= 240;
                loop {
                    let split = nodes.len() < 300
                        && d < 100
                        && (chain || (b.u8().is_multiple_of(2) && nodes.len() < 60));
                    if !split {
                        let count = (b.u8() as usize % 5).min(order.len() - used);
                        nodes.push(BuildNode {
                            bounds: quiver_rt::Aabb::EMPTY,
                            kind: NodeKind::Leaf {
                                first: used as u32,
                                count: count as u32,
                            },
                        });
                        used += count;
                        break;
                    }
                    nodes.push(BuildNode {
                        bounds: quiver_rt::Aabb::EMPTY,
                        kind: NodeKind::Inner {
                            left: node as u32 + 1,
                            right: 0,
                        },
                    });
                    pending.push((node, d + 1));
                    node += 1;
                    d += 1;
                }
            }
            // The last leaf in preorder takes whatever is left.
            if let Some(NodeKind::Leaf { count, .. }) =
                nodes.iter_mut().rev().map(|n| &mut n.kind).next()
            {
                *count += (order.len() - used) as u32;
            }
            quiver_rt::builders::BuildTree {
                nodes,
                prim_indices: order,
                dropped: tris.len() - finite.len(),
            }
        }
        _ => {
            let options = BuildOptions::default()
                .max_leaf_size(1 + b.u8() as usize % 6)
                .builder(Builder::ALL[b.u8() as usize % Builder::ALL.len()]);
            let (_, mut tree) = Bvh::build_with_tree(tris, &options).unwrap();
            for _ in 0..b.u8() % 4 {
                let n = tree.nodes.len();
                if n == 0 {
                    break; // truncated away
                }
                let i = b.u8() as usize % n;
                let (what, x) = (b.u8() % 6, b.index());
                match (what, &mut tree.nodes[i].kind) {
                    (0, NodeKind::Inner { left, .. }) => *left = x,
                    (1, NodeKind::Inner { right, .. }) => *right = x,
                    (0, NodeKind::Leaf { first, .. }) => *first = x,
                    (1, NodeKind::Leaf { count, .. }) => *count = x,
                    (2, _) => tree.dropped = x as usize,
                    (3, _) if !tree.prim_indices.is_empty() => {
                        let k = x as usize % tree.prim_indices.len();
                        tree.prim_indices[k] = b.index();
                    }
                    (4, _) => tree.nodes.truncate(x as usize % (n + 1)),
                    _ => {
                        let k = x as usize % n;
                        tree.nodes.swap(i, k);
                    }
                }
            }
            tree
        }
    }
}

/// Build trees from outside: arbitrary bytes decoded into up to 12 triangles (on a grid of
/// 1/8, one of them sometimes with a NaN corner) and a [`quiver_rt::builders::BuildTree`] over them —
/// arbitrary nodes, a random valid shape, or a builder's tree with links, leaf ranges, indices or
/// the dropped count changed (see `fuzz_tree`) — laid out by [`Bvh::from_tree`] in every layout and
/// by each layout type's own `from_tree`. A tree [`quiver_rt::builders::BuildTree::check`] refuses
/// must be refused by all of them; one it accepts must be accepted (unless a leaf is too large for
/// the layout) and then every query must answer as [`quiver_rt::traverse::reference::closest_hit`]
/// over the same triangles: a hit or a miss alike, the same `t` to rounding (a hit on an edge two
/// triangles share at the same distance may be either's, and a hit at an interval end may round in
/// or out), any-hit alike. Nothing may panic or loop.
pub fn from_tree_against_reference(data: &[u8]) {
    let mut b = ByteReader(data);
    let n = b.u8() as usize % 13;
    let flags = b.u8();
    let mode = b.u8();
    let max_leaf = 1 + b.u8() as usize % 16;
    let mut tris: Vec<Triangle> = (0..n)
        .map(|_| Triangle::new(b.point(), b.point(), b.point()))
        .collect();
    if flags & 4 == 4 && n > 0 {
        let i = b.u8() as usize % n;
        tris[i].v[b.u8() as usize % 3].y = f32::NAN;
    }
    let tree = fuzz_tree(&mut b, mode, &tris);
    let rays: Vec<Ray> = (0..b.0.len() / 8)
        .map(|_| {
            let origin = b.point() * 2.0;
            let dir = Vec3A::new(b.coord(), b.coord(), b.coord()) * 8.0;
            let t_min = b.u8() as f32 / 16.0;
            let t_max = match b.u8() {
                255 => f32::INFINITY,
                x => t_min + x as f32 / 8.0,
            };
            Ray::segment(origin, dir, t_min, t_max)
        })
        .take(16)
        .collect();
    if flags & 1 == 1 {
        let prims: Vec<Watertight> = tris.iter().map(|&t| Watertight(t)).collect();
        trees_against_reference(&tree, &prims, max_leaf, &rays);
    } else {
        trees_against_reference(&tree, &tris, max_leaf, &rays);
    }
}

fn trees_against_reference<P: Primitive>(
    tree: &quiver_rt::builders::BuildTree,
    prims: &[P],
    max_leaf: usize,
    rays: &[Ray],
) {
    use quiver_rt::builders::TreeError;
    use quiver_rt::layout::{Bvh2, Bvh2Mapping, Bvh4, Bvh4Mapping, Bvh8, QBvh4};
    let bounds = quiver_rt::builders::prim_bounds(prims);
    // The tree's structure as `check` finds it (boxes and leaf sizes aside: the layouts
    // recompute the one and cap the other by their own limit).
    let any_leaf = BuildConfig {
        max_leaf_size: usize::MAX,
        ..BuildConfig::default()
    };
    let valid = match tree.check(&bounds, &any_leaf) {
        Err(TreeError::NodeBox { .. } | TreeError::LeafBox { .. }) => Ok(()),
        other => other,
    };
    let what = format!("{tree:?} over {} primitives", prims.len());
    // Refused exactly when the check refuses, or for a leaf the layout cannot store.
    let agree = |got: &Result<(), TreeError>| match (&valid, got) {
        (Ok(()), Ok(())) | (Ok(()), Err(TreeError::LeafSize { .. })) => true,
        (Err(want), Err(e)) => want == e || matches!(e, TreeError::LeafSize { .. }),
        (Err(_), Ok(())) | (Ok(()), Err(_)) => false,
    };
    let config = BuildConfig {
        max_leaf_size: max_leaf,
        ..BuildConfig::default()
    };
    let mut traced = 0;
    for layout in Layout::ALL {
        let options = BuildOptions::default()
            .layout(layout)
            .config(config.clone());
        let bvh = Bvh::from_tree(tree, prims, &options);
        let shape = bvh.as_ref().map(|_| ()).map_err(Clone::clone);
        assert!(
            agree(&shape),
            "{layout}: {shape:?}, check: {valid:?}; {what}"
        );
        if let Ok(bvh) = bvh {
            same_as_reference(&bvh, prims, rays, &format!("{layout} {what}"));
            same_on_every_isa(&bvh, rays, &what);
            traced += 1;
        }
    }
    let check = |name: &str, shape: Result<(), TreeError>| {
        assert!(agree(&shape), "{name}: {shape:?}, check: {valid:?}; {what}");
    };
    for mapping in [
        Bvh2Mapping::DepthFirst,
        Bvh2Mapping::Subtree,
        Bvh2Mapping::Compact,
    ] {
        let name = format!("Bvh2 {mapping:?}");
        match Bvh2::from_tree(tree, prims, mapping) {
            Ok(q) => {
                check(&name, Ok(()));
                same_as_reference(&q, prims, rays, &format!("{name} {what}"));
            }
            Err(e) => check(&name, Err(e)),
        }
    }
    let isa = Isa::best();
    match Bvh4::<P>::from_tree(tree, prims, Bvh4Mapping::DepthFirst, isa) {
        Ok(q) => {
            check("Bvh4", Ok(()));
            same_as_reference(&q, prims, rays, &format!("Bvh4 {what}"));
        }
        Err(e) => check("Bvh4", Err(e)),
    }
    match QBvh4::<P>::from_tree(tree, prims, Bvh4Mapping::Subtree, isa) {
        Ok(q) => {
            check("QBvh4", Ok(()));
            same_as_reference(&q, prims, rays, &format!("QBvh4 {what}"));
        }
        Err(e) => check("QBvh4", Err(e)),
    }
    match Bvh8::from_tree(tree, prims, &config, isa) {
        Ok(q) => {
            check("Bvh8", Ok(()));
            same_as_reference(&q, prims, rays, &format!("Bvh8 {what}"));
        }
        Err(e) => check("Bvh8", Err(e)),
    }
    assert!(
        valid.is_err() || traced > 0,
        "a valid tree laid out nowhere: {what}"
    );
}

/// `q` answers every ray as [`quiver_rt::traverse::reference`] does over `prims` (see
/// [`from_tree_against_reference`] for the rounding it allows).
fn same_as_reference<P: Primitive>(
    q: &impl RayQuery<Hit = quiver_rt::Hit>,
    prims: &[P],
    rays: &[Ray],
    what: &str,
) {
    let close = |a: f32, b: f32| (a - b).abs() <= 1e-4 * (1.0 + a.abs().max(b.abs()));
    for r in rays {
        let want = quiver_rt::traverse::reference::closest_hit(prims, r);
        let got = q.closest_hit(r);
        let at_end = want.is_some_and(|h| close(h.t, r.t_min) || close(h.t, r.t_max));
        match (want, got) {
            (Some(w), Some(g)) => {
                assert!(close(w.t, g.t), "{what}: {r:?}: {g:?}, reference {w:?}");
                if g.prim != w.prim {
                    // Another primitive at (about) the same distance: it must really be hit
                    // there.
                    let own = quiver_rt::traverse::reference::closest_hit(
                        &prims[g.prim as usize..][..1],
                        r,
                    );
                    assert!(
                        own.is_some_and(|h| h.t == g.t),
                        "{what}: {r:?}: {g:?}, reference {w:?}"
                    );
                }
            }
            (None, None) => {}
            (Some(_), None) if at_end => {}
            _ => panic!("{what}: {r:?}: {got:?}, reference {want:?}"),
        }
        let any = q.any_hit(r);
        assert!(
            any == want.is_some() || at_end,
            "{what}: {r:?}: any-hit {any}, reference {want:?}"
        );
    }
}

/// A count for a structured file: usually small, sometimes one of the values that break
/// size arithmetic (0, 2^32 and around, 2^63, 2^64 - 1, 10^12).
fn hostile_count(b: &mut ByteReader<'_>) -> u64 {
    match b.u8() {
        x if x >= 240 => [
            0,
            1 << 32,
            (1 << 32) - 1,
            (1 << 32) + 1,
            1 << 63,
            u64::MAX,
            1_000_000_000_000,
            u32::MAX as u64 / 3,
        ][x as usize % 8],
        x => x as u64 % 12,
    }
}

/// Structure-aware PLY mode ([`ply_load`] with a first byte of 0xFF): the bytes choose a
/// valid header (ASCII or either binary order; vertex, face and other elements of hostile
/// counts; scalar and list properties of every type, empty lists and property-less
/// elements included), then a body of instances whose list counts and values come from the
/// bytes, then any leftover bytes. Loaded as [`mesh_load`] does and under small memory and
/// primitive limits, which must refuse with the budget error or stay within them.
pub fn ply_structured(data: &[u8]) -> Vec<u8> {
    const TYPES: [&str; 8] = [
        "char", "uchar", "short", "ushort", "int", "uint", "float", "double",
    ];
    const SIZES: [usize; 8] = [1, 1, 2, 2, 4, 4, 4, 8];
    let mut b = ByteReader(data);
    let format = b.u8() % 3;
    let mut head = format!(
        "ply\nformat {} 1.0\n",
        ["ascii", "binary_little_endian", "binary_big_endian"][format as usize]
    );
    // Each element: name, count, properties as (name, count type or none, item type).
    type Property = (String, Option<usize>, usize);
    let mut elements: Vec<(String, u64, Vec<Property>)> = Vec::new();
    for e in 0..1 + b.u8() % 4 {
        let kind = b.u8() % 4;
        let name = ["vertex", "face", "edge", "nothing"][kind as usize].to_string();
        if elements.iter().any(|x| x.0 == name) {
            continue;
        }
        let count = hostile_count(&mut b);
        let mut props = Vec::new();
        match kind {
            0 => {
                for axis in ["x", "y", "z"] {
                    props.push((axis.to_string(), None, 6 + b.u8() as usize % 2));
                }
            }
            1 => props.push((
                "vertex_indices".to_string(),
                Some(b.u8() as usize % 6),
                b.u8() as usize % 6,
            )),
            _ => {}
        }
        for k in 0..b.u8() % 3 {
            let list = (b.u8() % 2 == 0).then(|| b.u8() as usize % 6);
            props.push((format!("p{e}{k}"), list, b.u8() as usize % 8));
        }
        elements.push((name, count, props));
    }
    for (name, count, props) in &elements {
        head += &format!("element {name} {count}\n");
        for (p, list, ty) in props {
            match list {
                Some(c) => head += &format!("property list {} {} {p}\n", TYPES[*c], TYPES[*ty]),
                None => head += &format!("property {} {p}\n", TYPES[*ty]),
            }
        }
    }
    head += "end_header\n";
    let mut out = head.into_bytes();
    let big = format == 2;
    let value = |out: &mut Vec<u8>, ty: usize, v: i64| {
        if format == 0 {
            out.extend_from_slice(format!("{v} ").as_bytes());
            return;
        }
        let mut bytes = match ty {
            6 => (v as f32).to_le_bytes().to_vec(),
            7 => (v as f64).to_le_bytes().to_vec(),
            _ => v.to_le_bytes()[..SIZES[ty]].to_vec(),
        };
        if big {
            bytes.reverse();
        }
        out.extend_from_slice(&bytes);
    };
    for (name, count, props) in &elements {
        for _ in 0..(*count).min(24) {
            for (_, list, ty) in props {
                if let Some(c) = list {
                    // Mostly a few items (none included), sometimes a count past the file.
                    let n = match b.u8() {
                        x if x >= 250 => 1_000_000 + x as i64,
                        x => x as i64 % 6,
                    };
                    value(&mut out, *c, n);
                    for _ in 0..n.min(8) {
                        let v = if name == "face" {
                            b.u8() as i64 % 10
                        } else {
                            b.u8() as i64
                        };
                        value(&mut out, *ty, v);
                    }
                } else {
                    value(&mut out, *ty, b.u8() as i8 as i64);
                }
            }
            if format == 0 {
                out.push(b'\n');
            }
        }
    }
    out.extend_from_slice(b.0);
    out
}

/// Loads `bytes` (a structured file written as `ext`) under limits from `limit` (a byte):
/// a refusal must be the budget's error naming the limit, and a load must stay within them.
fn within_limits(bytes: &[u8], ext: &str, limit: u8) {
    use quiver_scenes::scene::{LoadOptions, Scene, SceneError};
    let dir = std::env::temp_dir().join(format!(
        "quiver-fuzz-limits-{}-{}",
        std::process::id(),
        limit
    ));
    let path = dir.join(format!("input.{ext}"));
    if std::fs::create_dir_all(&dir).is_err() || std::fs::write(&path, bytes).is_err() {
        return;
    }
    let max_prims = (limit % 16) as u64;
    let max_bytes = 64u64 << (limit / 16);
    let opts = LoadOptions::default()
        .max_primitives(max_prims)
        .max_bytes(max_bytes);
    let loaded = Scene::load_with(path.to_str().unwrap_or_default(), &opts);
    let _ = std::fs::remove_dir_all(&dir);
    match loaded {
        Ok((scene, _)) => assert!(
            scene.objects.len() as u64 <= max_prims,
            "{} objects under max_primitives {max_prims}",
            scene.objects.len()
        ),
        Err(SceneError::OverBudget { needs, limit, .. }) => {
            assert!(
                needs > limit,
                "refused at {needs}, within the limit {limit}"
            )
        }
        Err(_) => {}
    }
}

/// What [`ply_load`] runs on a first byte of 0xFF: [`ply_structured`]'s file, loaded as
/// [`mesh_load`] does and under limits.
fn ply_structured_load(data: &[u8]) {
    let file = ply_structured(data);
    mesh_load(&file, "ply");
    within_limits(&file, "ply", data.first().copied().unwrap_or(0));
}

/// Standard base64 of `bytes`, for structured glTF data URIs.
fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for c in bytes.chunks(3) {
        let n = c
            .iter()
            .enumerate()
            .fold(0u32, |n, (i, &b)| n | (b as u32) << (16 - 8 * i));
        for k in 0..=c.len() {
            out.push(A[(n >> (18 - 6 * k)) as usize & 63] as char);
        }
    }
    while !out.len().is_multiple_of(4) {
        out.push('=');
    }
    out
}

/// The coordinate every float of the file outside the glTF's folder holds: far beyond what
/// [`gltf_structured`]'s own data and transforms can reach, so a vertex near it was read from
/// outside.
const OUTSIDE: f32 = 1e20;

/// Structure-aware glTF mode ([`gltf_load`] with a first byte of 0xFF): the bytes choose a
/// glTF of buffers (base64 data, the `x.bin` beside it, or URIs that try to leave the folder:
/// `..`, percent-encoded `..` and `/`, absolute paths, a symbolic link out, schemes), buffer
/// views and accessors of hostile offsets, strides and counts (0 included), meshes of every
/// primitive mode, nodes whose children may form cycles or repeat, matrices (some not
/// affine) or translation/rotation/scale, with or without a `scene`. Floats in the data are
/// small (within ±16) and transforms scale by at most 2 a level, so a vertex near
/// `OUTSIDE` proves a read outside the folder. Returns the JSON text and `x.bin`'s bytes.
pub fn gltf_structured(data: &[u8]) -> (String, Vec<u8>) {
    let mut b = ByteReader(data);
    let tame = |b: &mut ByteReader<'_>| b.u8() as i8 as f32 / 8.0;
    let mut bin = Vec::new();
    for _ in 0..b.u8() % 64 {
        bin.extend_from_slice(&tame(&mut b).to_le_bytes());
    }
    let json_count = |b: &mut ByteReader<'_>| {
        let c = hostile_count(b);
        // JSON numbers past 2^53 still parse as u64 in serde_json.
        c.to_string()
    };
    let uris = [
        "x.bin",
        "./x.bin",
        "sub/../x.bin",
        "../outside.bin",
        "%2e%2e/outside.bin",
        "..%2Foutside.bin",
        "sub/..%5C..%5Coutside.bin",
        "link.bin",
        "%2Ftmp%2Foutside.bin",
        "file:///etc/passwd",
        "x.bin%00",
        "",
        "sub",
        "%zz",
    ];
    let mut buffers = Vec::new();
    for _ in 0..1 + b.u8() % 3 {
        let len = match b.u8() % 4 {
            0 => bin.len().to_string(),
            1 => json_count(&mut b),
            _ => (b.u8() as usize % (bin.len() + 1)).to_string(),
        };
        let uri = match b.u8() % 3 {
            0 => {
                let n = b.u8() as usize % 16;
                let mut raw = Vec::new();
                for _ in 0..n {
                    raw.extend_from_slice(&tame(&mut b).to_le_bytes());
                }
                format!("data:application/octet-stream;base64,{}", base64(&raw))
            }
            _ => uris[b.u8() as usize % uris.len()].to_string(),
        };
        buffers.push(format!(r#"{{"byteLength": {len}, "uri": "{uri}"}}"#));
    }
    let mut views = Vec::new();
    for _ in 0..1 + b.u8() % 3 {
        let stride = match b.u8() % 4 {
            0 => format!(r#", "byteStride": {}"#, 4 * (b.u8() % 70)),
            _ => String::new(),
        };
        views.push(format!(
            r#"{{"buffer": {}, "byteOffset": {}, "byteLength": {}{stride}}}"#,
            b.u8() % 4,
            b.u8() % 16,
            json_count(&mut b)
        ));
    }
    let mut accessors = Vec::new();
    for _ in 0..1 + b.u8() % 4 {
        let (ty, comp) = match b.u8() % 4 {
            0 | 1 => ("VEC3", 5126),
            2 => ("SCALAR", [5121, 5123, 5125][b.u8() as usize % 3]),
            _ => (
                ["VEC2", "VEC4", "MAT4", "SCALAR"][b.u8() as usize % 4],
                5120 + b.u8() as u32 % 8,
            ),
        };
        accessors.push(format!(
            r#"{{"bufferView": {}, "byteOffset": {}, "componentType": {comp}, "count": {}, "type": "{ty}"}}"#,
            b.u8() % 4,
            b.u8() % 40,
            json_count(&mut b)
        ));
    }
    let mut meshes = Vec::new();
    for _ in 0..1 + b.u8() % 2 {
        let mut prims = Vec::new();
        for _ in 0..1 + b.u8() % 3 {
            let indices = match b.u8() % 3 {
                0 => format!(r#", "indices": {}"#, b.u8() % 5),
                _ => String::new(),
            };
            prims.push(format!(
                r#"{{"attributes": {{"POSITION": {}}}, "mode": {}{indices}}}"#,
                b.u8() % 5,
                [4, 4, 5, 6, 0, 1, 7][b.u8() as usize % 7]
            ));
        }
        meshes.push(format!(r#"{{"primitives": [{}]}}"#, prims.join(", ")));
    }
    let node_count = 1 + b.u8() as usize % 6;
    let mut nodes = Vec::new();
    for _ in 0..node_count {
        let mut fields = Vec::new();
        if b.u8() % 4 != 0 {
            fields.push(format!(r#""mesh": {}"#, b.u8() % 3));
        }
        let children: Vec<String> = (0..b.u8() % 3)
            .map(|_| (b.u8() as usize % (node_count + 1)).to_string())
            .collect();
        if !children.is_empty() {
            fields.push(format!(r#""children": [{}]"#, children.join(", ")));
        }
        match b.u8() % 5 {
            0 => {
                // A matrix of scale at most 2, sometimes with a bottom row that is not affine.
                let mut m: Vec<String> = (0..16)
                    .map(|k| match k {
                        3 | 7 | 11 => "0".to_string(),
                        15 => "1".to_string(),
                        _ => ((b.u8() % 5) as f32 / 4.0 - 0.5).to_string(),
                    })
                    .collect();
                if b.u8() % 4 == 0 {
                    m[3 + 4 * (b.u8() as usize % 4)] = "0.5".into();
                }
                fields.push(format!(r#""matrix": [{}]"#, m.join(", ")));
            }
            1 => fields.push(format!(
                r#""translation": [{}, {}, {}], "scale": [{}, 1, -1]"#,
                tame(&mut b),
                tame(&mut b),
                tame(&mut b),
                [0.5, 2.0, 0.0, 1.0][b.u8() as usize % 4]
            )),
            2 => fields.push(r#""rotation": [0, 0.7071068, 0, 0.7071068]"#.into()),
            _ => {}
        }
        nodes.push(format!("{{{}}}", fields.join(", ")));
    }
    let scene = match b.u8() % 3 {
        0 => String::new(),
        1 => r#""scene": 0, "scenes": [{"nodes": [0]}], "#.into(),
        _ => r#""scenes": [{"nodes": [0, 1]}], "#.into(),
    };
    let json = format!(
        r#"{{"asset": {{"version": "2.0"}}, {scene}"buffers": [{}], "bufferViews": [{}], "accessors": [{}], "meshes": [{}], "nodes": [{}]}}"#,
        buffers.join(", "),
        views.join(", "),
        accessors.join(", "),
        meshes.join(", "),
        nodes.join(", ")
    );
    (json, bin)
}

/// What [`gltf_load`] runs on a first byte of 0xFF: [`gltf_structured`]'s file in a folder
/// of its own with its `x.bin`, a `sub` folder, a file of [`OUTSIDE`] floats beside the
/// folder and at `/tmp/outside.bin`, and a symbolic link to it inside: loaded as
/// [`mesh_load`] does and under limits, and no load may hold a vertex read from outside.
fn gltf_structured_load(data: &[u8]) {
    use quiver_scenes::scene::Scene;
    use std::sync::atomic::{AtomicUsize, Ordering};
    static N: AtomicUsize = AtomicUsize::new(0);
    let (json, bin) = gltf_structured(data);
    let root = std::env::temp_dir().join(format!(
        "quiver-fuzz-gltf-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    let dir = root.join("in");
    let outside: Vec<u8> = (0..256).flat_map(|_| OUTSIDE.to_le_bytes()).collect();
    let ready = std::fs::create_dir_all(dir.join("sub")).is_ok()
        && std::fs::write(dir.join("x.bin"), &bin).is_ok()
        && std::fs::write(root.join("outside.bin"), &outside).is_ok()
        && std::fs::write("/tmp/outside.bin", &outside).is_ok()
        && std::os::unix::fs::symlink(root.join("outside.bin"), dir.join("link.bin")).is_ok()
        && std::fs::write(dir.join("input.gltf"), &json).is_ok();
    if ready {
        let spec = dir.join("input.gltf");
        let spec = spec.to_str().unwrap_or_default();
        let lax = quiver_scenes::scene::LoadOptions::default()
            .non_finite(quiver_scenes::scene::NonFinite::Drop);
        for loaded in [Scene::load(spec), Scene::load_with(spec, &lax).map(|l| l.0)] {
            for t in loaded.iter().flat_map(|s| s.triangles()) {
                for v in t.v {
                    assert!(
                        v.abs().max_element() < OUTSIDE / 1e6,
                        "a vertex {v:?} read from outside the folder: {json}"
                    );
                }
            }
        }
        within_limits(json.as_bytes(), "gltf", data.first().copied().unwrap_or(0));
    }
    let _ = std::fs::remove_dir_all(&root);
    // The rest of mesh_load's checks (groups, strict against lax, the oracle), without x.bin.
    mesh_load(json.as_bytes(), "gltf");
}

/// Point queries from the bytes: the setup and triangles as for [`build_and_trace`], then
/// queries of four little-endian f32s each (a point and a largest distance; on tame inputs
/// the distance is taken as its magnitude, or infinite when its lowest bit is set). Nothing
/// may panic or loop; a NaN or non-finite point, or a NaN or negative distance, answers
/// `None` and offers nothing to a callback; an answer lies within its largest distance with
/// barycentrics in the triangle. On tame inputs `Bvh::closest_point` must answer as the f64
/// [`PointOracle`](crate::point_oracle::PointOracle) admits, `Bvh::point_query` must offer
/// every primitive within the distance (by the oracle), and `World::closest_point` over the
/// triangles placed by a non-uniform scale with a shear and a rotation (bytes 1–3 pick it)
/// must answer as the oracle over the placed triangles admits.
///
/// ```
/// quiver_lab::checks::point_queries(&[7u8; 300]);
/// quiver_lab::checks::point_queries(&[2u8; 300]);
/// ```
pub fn point_queries(data: &[u8]) {
    use crate::point_oracle::{closest_f64, PointOracle};
    let Some((setup, tris, _)) = fuzz_input(data) else {
        return;
    };
    let mut f = floats(&data[HEADER..]);
    if setup.tame {
        f.iter_mut().for_each(|x| *x = tame(*x));
    }
    let queries: Vec<(Vec3A, f32)> = f[(tris.len() * 9).min(f.len())..]
        .chunks_exact(4)
        .take(16)
        .map(|c| {
            let max = match setup.tame {
                true if c[3].to_bits() & 1 == 1 => f32::INFINITY,
                true => c[3].abs(),
                false => c[3],
            };
            (Vec3A::new(c[0], c[1], c[2]), max)
        })
        .collect();
    let fast = fuzz_bvh(setup, &tris, |t| t);
    let watertight = fuzz_bvh(setup, &tris, Watertight);
    let oracle = setup.tame.then(|| PointOracle::new(&tris));
    for &(p, max) in &queries {
        let valid = p.is_finite() && max >= 0.0;
        let hit = fast.closest_point(p, max);
        let wt = watertight.closest_point(p, max);
        let mut offered = Vec::new();
        fast.point_query(p, max, |i, _| {
            offered.push(i);
            true
        });
        if !valid {
            assert!(
                hit.is_none() && wt.is_none() && offered.is_empty(),
                "{p} {max}"
            );
            continue;
        }
        for h in [hit, wt].iter().flatten() {
            assert!(
                (h.prim as usize) < tris.len() && h.distance <= max,
                "{setup:?} {p} {max}: {h:?}"
            );
            assert!(h.u >= 0.0 && h.v >= 0.0 && h.u + h.v <= 1.0, "{h:?}");
        }
        let Some(oracle) = &oracle else {
            continue;
        };
        for h in [hit, wt] {
            if let Err(e) = oracle.check_bvh(p, max, h.as_ref()) {
                panic!("{setup:?}: {e}");
            }
        }
        // Every primitive within the distance (by the oracle, clear of its band) is offered.
        let band = oracle.tolerance(0.0);
        let pw = glam::DVec3::new(p.x as f64, p.y as f64, p.z as f64);
        for (i, t) in tris.iter().enumerate() {
            let v =
                t.v.map(|q| glam::DVec3::new(q.x as f64, q.y as f64, q.z as f64));
            let d = (closest_f64(&v, pw) - pw).length();
            if t.is_finite() && d + band < max as f64 {
                assert!(
                    offered.contains(&(i as u32)),
                    "{setup:?} {p} {max}: {i} at {d}"
                );
            }
        }
    }
    if setup.tame && !tris.is_empty() {
        point_queries_in_a_world(data, &tris, &queries);
    }
}

/// [`point_queries`]' world: the triangles as one geometry, placed twice (as they are and by
/// a transform of the bytes), the answers against the oracle over the placed triangles.
fn point_queries_in_a_world(data: &[u8], tris: &[Triangle], queries: &[(Vec3A, f32)]) {
    use crate::point_oracle::PointOracle;
    use glam::{Affine3A, Mat3, Quat, Vec3};
    use quiver_rt::{Instance, World};
    let unit = |x: u8| x as f32 / 255.0;
    let scale = Vec3::new(0.25 + 4.0 * unit(data[1]), 1.0, 0.25 + 4.0 * unit(data[2]));
    let shear = Mat3::from_cols(Vec3::X, Vec3::new(unit(data[3]) - 0.5, 1.0, 0.0), Vec3::Z);
    let rotation = Quat::from_axis_angle(Vec3::new(1.0, 2.0, 3.0).normalize(), unit(data[3]) * 6.0);
    let linear = Mat3::from_quat(rotation) * shear * Mat3::from_diagonal(scale);
    let transform = Affine3A::from_mat3_translation(linear, Vec3::new(0.5, -1.0, 2.0));
    let mut b = World::builder();
    let g = b.add_triangles(tris.to_vec());
    b.add_instance(Instance::of(g));
    b.add_instance(Instance::of(g).transform(transform));
    let Ok(world) = b.build(&BuildOptions::default()) else {
        return;
    };
    let oracle = PointOracle::for_world(&world);
    for &(p, max) in queries {
        let hit = world.closest_point(p, max);
        if let Err(e) = oracle.check_world(p, max, hit.as_ref()) {
            panic!("world {transform:?}: {e}");
        }
    }
}

/// The checksum of a saved BVH as `docs/file-format.md` defines it, computed here from the
/// document (not from the core's code): FNV-1a-64 over 64-bit little-endian words in four
/// interleaved streams per 1 MiB block, the block hashes folded in order, then the length.
fn saved_checksum(data: &[u8]) -> u64 {
    const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
    const PRIME: u64 = 0x0000_0100_0000_01b3;
    let step = |s: u64, w: u64| (s ^ w).wrapping_mul(PRIME);
    let block = |b: &[u8]| {
        let mut s: [u64; 4] = std::array::from_fn(|l| OFFSET ^ l as u64);
        for (i, w) in b.chunks(8).enumerate() {
            let mut word = [0u8; 8];
            word[..w.len()].copy_from_slice(w);
            s[i % 4] = step(s[i % 4], u64::from_le_bytes(word));
        }
        s.iter().fold(OFFSET, |h, &x| step(h, x))
    };
    let h = data.chunks(1 << 20).map(block).fold(OFFSET, step);
    step(h, data.len() as u64)
}

/// Writes a valid checksum over `file` (a saved BVH, changed): what a hostile writer does, so
/// the loader's structural checks, not the checksum, must refuse what is wrong.
pub fn reseal_saved(file: &mut [u8]) {
    if file.len() >= 8 {
        let end = file.len() - 8;
        let sum = saved_checksum(&file[..end]);
        file[end..].copy_from_slice(&sum.to_le_bytes());
    }
}

/// Saved BVH files from the bytes ([`Bvh::from_bytes`]): the first byte's low bit chooses
/// raw bytes as a file, or a valid file of up to 24 triangles (layout, triangles and rays
/// from the bytes) changed by the rest: bytes overwritten or flipped at chosen offsets,
/// truncated or extended, and the checksum made valid again or not. Loading must return a
/// BVH or a [`quiver_rt::LoadError`], never panic, hang or allocate past the bytes present;
/// a loaded BVH must save to bytes that load again and answer every ray (single and packets,
/// closest and any hit) as it does, and a refit of it must not panic; an unchanged file must
/// answer as the BVH that wrote it. The same for saved worlds ([`quiver_rt::World::from_bytes`];
/// the mode's bit 2 changes a world file of the triangles placed twice): never a panic, and
/// an unchanged file answers as the world that wrote it.
pub fn saved_bvh(data: &[u8]) {
    let mut b = ByteReader(data);
    let mode = b.u8();
    if mode & 1 == 0 {
        let rest = b.0;
        let rays = fuzz_rays(&mut ByteReader(rest));
        if let Ok(bvh) = Bvh::from_bytes(rest) {
            loaded_answers_again(&bvh, &rays, None);
        }
        if let Ok(world) = quiver_rt::World::from_bytes(rest) {
            for r in &rays {
                let _ = (world.closest_hit(r), world.any_hit(r));
            }
        }
        return;
    }
    let layout = Layout::ALL[b.u8() as usize % Layout::ALL.len()];
    let n = b.u8() as usize % 25;
    let tris: Vec<Triangle> = (0..n)
        .map(|_| Triangle::new(b.point(), b.point(), b.point()))
        .collect();
    let rays = fuzz_rays(&mut ByteReader(data));
    let options = BuildOptions::default().layout(layout);
    let bvh = Bvh::build(&tris, &options).expect("in range");
    // Mode bit 2: the triangles as a world (placed twice), its file changed instead.
    let world = (mode & 4 == 4).then(|| {
        use quiver_rt::{glam::Affine3A, Instance, World};
        let mut w = World::builder();
        let g = w.add_triangles(tris.clone());
        w.add_instance(Instance::of(g));
        w.add_instance(Instance::of(g).transform(Affine3A::from_translation(glam::Vec3::X)));
        w.build(&options).expect("valid instances")
    });
    let original = world
        .as_ref()
        .map_or_else(|| bvh.to_bytes(), |w| w.to_bytes());
    let mut file = original.clone();
    let edits = b.u8() % 8;
    for _ in 0..edits {
        let at = u16::from_le_bytes([b.u8(), b.u8()]) as usize;
        let op = b.u8();
        let value = b.u8();
        match op % 4 {
            0 if !file.is_empty() => {
                let i = at % file.len();
                file[i] = value;
            }
            1 if !file.is_empty() => {
                let i = at % file.len();
                file[i] ^= 1 << (value % 8);
            }
            // A 32-bit field set to a chosen small or extreme value (links, counts).
            2 if file.len() >= 4 => {
                let i = (at % (file.len() - 3)) & !3;
                let v = match value {
                    v if v >= 250 => u32::MAX - (v - 250) as u32,
                    v => v as u32,
                };
                file[i..i + 4].copy_from_slice(&v.to_le_bytes());
            }
            3 => file.truncate(at % (file.len() + 1)),
            _ => {}
        }
    }
    if mode & 2 == 2 {
        reseal_saved(&mut file);
    }
    if let Some(world) = world {
        let loaded = quiver_rt::World::from_bytes(&file);
        if file == original {
            let loaded = loaded.expect("an unchanged file loads");
            for r in &rays {
                assert_eq!(loaded.closest_hit(r), world.closest_hit(r), "{r:?}");
            }
        } else if let Ok(loaded) = loaded {
            for r in &rays {
                let _ = (loaded.closest_hit(r), loaded.any_hit(r));
            }
        }
        return;
    }
    let loaded = Bvh::from_bytes(&file);
    if file == original {
        let loaded = loaded.expect("an unchanged file loads");
        loaded_answers_again(&loaded, &rays, Some(&bvh));
        return;
    }
    if let Ok(loaded) = loaded {
        loaded_answers_again(&loaded, &rays, None);
        // A refit over triangles of the size the file claims must not panic either.
        let mut refit = loaded.clone();
        if refit.refit(&tris).is_ok() {
            loaded_answers_again(&refit, &rays, None);
        }
    }
}

/// Up to 16 rays from the bytes, on the same grid as the fuzzed triangles.
fn fuzz_rays(b: &mut ByteReader<'_>) -> Vec<Ray> {
    (0..16)
        .map(|_| Ray::new(b.point() * 2.0, Vec3A::new(b.coord(), b.coord(), b.coord())))
        .collect()
}

/// `bvh` (loaded) saves to bytes that load again and answer as it does; and as `want` does
/// where given.
fn loaded_answers_again(bvh: &Bvh, rays: &[Ray], want: Option<&Bvh>) {
    let again = Bvh::from_bytes(&bvh.to_bytes()).expect("a loaded BVH saves to a valid file");
    for other in [Some(&again), want].into_iter().flatten() {
        for r in rays {
            assert_eq!(bvh.closest_hit(r), other.closest_hit(r), "{r:?}");
            assert_eq!(bvh.any_hit(r), other.any_hit(r), "{r:?}");
        }
        let (mut a, mut o) = (vec![None; rays.len()], vec![None; rays.len()]);
        bvh.closest_hit_packet(rays, &mut a);
        other.closest_hit_packet(rays, &mut o);
        assert_eq!(a, o);
        let (mut a, mut o) = (vec![false; rays.len()], vec![false; rays.len()]);
        bvh.any_hit_packet(rays, &mut a);
        other.any_hit_packet(rays, &mut o);
        assert_eq!(a, o);
    }
}

#[cfg(test)]
mod tests {
    use super::{instanced_judged, Deformed};

    /// The seeds committed to reach the moving meshes' check do: the tame one traces three
    /// meshes and has hits and point queries at its rays' times judged by the oracles; the raw
    /// one has a mesh with a vertex that is not finite refused and traces the other two.
    ///
    /// On a thread of its own with a 64 MiB stack: unoptimized, the world packet walk's
    /// AVX-512 trampoline alone takes more than a test thread's 2 MiB.
    #[test]
    fn the_deforming_seeds_reach_the_moving_meshes() {
        let dir =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/corpus/instanced");
        let read = |name: &str| std::fs::read(dir.join(name)).unwrap();
        let (tame, raw) = (read("deforming"), read("deforming_raw"));
        let (tame, raw) = std::thread::Builder::new()
            .stack_size(64 << 20)
            .spawn(move || (instanced_judged(&tame), instanced_judged(&raw)))
            .unwrap()
            .join()
            .unwrap();
        assert_eq!(
            (tame.meshes, tame.refused, tame.points),
            (3, 0, 2),
            "{tame:?}"
        );
        assert!(tame.hits >= 10, "{tame:?}");
        let raw_did = Deformed {
            meshes: 2,
            refused: 1,
            hits: 0,
            points: 0,
        };
        assert_eq!(raw, raw_did);
    }
}
