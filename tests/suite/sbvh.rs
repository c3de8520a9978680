//! The spatial-split builder (`Builder::Sbvh`, `BuildOptions::high_quality`) against the f64
//! oracle and the brute-force reference on long, thin, overlapping triangles, where its
//! spatial splits put one triangle in several leaves: every layout and instruction set must
//! still report each primitive once, by its input index, at its true distance. Also its
//! reference budget, its independence of the thread count, its SAH cost against the binned
//! tree's, and refits of its trees.

use crate::common::in_pool;
use glam::Vec3A;
use quiver_lab::oracle::{Answer, Oracle};
use quiver_lab::rays;
use quiver_rt::builders::{build, prim_bounds, BuildConfig, BuildTree, Builder};
use quiver_rt::intersect::Watertight;
use quiver_rt::traverse::reference;
use quiver_rt::{BuildOptions, Bvh, Isa, Layout, Primitive, Ray, RayQuery, Triangle};
use rayon::prelude::*;

/// A small deterministic generator (xorshift64*), so the scenes need no other crate.
struct Gen(u64);

impl Gen {
    fn f32(&mut self) -> f32 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        ((self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 40) as f32) / (1u64 << 24) as f32
    }

    fn point(&mut self, lo: Vec3A, hi: Vec3A) -> Vec3A {
        lo + (hi - lo) * Vec3A::new(self.f32(), self.f32(), self.f32())
    }
}

/// `n` long, thin triangles in a 10-unit cube: each runs between two random points (most of
/// the cube's width apart) and is a few hundredths wide, so they cross and overlap everywhere;
/// one in eight is a small triangle on its own, so leaves also see ordinary geometry.
fn slivers(n: usize, seed: u64) -> Vec<Triangle> {
    let mut g = Gen(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1);
    let (lo, hi) = (Vec3A::ZERO, Vec3A::splat(10.0));
    (0..n)
        .map(|i| {
            let a = g.point(lo, hi);
            if i % 8 == 7 {
                let d = Vec3A::splat(0.3);
                return Triangle::new(a, g.point(a - d, a + d), g.point(a - d, a + d));
            }
            let b = g.point(lo, hi);
            let w = g.point(Vec3A::splat(-0.04), Vec3A::splat(0.04));
            Triangle::new(a, b, b + w)
        })
        .collect()
}

/// Rays aimed at points inside the triangles (where spatial splits cut them) from random
/// origins, and random rays through the box.
fn rays_for(tris: &[Triangle], n: usize, seed: u64) -> Vec<Ray> {
    let mut g = Gen(seed | 1);
    let b = prim_bounds(tris)
        .iter()
        .fold(quiver_rt::Aabb::EMPTY, |a, b| a.union(b));
    let mut out = rays::random_rays(&b, n / 2, seed);
    while out.len() < n {
        let t = &tris[(g.f32() * tris.len() as f32) as usize % tris.len()];
        let (mut u, mut v) = (g.f32(), g.f32());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        let target = t.v[0] + (t.v[1] - t.v[0]) * u + (t.v[2] - t.v[0]) * v;
        let origin = g.point(b.min - Vec3A::splat(2.0), b.max + Vec3A::splat(2.0));
        out.push(Ray::new(origin, target - origin));
    }
    out
}

/// The most references an SBVH over `n` primitives may hold.
fn budget(n: usize) -> usize {
    n + (n as f64 * 0.3).floor() as usize
}

/// Checks every query of `bvh` against the oracle's answers `want` (and the brute-force
/// reference where the oracle allows more than one answer).
fn against_oracle<P: Primitive>(
    bvh: &Bvh<P>,
    prims: &[P],
    rays: &[Ray],
    want: &[Answer],
    what: &str,
) {
    rays.par_iter()
        .zip(want)
        .enumerate()
        .for_each(|(i, (ray, w))| {
            let got = bvh.closest_hit(ray);
            if let Err(e) = w.check(got) {
                panic!("{what}: ray {i} {ray:?}: {e}");
            }
            if !w.is_decidable() {
                assert_eq!(got, reference::closest_hit(prims, ray), "{what}: ray {i}");
            }
            assert_eq!(bvh.any_hit(ray), got.is_some(), "{what}: any hit, ray {i}");
        });
}

