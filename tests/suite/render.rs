//! The renderer traces exactly the rays a scene calls for, the same rays for every layout and
//! thread count, and matches the SPD Readme's published counts.

use crate::common::in_pool;
use quiver_rt::{BuildOptions, Layout};
use quiver_scenes::accel::SceneBvh;
use quiver_scenes::render::{render, RayCounts, RenderConfig};
use quiver_scenes::scene::{nff, Scene};

fn run(
    scene: &Scene,
    res: u32,
    layout: Layout,
    threads: usize,
    counters: bool,
) -> quiver_scenes::render::Rendered {
    run_with(scene, res, layout, threads, counters, true)
}

fn run_with(
    scene: &Scene,
    res: u32,
    layout: Layout,
    threads: usize,
    counters: bool,
    packets: bool,
) -> quiver_scenes::render::Rendered {
    in_pool(threads, || {
        let bvh = SceneBvh::build(scene, &BuildOptions::default().layout(layout));
        let config = RenderConfig {
            res,
            two_sided: scene.two_sided_materials(),
            counters,
            packets,
            ..RenderConfig::default()
        };
        render(scene, &bvh, &config, &|_| {})
    })
}

/// A unit square at z = 0 facing +z, seen from z = 5 filling part of the view, with one light.
fn square(light_z: f32, material: &str) -> Scene {
    let text = format!(
        "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 45\nhither 0.001\nresolution 64 64\n\
         b 0 0 0\nl 0 0 {light_z}\nf {material}\np 4\n-1 -1 0\n1 -1 0\n1 1 0\n-1 1 0\n"
    );
    nff::parse(&text, "square.nff").unwrap()
}

#[test]
fn a_light_behind_the_surface_costs_no_shadow_ray() {
    let front = run(
        &square(3.0, "1 1 1 1 0 0 0 1"),
        32,
        Layout::Bvh2Dfs,
        1,
        false,
    )
    .rays;
    let behind = run(
        &square(-3.0, "1 1 1 1 0 0 0 1"),
        32,
        Layout::Bvh2Dfs,
        1,
        false,
    )
    .rays;
    assert!(front.eye_hit > 0);
    assert_eq!(front.shadow, front.eye_hit);
    assert_eq!(front.shadow_blocked, 0);
    assert_eq!(behind.eye_hit, front.eye_hit);
    assert_eq!(behind.shadow, 0);
}

#[test]
fn only_reflective_and_transmitting_surfaces_spawn_rays() {
    // Diffuse: no secondary rays at all.
    let diffuse = run(
        &square(3.0, "1 1 1 1 0 0 0 1"),
        32,
        Layout::Bvh2Dfs,
        1,
        false,
    )
    .rays;
    assert_eq!((diffuse.reflect, diffuse.refract), (0, 0));
    // Reflective: one reflection ray per eye hit (they fly off into the background).
    let mirror = run(
        &square(3.0, "1 1 1 0.5 0.5 3 0 1"),
        32,
        Layout::Bvh2Dfs,
        1,
        false,
    )
    .rays;
    assert_eq!((mirror.reflect, mirror.refract), (mirror.eye_hit, 0));
    // Transmitting (and reflective, as all SPD transmitters are): one of each per eye hit.
    let glass = run(
        &square(3.0, "1 1 1 0.1 0.5 3 0.5 1.5"),
        32,
        Layout::Bvh2Dfs,
        1,
        false,
    )
    .rays;
    assert_eq!(
        (glass.reflect, glass.refract),
        (glass.eye_hit, glass.eye_hit)
    );
}

#[test]
fn counts_and_pixels_identical_across_layouts_kernels_and_threads() {
    let scene = Scene::load("tetra5").unwrap();
    let base = run(&scene, 96, Layout::Bvh2Dfs, 1, false);
    for layout in Layout::ALL {
        for threads in [1, 2] {
            for counters in [false, true] {
                let r = run(&scene, 96, layout, threads, counters);
                assert_eq!(
                    r.rays, base.rays,
                    "{layout} {threads} threads counters {counters}"
                );
                assert_eq!(
                    r.rgb, base.rgb,
                    "{layout} {threads} threads counters {counters}"
                );
            }
        }
    }
}

