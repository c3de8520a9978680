//! Build invariants: identical trees for any thread count, degenerate inputs, exact SAH cost.

use crate::common::{in_pool, tri};
use glam::Vec3A;
use quiver_lab::rays;
use quiver_rt::builders::{
    build, optimize, prim_bounds, BuildConfig, BuildTree, Builder, NodeKind, MAX_DEPTH,
};
use quiver_rt::layout::{Bvh2, Bvh2Mapping};
use quiver_rt::traverse::reference;
use quiver_rt::{Aabb, Bvh, RayQuery, Triangle};
use quiver_scenes::rng::Rng;
use quiver_scenes::Scene;

const BUILDERS: [Builder; Builder::ALL.len()] = Builder::ALL;

#[test]
fn same_tree_for_one_and_two_threads() {
    let scene = Scene::load("soup150000").unwrap();
    let bounds = prim_bounds(&scene.triangles());
    // A low threshold sends many nodes through the horizontal (shared-node) path as well;
    // only the binned builders have that path. The SBVH has a test of its own
    // (`sbvh::sbvh_tree_is_the_same_on_one_and_two_threads`).
    for horizontal_threshold in [1 << 16, 2_000] {
        let config = BuildConfig {
            horizontal_threshold,
            ..BuildConfig::default()
        };
        let binned = |b: &Builder| matches!(b, Builder::Binned | Builder::BinnedOpt);
        let builders = BUILDERS.into_iter().filter(|b| *b != Builder::Sbvh);
        for builder in builders.filter(|b| horizontal_threshold == 1 << 16 || binned(b)) {
            let one = in_pool(1, || build(&bounds, &config, builder).unwrap());
            let two = in_pool(2, || build(&bounds, &config, builder).unwrap());
            one.check(&bounds, &config).unwrap();
            assert!(
                one == two,
                "{builder}: trees differ between 1 and 2 threads"
            );
        }
    }
}

#[test]
fn horizontal_and_vertical_give_the_same_tree() {
    let scene = Scene::load("tetra8").unwrap();
    let bounds = prim_bounds(&scene.triangles());
    let build_with = |horizontal_threshold| {
        let config = BuildConfig {
            horizontal_threshold,
            ..BuildConfig::default()
        };
        in_pool(2, || build(&bounds, &config, Builder::Binned).unwrap())
    };
    assert!(
        build_with(usize::MAX) == build_with(64),
        "horizontal partitioning changed the tree"
    );
}

/// Builds with both builders and several leaf sizes, validates, and checks traversal against
/// the reference on rays aimed at the geometry.
fn check_degenerate(name: &str, tris: &[Triangle]) -> Vec<BuildTree> {
    let bounds = prim_bounds(tris);
    let mut trees = Vec::new();
    for max_leaf_size in [1, 4, 8] {
        let config = BuildConfig {
            max_leaf_size,
            ..BuildConfig::default()
        };
        for builder in BUILDERS {
            let tree = build(&bounds, &config, builder).unwrap();
            tree.check(&bounds, &config)
                .unwrap_or_else(|e| panic!("{name} {builder} leaf {max_leaf_size}: {e}"));
            assert!(
                tree.stats().depth <= MAX_DEPTH,
                "{name}: depth {}",
                tree.stats().depth
            );
            let bvh = Bvh2::from_tree(&tree, tris, Bvh2Mapping::DepthFirst)
                .expect("a built tree fits its primitives");
            let finite = tris
                .iter()
                .filter(|t| t.is_finite())
                .fold(Aabb::EMPTY, |b, t| b.union(&t.bounds()));
            let mut rays = rays::random_rays(&finite, 300, 5);
            // Also rays straight at each (finite) triangle's centroid.
            rays.extend(tris.iter().filter(|t| t.is_finite()).take(300).map(|t| {
                let c = (t.v[0] + t.v[1] + t.v[2]) / 3.0;
                let o = c + Vec3A::new(0.3, 0.2, 1.0) * (1.0 + c.abs().max_element());
                quiver_rt::Ray::new(o, c - o)
            }));
            for r in &rays {
                assert_eq!(
                    bvh.closest_hit(r),
                    reference::closest_hit(tris, r),
                    "{name} {builder}: {r:?}"
                );
                assert_eq!(
                    bvh.any_hit(r),
                    reference::any_hit(tris, r),
                    "{name} {builder}: {r:?}"
                );
            }
            trees.push(tree);
        }
    }
    trees
}