#[test]
fn sbvh_gives_the_oracles_hits_in_every_layout_and_isa() {
    let tris = slivers(3000, 1);
    let rays = rays_for(&tris, 20_000, 2);
    let oracle = Oracle::new(&tris).closest_hits(&rays);
    let water: Vec<Watertight> = tris.iter().map(|&t| Watertight(t)).collect();
    for layout in Layout::ALL {
        let options = BuildOptions::high_quality().layout(layout);
        let (bvh, tree) = Bvh::build_with_tree(&tris, &options).unwrap();
        // The scene must make the builder split triangles, or this tests nothing new (at
        // least one in twenty: the spatial pass skips nodes below 64 references since the
        // cheaper binning, so 3000 slivers hold fewer pieces than the one in ten they did).
        assert!(
            tree.prim_indices.len() > tris.len() + tris.len() / 20,
            "{layout}: only {} references for {} triangles",
            tree.prim_indices.len(),
            tris.len()
        );
        tree.check(&prim_bounds(&tris), &options.config).unwrap();
        let water_bvh = Bvh::build(&water, &options).unwrap();
        for isa in Isa::ALL {
            let bvh = bvh.clone().with_isa(isa);
            if bvh.isa() != isa {
                continue;
            }
            against_oracle(&bvh, &tris, &rays, &oracle, &format!("{layout} {isa}"));
            let water_bvh = water_bvh.clone().with_isa(isa);
            against_oracle(
                &water_bvh,
                &water,
                &rays,
                &oracle,
                &format!("{layout} {isa} watertight"),
            );
        }
        // A mesh build clips the same triangles: the same tree.
        let positions: Vec<[f32; 3]> = tris.iter().flat_map(|t| t.v.map(|v| v.into())).collect();
        let indices: Vec<[u32; 3]> = (0..tris.len() as u32)
            .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
            .collect();
        let (mesh_bvh, mesh_tree) =
            Bvh::build_mesh_with_tree(&positions, &indices, &options).unwrap();
        assert_eq!(mesh_tree, tree, "{layout}");
        against_oracle(&mesh_bvh, &tris, &rays, &oracle, &format!("{layout} mesh"));
    }
}

#[test]
fn sbvh_over_boxes_is_valid_and_answers_through_from_tree() {
    // `builders::build` clips boxes, not triangles: the tree is coarser but just as valid,
    // and laid out by `from_tree` (boxes recomputed from whole triangles) it answers right.
    let tris = slivers(2000, 3);
    let bounds = prim_bounds(&tris);
    let config = BuildConfig::default();
    let tree = build(&bounds, &config, Builder::Sbvh).unwrap();
    tree.check(&bounds, &config).unwrap();
    assert!(tree.prim_indices.len() > tris.len());
    assert!(tree.prim_indices.len() <= budget(tris.len()));
    let rays = rays_for(&tris, 5000, 4);
    let oracle = Oracle::new(&tris).closest_hits(&rays);
    for layout in Layout::ALL {
        let bvh = Bvh::from_tree(&tree, &tris, &BuildOptions::default().layout(layout)).unwrap();
        against_oracle(&bvh, &tris, &rays, &oracle, &format!("from_tree {layout}"));
    }
}

#[test]
fn sbvh_references_stay_within_the_budget() {
    // Slivers that all span the whole box on x (every spatial split on x cuts all of them)
    // push the budget hardest; so do the ordinary slivers at several leaf sizes.
    let mut g = Gen(99);
    let spanning: Vec<Triangle> = (0..5000)
        .map(|_| {
            let (y, z) = (g.f32() * 10.0, g.f32() * 10.0);
            let y2 = g.f32() * 10.0;
            Triangle::new(
                Vec3A::new(0.0, y, z),
                Vec3A::new(10.0, y2, z),
                Vec3A::new(10.0, y2, z + 0.01),
            )
        })
        .collect();
    for (what, tris) in [("spanning", spanning), ("slivers", slivers(20_000, 5))] {
        for leaf in [1, 4, 8] {
            let options = BuildOptions::high_quality().max_leaf_size(leaf);
            let (_, tree) = Bvh::build_with_tree(&tris, &options).unwrap();
            let (refs, max) = (tree.prim_indices.len(), budget(tris.len()));
            println!(
                "{what}, leaves of {leaf}: {refs} references for {}",
                tris.len()
            );
            assert!(
                refs <= max,
                "{what} {leaf}: {refs} references, budget {max}"
            );
            assert!(refs > tris.len(), "{what} {leaf}: no spatial split taken");
            tree.check(&prim_bounds(&tris), &options.config).unwrap();
            let boxes = build(&prim_bounds(&tris), &options.config, Builder::Sbvh).unwrap();
            assert!(boxes.prim_indices.len() <= max, "{what} {leaf}: boxes");
        }
    }
}

