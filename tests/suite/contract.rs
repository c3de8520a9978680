//! The contracts an embedder's own types and trees meet: a primitive type written from
//! `Primitive`'s documentation alone answers like brute force in every layout, instruction
//! set and packet kernel; a tree from outside is checked, never trusted.

use crate::common::packet_answers;
use glam::Vec3A;
use quiver_lab::rays::random_rays;
use quiver_rt::builders::{
    build, prim_bounds, BuildConfig, BuildNode, BuildTree, Builder, NodeKind, TreeError,
};
use quiver_rt::intersect::Watertight;
use quiver_rt::layout::{Bvh2, Bvh2Mapping, Bvh4, Bvh4Mapping, Bvh8, QBvh4};
use quiver_rt::primitive::LeafFormat;
use quiver_rt::traverse::{reference, ConservativeBoxes, NoStats, PacketMode, PacketQuery};
use quiver_rt::{
    Aabb, BuildOptions, Bvh, Hit, Isa, Layout, PrimHit, Primitive, Ray, RayQuery, Triangle,
};

/// The seeded random soup of `n` triangles in the unit cube.
fn soup(n: usize) -> Vec<Triangle> {
    quiver_scenes::Scene::load(&format!("soup{n}"))
        .unwrap()
        .triangles()
}

/// Triangles with many exact ties: a random soup, each triangle also a second time further
/// on in the list, so a ray through one meets its twin at the same `t` and the lower index
/// must win.
fn soup_with_twins(n: usize) -> Vec<Triangle> {
    let soup = soup(n);
    let mut tris: Vec<Triangle> = soup.clone();
    tris.extend(soup.iter().rev());
    tris
}

/// A triangle that carries a material and declares the fast triangle format. Its own
/// `intersect` answers nonsense: the documentation says quiver never calls it for a
/// triangle format, and this type trusts that.
#[derive(Clone)]
struct Painted {
    tri: Triangle,
    _material: u16,
}

impl Primitive for Painted {
    const LEAF_FORMAT: LeafFormat = LeafFormat::FastTriangles;
    fn triangle(&self) -> Option<Triangle> {
        Some(self.tri)
    }
    fn bounds(&self) -> Aabb {
        self.tri.bounds()
    }
    fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
        Some(PrimHit {
            t: ray.t_min,
            u: 0.5,
            v: 0.5,
        })
    }
}

/// The same in the watertight format.
#[derive(Clone)]
struct Sealed(Triangle);

impl Primitive for Sealed {
    const LEAF_FORMAT: LeafFormat = LeafFormat::WatertightTriangles;
    fn triangle(&self) -> Option<Triangle> {
        Some(self.0)
    }
    fn bounds(&self) -> Aabb {
        self.0.bounds()
    }
    fn intersect(&self, _: &Ray) -> Option<PrimHit> {
        None
    }
}

/// An alpha-tested triangle in the plain format, written from the documentation: the nearest
/// hit in the closed interval, nothing kept between calls. A hole where `u < 0.3`.
#[derive(Clone)]
struct Holed(Triangle);

impl Primitive for Holed {
    fn bounds(&self) -> Aabb {
        self.0.bounds()
    }
    fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
        self.0.intersect(ray).filter(|h| h.u >= 0.3)
    }
}

/// Brute force written out here, apart from the library: every primitive's answer over the
/// whole interval, nearest kept, the lower index on equal `t`.
fn brute<P>(prims: &[P], ray: &Ray, test: impl Fn(&P, &Ray) -> Option<PrimHit>) -> Option<Hit> {
    let mut best: Option<Hit> = None;
    for (i, p) in prims.iter().enumerate() {
        if let Some(h) = test(p, ray) {
            if best.is_none_or(|b| h.t < b.t) {
                best = Some(Hit {
                    t: h.t,
                    prim: i as u32,
                    u: h.u,
                    v: h.v,
                });
            }
        }
    }
    best
}