/// Within 10% of the SPD Readme's table (513 x 513 eye rays, default sizes).
fn within_10_percent(name: &str, got: RayCounts, want: [u64; 4]) {
    let have = [got.eye_hit, got.reflect, got.refract, got.shadow];
    for (k, (h, w)) in ["eye hit", "reflect", "refract", "shadow"]
        .iter()
        .zip(have.iter().zip(want))
    {
        let ok = if w == 0 {
            *h == 0
        } else {
            (*h as f64 - w as f64).abs() <= 0.1 * w as f64
        };
        assert!(ok, "{name} {k} rays: {h}, SPD Readme: {w}");
    }
}

/// The SPD Readme's statistics table (curve mode, default sizes; its teapot figures are for
/// size 12): eye hit, reflect, refract and shadow rays for 513 x 513 corner eye rays.
#[test]
fn every_spd_scene_matches_the_readme_within_10_percent() {
    let table: [(&str, [u64; 4]); 7] = [
        ("balls", [263169, 175095, 0, 954368]),
        ("gears", [245086, 304643, 207564, 2246955]),
        ("mount", [173125, 354769, 354769, 412922]),
        ("rings", [263169, 315236, 0, 1085002]),
        ("teapot12", [161120, 225248, 0, 407656]),
        ("tetra", [49788, 0, 0, 46112]),
        ("tree", [169836, 0, 0, 1097419]),
    ];
    for (name, want) in table {
        let r = run(&Scene::load(name).unwrap(), 512, Layout::Bvh4Dfs, 2, false).rays;
        assert_eq!(r.eye, 513 * 513);
        within_10_percent(name, r, want);
    }
}

/// Counts do not depend on the layout or the thread count for a scene with every kind of
/// secondary ray (mount: reflective and transmitting glass spheres over a mountain).
#[test]
fn mount_counts_identical_across_layouts_and_threads() {
    let scene = Scene::load("mount3").unwrap();
    let base = run(&scene, 64, Layout::Bvh2Dfs, 1, false);
    assert!(base.rays.refract > 0 && base.rays.reflect > 0);
    for layout in [Layout::Bvh2Subtree, Layout::Bvh4Dfs, Layout::Bvh4Quant] {
        let r = run(&scene, 64, layout, 2, true);
        assert_eq!((r.rays, &r.rgb), (base.rays, &base.rgb), "{layout}");
    }
}

/// Packets on or off, the same rays and the same image: eye rays, shadow rays (several
/// lights, some behind surfaces), reflection and refraction, triangles and analytic shapes,
/// packet and binary layouts, 1 and 2 threads, counters on and off.
#[test]
fn packets_on_and_off_trace_the_same_rays_and_draw_the_same_image() {
    for spec in ["tetra5", "mount3", "balls2", "gears2", "teapot6", "tree"] {
        let scene = Scene::load(spec).unwrap();
        // 100 x 100 pixels: 101 corners, so the last tile column and band are partial.
        let base = run_with(&scene, 100, Layout::Bvh4Dfs, 1, false, false);
        assert!(base.rays.eye_hit > 0 && base.rays.shadow > 0, "{spec}");
        assert_eq!(base.packet_rays, 0, "{spec}: packets off");
        for layout in [
            Layout::Bvh4Dfs,
            Layout::Bvh4Quant,
            Layout::Bvh2Dfs,
            Layout::Bvh8Dfs,
        ] {
            for (threads, counters) in [(1, false), (2, true)] {
                let r = run_with(&scene, 100, layout, threads, counters, true);
                let what = format!("{spec} {layout} {threads} threads counters {counters}");
                assert_eq!(r.rays, base.rays, "{what}");
                assert_eq!(r.rgb, base.rgb, "{what}");
                // Every eye ray goes in an 8 x 8 tile of corners: a coherent packet.
                assert!(r.packet_rays >= r.rays.eye, "{what}: {}", r.packet_rays);
                assert!(r.packet_rays <= r.rays.total(), "{what}");
            }
        }
    }
}

