//! Kernel instruction probe: `cargo run --release -p quiver-lab --example kernel_counts`
//! traces fixed ray sets through every query kernel once, each kernel in a function of its own
//! (`k_*`), so one callgrind run gives every kernel's instruction count:
//! `valgrind --tool=callgrind --toggle-collect='kernel_counts::k_*' --callgrind-out-file=OUT
//! target/release/examples/kernel_counts` then `callgrind_annotate --inclusive=yes OUT | grep k_`.
//! Instruction counts repeat exactly for one binary and input, so two builds' counts compare a
//! change's cost per kernel on a shared machine. `QUIVER_ISA=portable` runs the portable lanes.
use quiver_rt::intersect::Watertight;
use quiver_rt::traverse::Counters;
use quiver_rt::{BuildOptions, Bvh, Hit, Layout, Ray, RayQuery, Triangle};
use quiver_lab::rays;
use quiver_scenes::accel::SceneBvh;
use quiver_scenes::scene::tessellate::DEFAULT_RESOLUTION;
use quiver_scenes::Scene;

#[inline(always)]
fn closest<Q: RayQuery>(q: &Q, eye: &[Ray]) -> usize {
    eye.iter().filter(|r| q.closest_hit(r).is_some()).count()
}

#[inline(always)]
fn any<Q: RayQuery>(q: &Q, shadow: &[Ray]) -> usize {
    shadow.iter().filter(|r| q.any_hit(r)).count()
}

#[inline(always)]
fn closest_packets<Q: RayQuery>(q: &Q, eye: &[Ray]) -> usize {
    let mut out = [None; 64];
    let mut n = 0;
    for p in eye.chunks(64) {
        q.closest_hit_packet(p, &mut out[..p.len()]);
        n += out[..p.len()].iter().filter(|h| h.is_some()).count();
    }
    n
}

#[inline(always)]
fn any_packets<Q: RayQuery>(q: &Q, shadow: &[Ray]) -> usize {
    let mut occ = [false; 64];
    let mut n = 0;
    for p in shadow.chunks(64) {
        q.any_hit_packet(p, &mut occ[..p.len()]);
        n += occ[..p.len()].iter().filter(|&&h| h).count();
    }
    n
}

/// Each kernel twice, closest hit (eye rays) and any hit (shadow rays), each in a function of
/// its own with a body of its own (so the linker does not fold kernels of one type together).
macro_rules! kernels {
    ($($closest:ident, $any:ident, $name:ident($c:ident, $a:ident);)*) => {
        $(
            #[inline(never)]
            fn $closest<Q: RayQuery>(q: &Q, eye: &[Ray]) -> usize {
                std::hint::black_box(stringify!($closest));
                $c(q, eye)
            }
            #[inline(never)]
            fn $any<Q: RayQuery>(q: &Q, shadow: &[Ray]) -> usize {
                std::hint::black_box(stringify!($any));
                $a(q, shadow)
            }
            fn $name<Q: RayQuery>(q: &Q, eye: &[Ray], shadow: &[Ray]) -> usize {
                $closest(q, eye) + $any(q, shadow)
            }
        )*
    };
}

kernels! {
    k_bvh8_closest, k_bvh8_any, bvh8_single(closest, any);
    k_bvh8_closest_packets, k_bvh8_any_packets, bvh8_packets(closest_packets, any_packets);
    k_bvh4_closest, k_bvh4_any, bvh4_single(closest, any);
    k_bvh4_closest_packets, k_bvh4_any_packets, bvh4_packets(closest_packets, any_packets);
    k_qbvh4_closest, k_qbvh4_any, qbvh4_single(closest, any);
    k_qbvh4_closest_packets, k_qbvh4_any_packets, qbvh4_packets(closest_packets, any_packets);
    k_bvh2_dfs_closest, k_bvh2_dfs_any, bvh2_dfs_single(closest, any);
    k_bvh2_compact_closest, k_bvh2_compact_any, bvh2_compact_single(closest, any);
    k_watertight_closest, k_watertight_any, watertight_single(closest, any);
    k_watertight_closest_packets, k_watertight_any_packets, watertight_packets(closest_packets, any_packets);
    k_mixed_closest, k_mixed_any, mixed_single(closest, any);
    k_mixed_closest_packets, k_mixed_any_packets, mixed_packets(closest_packets, any_packets);
    k_world_closest, k_world_any, world_single(closest, any);
    k_world_closest_packets, k_world_any_packets, world_packets(closest_packets, any_packets);
}