/// Every layout and instruction set, closest and any hit, one ray at a time and in packets,
/// against `want`.
fn check_everywhere<P: Primitive>(prims: &[P], rays: &[Ray], want: &[Option<Hit>], what: &str) {
    let ties = want.iter().zip(rays).filter(|(w, _)| w.is_some()).count();
    assert!(
        ties > rays.len() / 10,
        "{what}: the rays hit too little to test"
    );
    for layout in Layout::ALL {
        for isa in Isa::ALL {
            let bvh = Bvh::build(prims, &BuildOptions::default().layout(layout).isa(isa)).unwrap();
            if bvh.isa() != isa && layout == Layout::Bvh8Dfs {
                continue;
            }
            for mode in [PacketMode::Always, PacketMode::Never] {
                let (hits, occluded) = packet_answers(&bvh, rays, mode);
                for (i, r) in rays.iter().enumerate() {
                    let at = || format!("{what} {layout} {isa} {mode:?} ray {i}");
                    assert_eq!(hits[i], want[i], "{} packet", at());
                    assert_eq!(bvh.closest_hit(r), want[i], "{}", at());
                    assert_eq!(occluded[i], want[i].is_some(), "{} packet any", at());
                    assert_eq!(bvh.any_hit(r), want[i].is_some(), "{} any", at());
                }
            }
        }
    }
}

/// Random rays (some of them), and as many again from random points aimed at a point inside a
/// random triangle: most hit, many through a triangle and its twin at once.
fn rays_through(tris: &[Triangle], n: usize) -> Vec<Ray> {
    let bounds = prim_bounds(tris)
        .iter()
        .fold(Aabb::EMPTY, |a, b| a.union(b));
    let mut rays = random_rays(&bounds, n, 5);
    let from = random_rays(&bounds, n, 6);
    for (k, r) in from.iter().enumerate() {
        let t = &tris[(k * 7919) % tris.len()];
        let (a, b) = (((k * 37) % 11) as f32 / 11.0, ((k * 13) % 7) as f32 / 7.0);
        let (a, b) = if a + b > 1.0 {
            (1.0 - a, 1.0 - b)
        } else {
            (a, b)
        };
        let target = t.v[0] + a * (t.v[1] - t.v[0]) + b * (t.v[2] - t.v[0]);
        rays.push(Ray::new(r.origin, target - r.origin));
    }
    rays
}

#[test]
fn a_triangle_format_type_is_tested_as_its_triangle_everywhere() {
    let tris = soup_with_twins(600);
    let rays = rays_through(&tris, 1500);
    let painted: Vec<Painted> = tris
        .iter()
        .map(|&tri| Painted { tri, _material: 7 })
        .collect();
    let want: Vec<_> = rays
        .iter()
        .map(|r| brute(&tris, r, |t, r| t.intersect(r)))
        .collect();
    check_everywhere(&painted, &rays, &want, "fast wrapper");
    // The library's own reference agrees with the written-out brute force and the type.
    for (r, w) in rays.iter().zip(&want) {
        assert_eq!(reference::closest_hit(&painted, r), *w);
    }
    let sealed: Vec<Sealed> = tris.iter().map(|&t| Sealed(t)).collect();
    let want: Vec<_> = rays
        .iter()
        .map(|r| brute(&tris, r, |t, r| Watertight(*t).intersect(r)))
        .collect();
    check_everywhere(&sealed, &rays, &want, "watertight wrapper");
}

/// Rays from both sides of `tri`'s plane, 10^-3 to 10^3 of a unit away, aimed at points inside
/// it (a third of them within 10^-6 of its first vertex, as the fuzzer's ray was).
fn rays_onto(tri: &Triangle, n: usize) -> Vec<Ray> {
    (0..n)
        .map(|k| {
            let (a, b) = (((k * 37) % 11) as f32 / 11.0, ((k * 13) % 7) as f32 / 7.0);
            let (a, b) = if a + b > 1.0 {
                (1.0 - a, 1.0 - b)
            } else {
                (a, b)
            };
            let (a, b) = if k % 3 == 0 {
                (a * 1e-6, b * 1e-6)
            } else {
                (a, b)
            };
            let target = tri.v[0] + a * (tri.v[1] - tri.v[0]) + b * (tri.v[2] - tri.v[0]);
            let side = if k % 2 == 0 { -1.0 } else { 1.0 };
            let off = Vec3A::new(
                ((k * 31) % 17) as f32 - 8.0,
                ((k * 7) % 13) as f32 - 6.0,
                side * (1 + k % 5) as f32,
            );
            let from = target + 10f32.powi((k % 7) as i32 - 3) * off;
            Ray::new(from, target - from)
        })
        .collect()
}

