//! Havran's minimum testing output as the renderer reports it, held to what holds by
//! definition: a recording of the render's queries sees exactly the rays the renderer counts,
//! with exactly its hits (eye and secondary hits, blocked shadow rays: `r_SI · N_rays`); every
//! recorded hit is found again by the one test of Havran's ideal algorithm; the recorded rays
//! traced alone give the recorded answers; and the ratios keep his inequalities
//! (`r_ITM >= 1`, `N_EETS <= N_ETS <= N_TS`). The census of a layout counts every primitive
//! once, and a binary tree has one more leaf than inner nodes.

use crate::common::in_pool;
use quiver_rt::predict::census;
use quiver_rt::traverse::{ConservativeBoxes, NoFilter, NoStats};
use quiver_rt::{BuildOptions, Layout, RayQuery};
use quiver_scenes::accel::SceneBvh;
use quiver_scenes::render::{render, RenderConfig};
use quiver_scenes::scene::Scene;

#[test]
fn recorded_queries_match_the_render_and_havrans_inequalities() {
    // Reflection and refraction (balls, mount), many lights (rings), analytic shapes (gears).
    for name in ["balls1", "mount2", "rings1", "gears1"] {
        let scene = Scene::load(name).unwrap();
        let layout = Layout::Bvh4Dfs;
        let bvh = SceneBvh::build(&scene, &BuildOptions::default().layout(layout));
        let rec = bvh.clone().recording();
        let config = RenderConfig {
            res: 48,
            two_sided: scene.two_sided_materials(),
            counters: true,
            packets: false,
            ..RenderConfig::default()
        };
        let out = in_pool(2, || render(&scene, &rec, &config, &|_| {}));
        let traced = rec.recorded();
        let rays = out.rays;
        assert_eq!(traced.len() as u64, rays.total(), "{name}: rays recorded");
        let closest_hits = traced.iter().filter(|t| !t.any && t.hit.is_some()).count() as u64;
        let blocked = traced.iter().filter(|t| t.any && t.found).count() as u64;
        assert_eq!(
            closest_hits,
            rays.eye_hit + rays.secondary_hit,
            "{name}: hits"
        );
        assert_eq!(blocked, rays.shadow_blocked, "{name}: blocked shadow rays");
        assert_eq!(
            traced.iter().filter(|t| t.any).count() as u64,
            rays.shadow,
            "{name}: shadow rays"
        );
        for t in &traced {
            let closest = bvh
                .closest_hit_with::<ConservativeBoxes, _, _>(&t.ray, &mut NoStats, &mut NoFilter)
                .map(|h| h.prim);
            assert_eq!(closest, t.hit, "{name}: replayed hit differs");
            if t.any {
                let blocked = bvh.any_hit_with::<ConservativeBoxes, _, _>(
                    &t.ray,
                    &mut NoStats,
                    &mut NoFilter,
                );
                assert_eq!(blocked, t.found, "{name}: replayed occlusion differs");
            } else {
                assert_eq!(t.found, t.hit.is_some());
            }
            if let Some(p) = t.hit {
                assert!(
                    bvh.intersect_one(&t.ray, p).is_some(),
                    "{name}: ideal test misses"
                );
            }
        }
        let w = out.work;
        let n = rays.total() as f64;
        assert!(w.prim_tests >= rays.hits(), "{name}: r_ITM < 1");
        assert!(
            w.empty_leaves <= w.leaves && w.leaves <= w.nodes,
            "{name}: N_EETS/N_ETS/N_TS"
        );
        assert!(
            w.nodes as f64 / n >= 1.0 || rays.total() == 0,
            "{name}: N_TS < 1"
        );
        let c = census(&bvh);
        assert_eq!(c.references, bvh.primitives(), "{name}: N_ER");
        let (_, tree) = BuildOptions::default().build_with_tree(&scene.prims().0);
        let b = census(&tree);
        assert_eq!(b.leaves, b.inner + 1, "{name}: binary census");
    }
}