/// Renders `scene` in patch mode flattened and instanced (spheres and cones as instances of
/// unit shapes) with the same settings.
fn flattened_and_instanced(
    name: &str,
    res: u32,
    packets: bool,
) -> (
    quiver_scenes::render::Rendered,
    quiver_scenes::render::Rendered,
) {
    use quiver_scenes::scene::tessellate::DEFAULT_RESOLUTION;
    let scene = Scene::load(name).unwrap();
    let patched = scene.clone().into_patches(DEFAULT_RESOLUTION);
    let options = BuildOptions::default();
    let config = |two_sided| RenderConfig {
        res,
        two_sided,
        packets,
        ..RenderConfig::default()
    };
    let flat = SceneBvh::build_triangles(&patched, &options);
    let inst = SceneBvh::build_instanced(&scene, DEFAULT_RESOLUTION, &options).unwrap();
    assert_eq!(
        inst.primitives(),
        flat.primitives(),
        "{name}: the same triangles"
    );
    (
        render(
            &patched,
            &flat,
            &config(patched.two_sided_materials()),
            &|_| {},
        ),
        render(
            &scene,
            &inst,
            &config(scene.patch_mode_two_sided_materials()),
            &|_| {},
        ),
    )
}

#[test]
fn instanced_scenes_render_as_their_flattened_patch_scenes() {
    // The instances place the unit shapes by a transform, which rounds each vertex within an
    // ulp or two of where patch mode puts it: rays that graze a silhouette or a seam may go
    // the other way. Measured at 128^2 (packets on and off alike): at most 0.09% of pixels
    // differ by more than 8 levels (jacks2), and each ray count by at most 0.1% of all rays.
    for name in ["balls2", "jacks2", "rings2", "lattice2", "tree6", "gears2"] {
        for packets in [true, false] {
            let (flat, inst) = flattened_and_instanced(name, 128, packets);
            let (a, b) = (flat.rays, inst.rays);
            let total = a.total() as i64;
            let within = |what: &str, x: u64, y: u64| {
                let d = (x as i64 - y as i64).abs();
                assert!(
                    d * 500 <= total,
                    "{name} packets {packets}: {what} {x} flattened, {y} instanced, of {total} rays"
                );
            };
            assert_eq!(a.eye, b.eye);
            within("eye hits", a.eye_hit, b.eye_hit);
            within("reflection rays", a.reflect, b.reflect);
            within("refraction rays", a.refract, b.refract);
            within("secondary hits", a.secondary_hit, b.secondary_hit);
            within("shadow rays", a.shadow, b.shadow);
            within("blocked shadow rays", a.shadow_blocked, b.shadow_blocked);
            let far = flat
                .rgb
                .iter()
                .zip(&inst.rgb)
                .filter(|(p, q)| (0..3).any(|c| p[c].abs_diff(q[c]) > 8))
                .count();
            assert!(
                far * 400 <= flat.rgb.len(),
                "{name} packets {packets}: {far} of {} pixels differ by more than 8",
                flat.rgb.len()
            );
        }
    }
}

#[test]
fn an_instanced_scene_renders_alike_with_packets_on_and_off_and_on_any_pool() {
    let (a, _) = flattened_and_instanced("balls2", 64, true);
    for (threads, packets) in [(1, true), (2, false), (2, true)] {
        let (_, b) = in_pool(threads, || flattened_and_instanced("balls2", 64, packets));
        let (_, c) = in_pool(1, || flattened_and_instanced("balls2", 64, true));
        assert_eq!(b.rays, c.rays, "threads {threads} packets {packets}");
        assert_eq!(b.rgb, c.rgb, "threads {threads} packets {packets}");
    }
    assert!(a.rays.total() > 0);
}