/// `Ray::t_max` is the largest distance accepted, so a ray cut off exactly at its nearest hit
/// still finds that hit, in every layout, instruction set and packet kernel, wherever the
/// hit's computed distance is within the box test's slack of its box's entry. The first scene
/// is one the fuzzer found: a triangle 1.6e6 long in the plane z = 0, whose computed distance
/// falls an ulp short of where the ray enters the plane of its box, so the box test at `t_max`
/// needs its slack at the root as everywhere else.
#[test]
fn a_ray_cut_off_at_its_hit_still_finds_it() {
    let plane = vec![Triangle::new(
        Vec3A::new(0.0, -0.2033262, 0.0),
        Vec3A::new(-1.5135877, -1129527.6, 0.0),
        Vec3A::new(-1615431.9, 0.0, 0.0),
    )];
    let fuzzed = Ray::segment(
        Vec3A::new(0.0, -0.990969, -0.6104418),
        Vec3A::new(-0.5433462, -0.75431556, 0.69787383),
        0.0,
        0.98620546,
    );
    let onto_plane = rays_onto(&plane[0], 600);
    let twins = soup_with_twins(300);
    let through_twins = rays_through(&twins, 600);
    for (tris, mut rays, what) in [
        (plane, onto_plane, "long plane"),
        (twins, through_twins, "twins"),
    ] {
        rays.push(fuzzed);
        let want: Vec<_> = rays
            .iter()
            .map(|r| brute(&tris, r, |t, r| t.intersect(r)))
            .collect();
        let cut: Vec<Ray> = rays
            .iter()
            .zip(&want)
            .map(|(r, w)| Ray {
                t_max: w.map_or(r.t_max, |h| h.t),
                ..*r
            })
            .collect();
        check_everywhere(&tris, &cut, &want, what);
    }
}

#[test]
fn a_plain_wrapper_written_from_the_docs_answers_like_brute_force() {
    let tris = soup_with_twins(600);
    let holed: Vec<Holed> = tris.iter().map(|&t| Holed(t)).collect();
    let rays = rays_through(&tris, 1500);
    let want: Vec<_> = rays
        .iter()
        .map(|r| brute(&holed, r, Holed::intersect))
        .collect();
    // The holes matter: some rays pass a triangle they would hit without its hole.
    let plain: Vec<_> = rays
        .iter()
        .map(|r| brute(&tris, r, |t, r| t.intersect(r)))
        .collect();
    assert!(want.iter().zip(&plain).filter(|(a, b)| a != b).count() > 10);
    check_everywhere(&holed, &rays, &want, "holed wrapper");
}

/// A chain: every inner node's left child is a leaf of one primitive, its right child the
/// rest, `depth` levels deep, in preorder.
fn chain(depth: usize, prims: &[Triangle]) -> BuildTree {
    assert!(prims.len() > depth);
    let mut nodes = Vec::new();
    for d in 0..depth {
        let left = nodes.len() as u32 + 1;
        nodes.push(BuildNode {
            bounds: Aabb::EMPTY,
            kind: NodeKind::Inner {
                left,
                right: left + 1,
            },
        });
        nodes.push(BuildNode {
            bounds: Aabb::EMPTY,
            kind: NodeKind::Leaf {
                first: d as u32,
                count: 1,
            },
        });
    }
    nodes.push(BuildNode {
        bounds: Aabb::EMPTY,
        kind: NodeKind::Leaf {
            first: depth as u32,
            count: (prims.len() - depth) as u32,
        },
    });
    BuildTree {
        nodes,
        prim_indices: (0..prims.len() as u32).collect(),
        dropped: 0,
    }
}

