//! The surface-area predictor against measurement: over isotropic random lines through the
//! root box, the nodes, leaves, box tests and primitive tests a non-stopping walk makes per
//! line equal `quiver_rt::predict`'s sums in expectation (Cauchy–Crofton), for every builder and
//! layout. The oracle is the identity; the tolerance is four standard errors of the sample.

use quiver_rt::builders::Builder;
use quiver_rt::predict::{predict, Prediction};
use quiver_rt::{BuildOptions, Bvh, Layout};
use quiver_lab::lines::{isotropic_lines, pierced, Pierce, Sample};
use quiver_scenes::Scene;

fn within(what: &str, scene: &str, s: Sample, predicted: f64) {
    let tol = 4.0 * s.std_error + 1e-9 * predicted.abs();
    assert!(
        (s.mean - predicted).abs() <= tol,
        "{scene} {what}: measured {} ± {} (1 s.e.), predicted {predicted}",
        s.mean,
        s.std_error
    );
}

fn check(
    scene: &str,
    name: &str,
    p: &Prediction,
    ghost: &Bvh<Pierce<quiver_rt::Triangle>>,
    lines: &[quiver_rt::Ray],
) {
    let m = pierced(ghost, lines);
    within(&format!("{name} nodes"), scene, m.nodes, p.nodes);
    within(&format!("{name} leaves"), scene, m.leaves, p.leaves);
    within(
        &format!("{name} box tests"),
        scene,
        m.box_tests,
        p.box_tests,
    );
    within(
        &format!("{name} primitive tests"),
        scene,
        m.prim_tests,
        p.prim_tests,
    );
}

#[test]
fn crofton_prediction_matches_pierced_lines() {
    // Closed meshes, scattered spheres as triangles, a fractal with holes, and a flat-ish
    // random soup: different shapes of tree.
    for scene in ["tetra4", "balls1", "gears1", "teapot6", "soup2000"] {
        let tris = Scene::load(scene).unwrap().triangles();
        let ghosts = Pierce::of(&tris);
        for builder in Builder::ALL {
            let (_, tree) = BuildOptions::default()
                .builder(builder)
                .build_with_tree(&tris);
            let root = tree.nodes[0].bounds;
            let lines = isotropic_lines(&root, 40_000, 17);
            let ghost2 = Bvh::from_tree(
                &tree,
                &ghosts,
                &BuildOptions::default().layout(Layout::Bvh2Dfs),
            )
            .expect("a built tree fits its primitives");
            // `from_tree` boxes whole primitives, where an SBVH's leaves box only their pieces:
            // its ghosts are walked over other boxes than the build's, so predict those.
            let sbvh = builder == Builder::Sbvh;
            let tree_p = if sbvh {
                predict(&ghost2)
            } else {
                predict(&tree)
            };
            check(scene, &format!("{builder} tree"), &tree_p, &ghost2, &lines);
            for layout in Layout::ALL {
                // The tree the ghosts walk, laid out over the triangles: a fresh build in a
                // binary layout would count its leaves otherwise and make another tree.
                let bvh = Bvh::from_tree(&tree, &tris, &BuildOptions::default().layout(layout))
                    .expect("a built tree fits its primitives");
                let ghost = Bvh::from_tree(&tree, &ghosts, &BuildOptions::default().layout(layout))
                    .expect("a built tree fits its primitives");
                let p = if sbvh {
                    ghost.predict_within(&root)
                } else {
                    bvh.predict_within(&root)
                };
                check(scene, &format!("{builder} {layout}"), &p, &ghost, &lines);
            }
        }
    }
}