#[test]
fn sbvh_tree_is_the_same_on_one_and_two_threads() {
    // Large enough for parallel binning (32k references) and parallel subtrees.
    let tris = slivers(60_000, 7);
    let options = BuildOptions::high_quality();
    let one: BuildTree = in_pool(1, || Bvh::build_with_tree(&tris, &options).unwrap().1);
    let two: BuildTree = in_pool(2, || Bvh::build_with_tree(&tris, &options).unwrap().1);
    assert!(one.prim_indices.len() > tris.len());
    assert_eq!(one, two);
    let bounds = prim_bounds(&tris);
    let config = BuildConfig::default();
    let one = in_pool(1, || build(&bounds, &config, Builder::Sbvh).unwrap());
    let two = in_pool(2, || build(&bounds, &config, Builder::Sbvh).unwrap());
    assert_eq!(one, two);
}

#[test]
fn sbvh_tree_costs_less_than_the_binned_tree_on_long_triangles() {
    // Not a theorem for whole trees: each node takes the cheaper of its best object split
    // (the binned builder's candidates, the same bins) and a spatial split, but a cheaper
    // split at one node need not make its subtree cheaper. On slivers across the whole box,
    // though, no object split can separate them: both children of every object split keep
    // boxes near their parent's, while a spatial split halves the boxes. The tree SAH is
    // exact for both (boxes from the build), so this compares the trees the tracers walk.
    for (n, seed) in [(5000, 11), (40_000, 12)] {
        let tris = slivers(n, seed);
        let config = BuildConfig::default();
        let (_, binned) = Bvh::build_with_tree(&tris, &BuildOptions::default()).unwrap();
        let (_, sbvh) = Bvh::build_with_tree(&tris, &BuildOptions::high_quality()).unwrap();
        let (b, s) = (binned.sah_cost(&config), sbvh.sah_cost(&config));
        println!("{n} slivers: SAH cost binned {b:.1}, sbvh {s:.1}");
        assert!(s <= b, "{n}: sbvh {s} > binned {b}");
    }
}

#[test]
fn refit_of_an_sbvh_is_correct_and_never_tighter() {
    // A refit boxes whole primitives: every box still contains what its leaves hold, so
    // answers stay the oracle's, and the cost cannot fall below the clipped build's.
    let tris = slivers(3000, 13);
    let moved: Vec<Triangle> = tris
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let d = Vec3A::new((i % 7) as f32 * 0.01, 0.0, (i % 3) as f32 * 0.02);
            Triangle::new(t.v[0] + d, t.v[1], t.v[2] - d)
        })
        .collect();
    let rays = rays_for(&tris, 5000, 14);
    let at_rest = Oracle::new(&tris).closest_hits(&rays);
    let now = Oracle::new(&moved).closest_hits(&rays);
    for layout in Layout::ALL {
        let mut bvh = Bvh::build(&tris, &BuildOptions::high_quality().layout(layout)).unwrap();
        let built = bvh.sah_cost();
        bvh.refit(&tris).unwrap();
        assert!(bvh.sah_cost() >= built, "{layout}");
        against_oracle(
            &bvh,
            &tris,
            &rays,
            &at_rest,
            &format!("{layout} refit in place"),
        );
        bvh.refit(&moved).unwrap();
        against_oracle(&bvh, &moved, &rays, &now, &format!("{layout} refit moved"));
        assert!(bvh.refit(&moved[1..]).is_err());
    }
}