/// Every way to lay a tree out from outside, each checked.
fn lay_out_everywhere(tree: &BuildTree, tris: &[Triangle]) -> Vec<Result<(), TreeError>> {
    let mut out = Vec::new();
    for layout in Layout::ALL {
        let options = BuildOptions::default().layout(layout);
        out.push(Bvh::from_tree(tree, tris, &options).map(|_| ()));
    }
    out.push(Bvh2::from_tree(tree, tris, Bvh2Mapping::Compact).map(|_| ()));
    out.push(
        Bvh4::<Triangle>::from_tree(tree, tris, Bvh4Mapping::Subtree, Isa::Portable).map(|_| ()),
    );
    out.push(QBvh4::from_tree(tree, tris, Bvh4Mapping::DepthFirst, Isa::Portable).map(|_| ()));
    out.push(Bvh8::from_tree(tree, tris, &BuildConfig::default(), Isa::detect()).map(|_| ()));
    out
}

#[test]
fn trees_from_outside_are_checked_not_trusted() {
    let tris = soup(300);
    let bounds = prim_bounds(&tris);
    let tree = build(&bounds, &BuildConfig::default(), Builder::Binned).unwrap();

    // Fewer or more primitives than the tree was built for.
    for n in [299, 301] {
        let other = soup(n);
        for r in lay_out_everywhere(&tree, &other) {
            assert!(
                matches!(r, Err(TreeError::PrimCount { tree: 300, .. })),
                "{r:?}"
            );
        }
    }
    // The same count but other primitives: the boxes are recomputed, so answers are right.
    let other: Vec<Triangle> = soup(300)
        .iter()
        .rev()
        .map(|t| Triangle::new(t.v[0] * 2.0, t.v[1] + Vec3A::X, t.v[2]))
        .collect();
    for layout in Layout::ALL {
        let bvh = Bvh::from_tree(&tree, &other, &BuildOptions::default().layout(layout)).unwrap();
        for r in random_rays(&bvh.bounds(), 500, 1) {
            assert_eq!(
                bvh.closest_hit(&r),
                reference::closest_hit(&other, &r),
                "{layout}"
            );
        }
    }

    // Deeper than the kernels' stacks: refused; at the limit, every layout answers.
    let long: Vec<Triangle> = (0..200)
        .map(|i| {
            let o = Vec3A::new(i as f32, 0.0, 0.0);
            Triangle::new(o, o + Vec3A::X, o + Vec3A::Y)
        })
        .collect();
    for r in lay_out_everywhere(&chain(100, &long), &long) {
        assert!(
            matches!(r, Err(TreeError::TooDeep { max, .. }) if max == quiver_rt::builders::MAX_DEPTH),
            "{r:?}"
        );
    }
    let deepest = chain(quiver_rt::builders::MAX_DEPTH, &long);
    for layout in Layout::ALL {
        let bvh = Bvh::from_tree(&deepest, &long, &BuildOptions::default().layout(layout)).unwrap();
        for i in [0usize, 40, 80, 150, 199] {
            let r = Ray::new(Vec3A::new(i as f32 + 0.1, 0.1, 1.0), -Vec3A::Z);
            assert_eq!(
                bvh.closest_hit(&r),
                reference::closest_hit(&long, &r),
                "{layout} {i}"
            );
        }
    }

    // A root that points at itself, a shared subtree, a leaf past the index array.
    let mut cyclic = tree.clone();
    cyclic.nodes[0].kind = NodeKind::Inner { left: 0, right: 0 };
    let mut shared = tree.clone();
    if let NodeKind::Inner { left, .. } = shared.nodes[0].kind {
        shared.nodes[0].kind = NodeKind::Inner { left, right: left };
    }
    let mut past = tree.clone();
    let last = past.nodes.len() - 1;
    past.nodes[last].kind = NodeKind::Leaf {
        first: 299,
        count: 5,
    };
    let mut twice = tree.clone();
    twice.prim_indices[1] = twice.prim_indices[0];
    for (what, bad) in [
        ("cyclic", &cyclic),
        ("shared", &shared),
        ("past", &past),
        ("twice", &twice),
    ] {
        for r in lay_out_everywhere(bad, &tris) {
            let e = r.expect_err(what);
            assert!(!e.to_string().is_empty(), "{what}");
        }
    }
    let mut no_nodes = tree.clone();
    no_nodes.nodes.clear();
    assert_eq!(
        Bvh::from_tree(&no_nodes, &tris, &BuildOptions::default()).err(),
        Some(TreeError::NoNodes)
    );
}