#[test]
fn zero_primitives() {
    for tree in check_degenerate("empty", &[]) {
        assert_eq!(tree.nodes.len(), 1);
        assert_eq!(tree.nodes[0].kind, NodeKind::Leaf { first: 0, count: 0 });
    }
}

#[test]
fn one_primitive() {
    for tree in check_degenerate("one", &[tri([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])]) {
        assert_eq!(tree.nodes.len(), 1);
        assert_eq!(tree.prim_indices, vec![0]);
    }
}

#[test]
fn all_centroids_equal() {
    // 1000 copies of one triangle, and 1000 different triangles sharing one centroid.
    let t = tri([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
    check_degenerate("copies", &vec![t; 1000]);
    let mut rng = Rng::new(3);
    let star: Vec<Triangle> = (0..1000)
        .map(|_| {
            let a = rng.unit_vector();
            let b = rng.unit_vector();
            Triangle::new(a, b, -(a + b))
        })
        .collect();
    check_degenerate("star", &star);
}

#[test]
fn all_geometry_in_one_plane() {
    let mut rng = Rng::new(4);
    let flat: Vec<Triangle> = (0..5000)
        .map(|_| {
            let c = Vec3A::new(rng.f32(), rng.f32(), 0.0) * 10.0;
            tri(
                c.into(),
                (c + Vec3A::X * 0.1).into(),
                (c + Vec3A::Y * 0.1).into(),
            )
        })
        .collect();
    check_degenerate("flat", &flat);
}

#[test]
fn coordinates_spanning_1e_minus6_to_1e7() {
    let mut rng = Rng::new(5);
    let mut tris = Vec::new();
    for i in 0..3000 {
        // Sizes and positions from 1e-6 to 1e7, interleaved.
        let scale = 10f32.powf(-6.0 + 13.0 * (i % 100) as f32 / 99.0);
        let c = rng.in_box(Vec3A::splat(-1.0), Vec3A::ONE) * scale;
        let e = scale * 0.1;
        tris.push(tri(
            c.into(),
            (c + Vec3A::X * e).into(),
            (c + Vec3A::new(0.0, e, e)).into(),
        ));
    }
    check_degenerate("scales", &tris);
    // Exponentially spaced centroids: the SAH would peel one primitive per level.
    let expo: Vec<Triangle> = (0..2000)
        .map(|i| {
            let x = 1.02f32.powi(i) * 1e-6;
            tri([x, 0.0, 0.0], [x, 1e-6, 0.0], [x, 0.0, 1e-6])
        })
        .collect();
    check_degenerate("exponential", &expo);
}

#[test]
fn coordinates_near_the_largest_float() {
    // Finite but huge: box areas overflow to infinity (and SAH sums to NaN), which must not
    // stop any builder, and every tree must still hold every triangle once.
    let mut rng = Rng::new(6);
    let tris: Vec<Triangle> = (0..2000)
        .map(|i| {
            // 1.5e38: the box from -s to s spans 3e38, still below f32::MAX.
            let s = [1.5e38f32, 1e20, 1.0, 1e-30][i % 4];
            let mut v = || rng.in_box(Vec3A::splat(-s), Vec3A::splat(s));
            Triangle::new(v(), v(), v())
        })
        .collect();
    assert!(tris.iter().all(|t| t.is_finite()));
    for tree in check_degenerate("huge", &tris) {
        assert_eq!(tree.dropped, 0);
    }
}

#[test]
fn non_finite_vertices_are_dropped_and_counted() {
    let good = tri([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
    let mut tris = vec![good; 10];
    tris[2].v[1].x = f32::NAN;
    tris[5].v[0].y = f32::INFINITY;
    tris[7].v[2].z = f32::NEG_INFINITY;
    for tree in check_degenerate("non-finite", &tris) {
        assert_eq!(tree.dropped, 3);
        let mut refs = tree.prim_indices.clone();
        refs.sort();
        assert_eq!(refs, vec![0, 1, 3, 4, 6, 8, 9]);
    }
    // Nothing finite at all.
    let nan = tri([f32::NAN; 3], [0.0; 3], [1.0; 3]);
    for tree in check_degenerate("all-nan", &[nan; 5]) {
        assert_eq!((tree.dropped, tree.nodes.len()), (5, 1));
    }
}

fn unit_box(x: f32) -> Aabb {
    Aabb::new(Vec3A::new(x, 0.0, 0.0), Vec3A::new(x + 1.0, 1.0, 1.0))
}

#[test]
fn sah_cost_matches_hand_computation() {
    // Two unit cubes, x in [0,1] and [2,3]: the root box is 3×1×1 with half area 3+1+3 = 7,
    // each leaf has half area 3. C = c_T·7/7 + c_I·(3·1 + 3·1)/7.
    let boxes = [unit_box(0.0), unit_box(2.0)];
    for builder in BUILDERS {
        let config = BuildConfig {
            traversal_cost: 1.5,
            intersection_cost: 2.0,
            ..BuildConfig::default()
        };
        let tree = build(&boxes, &config, builder).unwrap();
        assert_eq!(
            tree.stats().leaves,
            2,
            "{builder}: two far-apart boxes must be split"
        );
        let want = 1.5 * 7.0 / 7.0 + 2.0 * 6.0 / 7.0;
        assert!((tree.sah_cost(&config) - want).abs() < 1e-9, "{builder}");
    }
}

#[test]
fn sah_leaf_decision() {
    // Four overlapping cubes: splitting cannot reduce the area, so with a costly traversal
    // the root stays a leaf; with a free traversal every cube gets its own leaf when apart.
    let overlapping: Vec<Aabb> = (0..4).map(|i| unit_box(i as f32 * 0.01)).collect();
    let apart: Vec<Aabb> = (0..4).map(|i| unit_box(i as f32 * 10.0)).collect();
    for builder in BUILDERS {
        let costly = BuildConfig {
            traversal_cost: 10.0,
            ..BuildConfig::default()
        };
        assert_eq!(
            build(&overlapping, &costly, builder).unwrap().nodes.len(),
            1,
            "{builder}"
        );
        let free = BuildConfig {
            traversal_cost: 0.0,
            ..BuildConfig::default()
        };
        assert_eq!(
            build(&apart, &free, builder).unwrap().stats().leaves,
            4,
            "{builder}"
        );
        // The maximum leaf size wins over the SAH.
        let tiny_leaves = BuildConfig {
            max_leaf_size: 1,
            ..costly
        };
        assert_eq!(
            build(&overlapping, &tiny_leaves, builder)
                .unwrap()
                .stats()
                .leaves,
            4,
            "{builder}"
        );
    }
}

/// The binned builder's SAH cost stays within 3% of the full-sweep reference's (the quality
/// target) on a regular mesh and on a random soup, whose uneven primitive sizes are where 16
/// bins lose most against every-plane evaluation.
#[test]
fn binned_sah_within_3_percent_of_sweep() {
    let config = BuildConfig::default();
    for name in ["tetra7", "soup20000"] {
        let scene = Scene::load(name).unwrap();
        let bounds = prim_bounds(&scene.triangles());
        let binned = build(&bounds, &config, Builder::Binned)
            .unwrap()
            .sah_cost(&config);
        let sweep = build(&bounds, &config, Builder::Sweep)
            .unwrap()
            .sah_cost(&config);
        println!(
            "{name}: binned {binned:.3} sweep {sweep:.3} ratio {:.4}",
            binned / sweep
        );
        assert!(
            binned <= sweep * 1.03,
            "{name}: binned {binned} vs sweep {sweep}"
        );
    }
}

/// The ray-termination cost models keep the build invariants: valid trees, identical for any
/// thread count (their float area sums are added in a fixed order, also on the horizontal
/// path).
#[test]
fn cost_models_build_valid_trees_independent_of_threads() {
    use quiver_rt::builders::{build_with_areas, CostModel};
    use quiver_rt::Primitive;
    let tris = Scene::load("soup40000").unwrap().triangles();
    let bounds = prim_bounds(&tris);
    let areas: Vec<f32> = tris.iter().map(|t| t.surface_area()).collect();
    for cost_model in [CostModel::Rtsah, CostModel::Srdh] {
        let config = BuildConfig {
            cost_model,
            horizontal_threshold: 4_000,
            ..BuildConfig::default()
        };
        // The cost models are the top-down builders' (see `build_with_areas`).
        for builder in [Builder::Binned, Builder::Sweep] {
            let at = |threads| {
                in_pool(threads, || {
                    build_with_areas(&bounds, Some(&areas), &config, builder).unwrap()
                })
            };
            let one = at(1);
            one.check(&bounds, &config)
                .unwrap_or_else(|e| panic!("{cost_model} {builder}: {e}"));
            assert!(one == at(2), "{cost_model} {builder}: 1 vs 2 threads");
            assert!(one == at(3), "{cost_model} {builder}: 1 vs 3 threads");
        }
    }
}

/// RTSAH spares a child's primitive tests only for rays stopped in the other child: with
/// primitives of no surface (nothing stops a ray) it is the SAH, split for split and leaf for
/// leaf. And the SAH ignores the areas it is given.
#[test]
fn rtsah_without_occlusion_is_the_sah() {
    use quiver_rt::builders::{build_with_areas, CostModel};
    let tris = Scene::load("teapot6").unwrap().triangles();
    let bounds = prim_bounds(&tris);
    let zeros = vec![0.0; bounds.len()];
    let ones = vec![1.0; bounds.len()];
    for builder in [Builder::Binned, Builder::Sweep] {
        let sah = build(&bounds, &BuildConfig::default(), builder).unwrap();
        let rtsah = BuildConfig {
            cost_model: CostModel::Rtsah,
            ..BuildConfig::default()
        };
        assert!(
            build_with_areas(&bounds, Some(&zeros), &rtsah, builder).unwrap() == sah,
            "{builder}: RTSAH with no occlusion differs from the SAH"
        );
        let with_areas =
            build_with_areas(&bounds, Some(&ones), &BuildConfig::default(), builder).unwrap();
        assert!(with_areas == sah, "{builder}: the SAH read the areas");
        // Occluding primitives do change it (else the model would be dead weight).
        assert!(build_with_areas(&bounds, Some(&ones), &rtsah, builder).unwrap() != sah);
    }
}

/// The insertion-based optimisation keeps the tree of least inner-node area it saw (the
/// leaves, and so their cost, stay as they are), and the SAH compaction after it merges only
/// where that is cheaper, so as a pass over any builder's tree it never raises the SAH cost
/// (up to the order in which f64 sums add the same areas), and its output is a valid tree
/// over the same primitives.
#[test]
fn optimisation_never_raises_the_cost() {
    let config = BuildConfig::default();
    for name in ["teapot6", "soup5000"] {
        let tris = Scene::load(name).unwrap().triangles();
        let bounds = prim_bounds(&tris);
        for builder in BUILDERS {
            let tree = build(&bounds, &config, builder).unwrap();
            let better = optimize(&tree, &bounds, &config).unwrap();
            better
                .check(&bounds, &config)
                .unwrap_or_else(|e| panic!("{name} {builder}: {e}"));
            let (before, after) = (tree.sah_cost(&config), better.sah_cost(&config));
            assert!(
                after <= before * (1.0 + 1e-9),
                "{name} {builder}: {before} -> {after}"
            );
        }
    }
}

/// The splits of `tree` a leaf could have replaced (subtrees within `max_leaf_size`), each
/// checked to pay under `config`'s count of tests: `c_T + c_I·Σ (A_child / A)·tests(child)`
/// below `c_I·tests(n)`, computed here in f64 from the tree's boxes (the builders score in
/// f32, hence the relative slack of 1e-5). Returns how many there are.
fn optional_splits_that_pay(tree: &BuildTree, config: &BuildConfig, what: &str) -> usize {
    let nodes = &tree.nodes;
    let mut count = vec![0usize; nodes.len()];
    for i in (0..nodes.len()).rev() {
        count[i] = match nodes[i].kind {
            NodeKind::Leaf { count, .. } => count as usize,
            NodeKind::Inner { left, right } => count[left as usize] + count[right as usize],
        };
    }
    let tests = |n: usize| config.tests(n) as f64;
    let (ct, ci) = (
        config.traversal_cost as f64,
        config.intersection_cost as f64,
    );
    let mut optional = 0;
    for (i, node) in nodes.iter().enumerate() {
        let NodeKind::Inner { left, right } = node.kind else {
            continue;
        };
        let n = count[i];
        if n > config.max_leaf_size {
            continue;
        }
        optional += 1;
        let area = node.bounds.half_area_f64();
        let child =
            |c: u32| nodes[c as usize].bounds.half_area_f64() / area * tests(count[c as usize]);
        let split = ct + ci * (child(left) + child(right));
        let leaf = ci * tests(n);
        assert!(
            split < leaf * (1.0 + 1e-5),
            "{what}: node {i} of {n} split at cost {split} over a leaf's {leaf}"
        );
    }
    optional
}

/// With the leaves counted in SIMD groups of four, a node within the leaf size is split
/// only where the group tests it saves pay for the extra box test: on a random soup the
/// grouped builds keep far fewer such splits than the builds counting single triangles, and
/// every split they keep pays under their own count. The default BVH over triangles (8-wide)
/// builds with the groups, the binary layout without them.
#[test]
fn leaves_counted_in_groups_split_only_where_the_group_cost_pays() {
    let tris = Scene::load("soup3000").unwrap().triangles();
    let bounds = prim_bounds(&tris);
    let single = BuildConfig {
        leaf_group: 1,
        ..BuildConfig::default()
    };
    let grouped = BuildConfig {
        leaf_group: 4,
        ..BuildConfig::default()
    };
    assert_eq!(grouped.tests(5), 2.0 * quiver_rt::builders::GROUP_TEST_COST);
    for builder in [Builder::Binned, Builder::Sweep] {
        let one = build(&bounds, &single, builder).unwrap();
        let four = build(&bounds, &grouped, builder).unwrap();
        four.check(&bounds, &grouped)
            .unwrap_or_else(|e| panic!("{builder}: {e}"));
        let (s1, s4) = (
            optional_splits_that_pay(&one, &single, &format!("{builder} single")),
            optional_splits_that_pay(&four, &grouped, &format!("{builder} grouped")),
        );
        println!("{builder}: optional splits single {s1}, grouped {s4}");
        assert!(s4 * 4 < s1, "{builder}: grouped {s4} vs single {s1}");
        assert!(
            four.stats().leaves < one.stats().leaves,
            "{builder}: leaves {} vs {}",
            four.stats().leaves,
            one.stats().leaves
        );
    }
    let leaves = |layout| {
        Bvh::build_with_tree(&tris, &quiver_rt::BuildOptions::default().layout(layout))
            .unwrap()
            .1
            .stats()
            .leaves
    };
    assert!(leaves(quiver_rt::Layout::Bvh8Dfs) < leaves(quiver_rt::Layout::Bvh2Dfs));
}
