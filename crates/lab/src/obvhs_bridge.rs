//! quiver's data in obvhs 0.4's terms, for measuring the two side by side (`quiver bench`,
//! the obvhs agreement test, the build benchmark). Only with the `cli` feature, which brings
//! obvhs in.
//!
//! ```
//! use quiver_scenes::Scene;
//! use quiver_lab::{obvhs_bridge};
//! let tris = Scene::load("tetra3").unwrap().triangles();
//! assert_eq!(obvhs_bridge::triangles(&tris).len(), 64);
//! ```

use quiver_rt::Triangle;

/// The same triangles in obvhs's type.
pub fn triangles(tris: &[Triangle]) -> Vec<obvhs::triangle::Triangle> {
    tris.iter()
        .map(|t| obvhs::triangle::Triangle {
            v0: t.v[0],
            v1: t.v[1],
            v2: t.v[2],
        })
        .collect()
}

/// SAH cost of an obvhs tree with quiver's constants (c_T = c_I = 1), so the two compare.
/// obvhs marks leaves by a non-zero primitive count. An empty tree (obvhs builds no nodes
/// for no triangles) costs 0, as quiver's tree over nothing does.
pub fn sah_cost(bvh: &obvhs::bvh2::Bvh2) -> f64 {
    let area = |n: &obvhs::bvh2::node::Bvh2Node| n.aabb.half_area() as f64;
    let Some(root) = bvh.nodes.first() else {
        return 0.0;
    };
    let root = area(root).max(f64::MIN_POSITIVE);
    bvh.nodes
        .iter()
        .map(|n| {
            let count = if n.prim_count == 0 {
                1.0
            } else {
                n.prim_count as f64
            };
            area(n) / root * count
        })
        .sum()
}