#[test]
fn from_tree_keeps_the_callers_options() {
    // A tree with leaves of up to 4, laid out again with the same options, keeps them:
    // the 8-wide collapse may merge leaves only up to the caller's leaf size.
    let tris = soup(2000);
    let four = BuildOptions::default().max_leaf_size(4).isa(Isa::Portable);
    let (built, tree) = Bvh::build_with_tree(&tris, &four).unwrap();
    let again = Bvh::from_tree(&tree, &tris, &four).unwrap();
    assert_eq!(again.footprint(), built.footprint());
    assert_eq!(again.isa(), Isa::Portable);
    let eight = Bvh::from_tree(&tree, &tris, &BuildOptions::default().isa(Isa::Portable)).unwrap();
    assert!(
        eight.footprint().nodes < again.footprint().nodes,
        "larger leaves merge further"
    );
    // And on the caller's pool, the same BVH.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let on_pool = Bvh::from_tree(&tree, &tris, &four.clone().thread_pool(&pool)).unwrap();
    assert_eq!(on_pool.footprint(), built.footprint());
}

#[test]
fn a_filter_answers_as_if_the_rejected_candidates_were_not_there() {
    // Filtering plain triangles by `u >= 0.3` must answer what the holed primitive answers
    // by its own test: the same candidates kept, the same tie rule.
    let tris = soup_with_twins(600);
    let holed: Vec<Holed> = tris.iter().map(|&t| Holed(t)).collect();
    let rays = rays_through(&tris, 1500);
    let want: Vec<_> = rays
        .iter()
        .map(|r| brute(&holed, r, Holed::intersect))
        .collect();
    let keep = |h: &Hit| h.u >= 0.3;
    let mut asked = 0usize;
    for layout in Layout::ALL {
        for isa in Isa::ALL {
            let bvh = Bvh::build(&tris, &BuildOptions::default().layout(layout).isa(isa)).unwrap();
            if bvh.isa() != isa && layout == Layout::Bvh8Dfs {
                continue;
            }
            for mode in [PacketMode::Always, PacketMode::Never] {
                let q = PacketQuery::new(&rays).mode(mode);
                let mut hits = vec![None; rays.len()];
                let mut occluded = vec![false; rays.len()];
                let mut counted = |h: &Hit| {
                    asked += 1;
                    keep(h)
                };
                bvh.closest_hit_packet_with::<ConservativeBoxes, _, _>(
                    q,
                    &mut hits,
                    &mut NoStats,
                    &mut counted,
                );
                bvh.any_hit_packet_with::<ConservativeBoxes, _, _>(
                    q,
                    &mut occluded,
                    &mut NoStats,
                    &mut keep.clone(),
                );
                for (i, r) in rays.iter().enumerate() {
                    let at = format!("{layout} {isa} {mode:?} ray {i}");
                    assert_eq!(hits[i], want[i], "{at} packet");
                    assert_eq!(bvh.closest_hit_filtered(r, keep), want[i], "{at}");
                    assert_eq!(occluded[i], want[i].is_some(), "{at} packet any");
                    assert_eq!(bvh.any_hit_filtered(r, keep), want[i].is_some(), "{at} any");
                }
            }
        }
    }
    assert!(asked > 0, "the filter was consulted");
}