#[inline(never)]
fn k_bvh8_counted(q: &Bvh, eye: &[Ray], shadow: &[Ray]) -> usize {
    let mut c = Counters::default();
    let n = eye.iter().filter(|r| q.closest_hit_counted(r, &mut c).is_some()).count();
    n + shadow.iter().filter(|r| q.any_hit_counted(r, &mut c)).count() + c.nodes as usize
}

#[inline(never)]
fn k_bvh8_filtered(q: &Bvh, eye: &[Ray], shadow: &[Ray]) -> usize {
    let accept = |h: &Hit| h.prim % 7 != 3;
    let n = eye.iter().filter(|r| q.closest_hit_filtered(r, accept).is_some()).count();
    n + shadow.iter().filter(|r| q.any_hit_filtered(r, accept)).count()
}

#[inline(never)]
fn k_world_filtered(q: &SceneBvh, eye: &[Ray], shadow: &[Ray]) -> usize {
    let accept = |h: &Hit| h.prim % 7 != 3;
    let n = eye.iter().filter(|r| q.closest_hit_filtered(r, accept).is_some()).count();
    n + shadow.iter().filter(|r| q.any_hit_filtered(r, accept)).count()
}

fn main() {
    let res = 128;
    let teapot = Scene::load("teapot12").expect("scene").into_patches(DEFAULT_RESOLUTION);
    let tris: Vec<Triangle> = teapot.triangles();
    let eye = rays::camera_rays(&teapot.camera, res);
    let tiles = rays::camera_tiles(&teapot.camera, res, 8);
    let light = teapot.lights.first().map_or(teapot.camera.from, |l| l.pos);
    let default = Bvh::new(&tris);
    let shadow = rays::shadow_rays(&default, &eye, &[light]);
    let tile_shadow = rays::shadow_rays(&default, &tiles, &[light]);
    let mut total = 0;
    let of = |l: &str| BuildOptions::default().layout(l.parse::<Layout>().expect("layout"));
    total += bvh8_single(&default, &eye, &shadow);
    total += bvh8_packets(&default, &tiles, &tile_shadow);
    total += k_bvh8_counted(&default, &eye, &shadow);
    total += k_bvh8_filtered(&default, &eye, &shadow);
    let b4 = of("bvh4-dfs").build(&tris);
    total += bvh4_single(&b4, &eye, &shadow);
    total += bvh4_packets(&b4, &tiles, &tile_shadow);
    let q4 = of("bvh4-quant").build(&tris);
    total += qbvh4_single(&q4, &eye, &shadow);
    total += qbvh4_packets(&q4, &tiles, &tile_shadow);
    let b2 = of("bvh2-dfs").build(&tris);
    total += bvh2_dfs_single(&b2, &eye, &shadow);
    let b2c = of("bvh2-compact").build(&tris);
    total += bvh2_compact_single(&b2c, &eye, &shadow);
    let wt: Vec<Watertight> = tris.iter().map(|&t| Watertight(t)).collect();
    let wt = Bvh::new(&wt);
    total += watertight_single(&wt, &eye, &shadow);
    total += watertight_packets(&wt, &tiles, &tile_shadow);

    let balls = Scene::load("balls3").expect("scene");
    let mixed = SceneBvh::build(&balls, &BuildOptions::default());
    let beye = rays::camera_rays(&balls.camera, res);
    let btiles = rays::camera_tiles(&balls.camera, res, 8);
    let blight = balls.lights.first().map_or(balls.camera.from, |l| l.pos);
    let bshadow = rays::shadow_rays(&mixed, &beye, &[blight]);
    let btshadow = rays::shadow_rays(&mixed, &btiles, &[blight]);
    total += mixed_single(&mixed, &beye, &bshadow);
    total += mixed_packets(&mixed, &btiles, &btshadow);

    let lattice = Scene::load("lattice4").expect("scene");
    let world = SceneBvh::build_instanced(&lattice, DEFAULT_RESOLUTION, &BuildOptions::default())
        .expect("an instanced world");
    let leye = rays::camera_rays(&lattice.camera, res);
    let ltiles = rays::camera_tiles(&lattice.camera, res, 8);
    let llight = lattice.lights.first().map_or(lattice.camera.from, |l| l.pos);
    let lshadow = rays::shadow_rays(&world, &leye, &[llight]);
    let ltshadow = rays::shadow_rays(&world, &ltiles, &[llight]);
    total += world_single(&world, &leye, &lshadow);
    total += world_packets(&world, &ltiles, &ltshadow);
    total += k_world_filtered(&world, &leye, &lshadow);
    println!("kernel_counts: {total} answers (teapot12 {} tris, {} eye rays a scene)", tris.len(), eye.len());
}
