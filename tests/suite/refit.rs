//! Refit for animation against two oracles: a fresh layout of the same build tree over the
//! moved primitives (`Bvh::from_tree`, which answers every query exactly as the refit BVH
//! must: the same primitive, t, u and v, single rays and packets, closest and any hit), and
//! the independent f64 oracle over the moved triangles (its answer on every decidable ray,
//! an admissible one and exactly the brute-force reference's on the rays in its band). Every
//! layout and instruction set; a mesh waved, swept far away, scrambled, taken far from unit
//! size both ways and brought home; worlds with geometries refit and instances moved against
//! the same world built afresh and the flattened scene; every refusal an error that leaves
//! the BVH as it was.

use crate::common::packet_answers;
use glam::{Affine3A, Quat, Vec3, Vec3A};
use quiver_lab::oracle::{Answer, Oracle};
use quiver_lab::rays::random_rays;
use quiver_lab::worlds::{check as check_world, Placements};
use quiver_rt::traverse::{reference, PacketMode};
use quiver_rt::{
    BuildOptions, Bvh, GeometryId, Hit, Instance, InstanceId, Isa, Layout, MeshError, Ray,
    RayQuery, RefitError, Triangle, World, WorldError,
};
use quiver_scenes::rng::Rng;
use quiver_scenes::Scene;
use rayon::prelude::*;
use std::collections::HashMap;

/// An indexed triangle mesh.
#[derive(Clone)]
struct Mesh {
    positions: Vec<[f32; 3]>,
    indices: Vec<[u32; 3]>,
}

impl Mesh {
    /// The Stanford bunny of tests/data, its shared vertices shared again (the OBJ reader
    /// gives triangles).
    fn bunny() -> Mesh {
        let tris = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/bunny.obj"))
            .unwrap()
            .triangles();
        let mut at: HashMap<[u32; 3], u32> = HashMap::new();
        let mut positions = Vec::new();
        let indices = tris
            .iter()
            .map(|t| {
                t.v.map(|v| {
                    let p = v.to_array();
                    *at.entry(p.map(f32::to_bits)).or_insert_with(|| {
                        positions.push(p);
                        positions.len() as u32 - 1
                    })
                })
            })
            .collect();
        Mesh { positions, indices }
    }

    fn tris(&self) -> Vec<Triangle> {
        self.indices
            .iter()
            .map(|i| {
                let [a, b, c] = i.map(|k| Vec3A::from(self.positions[k as usize]));
                Triangle::new(a, b, c)
            })
            .collect()
    }

    /// Every vertex moved by `f(vertex index, position)`.
    fn moved(&self, f: impl Fn(usize, Vec3A) -> Vec3A) -> Mesh {
        Mesh {
            positions: self
                .positions
                .iter()
                .enumerate()
                .map(|(k, &p)| f(k, p.into()).to_array())
                .collect(),
            indices: self.indices.clone(),
        }
    }

    fn centre_and_size(&self) -> (Vec3A, f32) {
        let b = self
            .tris()
            .iter()
            .fold(quiver_rt::Aabb::EMPTY, |b, t| b.union(&t.bounds()));
        (b.center(), b.extent().max_element())
    }
}

/// A vertex's own pseudo-random unit vector.
fn scatter(k: usize) -> Vec3A {
    let mut rng = Rng::new(k as u64 * 7919 + 1);
    rng.unit_vector()
}

/// The poses a bunny is refit through, in order, each from the last: a wave over its surface,
/// a large sweep (turned, stretched, thirty sizes away), its vertices scrambled (the tree no
/// longer fits: slower, still exact), the wave far above and far below unit size (the BVH's
/// scaled frame, both ways: the wave scaled by `2^70` and `2^-70` exactly, the third entry),
/// and home.
fn poses(a: &Mesh) -> Vec<(&'static str, Mesh, f32)> {
    let (c, s) = a.centre_and_size();
    let k = std::f32::consts::TAU * 2.0 / s;
    let wave = move |_: usize, p: Vec3A| {
        p + 0.04 * s * Vec3A::new((k * p.y + 0.7).sin(), (k * p.z).sin(), (k * p.x).sin())
    };
    let turn = Quat::from_axis_angle(Vec3::new(0.3, 1.0, 0.1).normalize(), 1.75);
    let sweep = move |_: usize, p: Vec3A| {
        Vec3A::from(turn * Vec3::from(p - c)) * Vec3A::new(1.0, 2.5, 1.0) + c + 30.0 * s
    };
    let big = 2f32.powi(70);
    vec![
        ("wave", a.moved(wave), 1.0),
        ("sweep", a.moved(sweep), 1.0),
        ("scrambled", a.moved(|k, p| p + 0.6 * s * scatter(k)), 1.0),
        ("huge", a.moved(|k, p| wave(k, p) * big), big),
        ("tiny", a.moved(|k, p| wave(k, p) / big), 1.0 / big),
        ("home", a.clone(), 1.0),
    ]
}

/// Rays through a pose with the oracle's verdicts and, on the rays in its band, the
/// brute-force reference's answer; for a pose that is another scaled by a power of two
/// (`scale`), that pose's rays moved with it and its verdicts, which then hold for the hits
/// with `t` divided by `scale` (the BVH's frame makes a scaled scene answer bit for bit as at
/// unit size; the f32 test of the scaled triangles themselves, which the oracle models,
/// would overflow).
struct Rays {
    rays: Vec<Ray>,
    want: Vec<Answer>,
    reference: Vec<Option<Option<Hit>>>,
    scale: f32,
}

impl Rays {
    /// Random rays through the triangles' box, and rays aimed at triangle centroids.
    fn new(tris: &[Triangle], n: usize, seed: u64) -> Rays {
        let bounds = tris
            .iter()
            .fold(quiver_rt::Aabb::EMPTY, |b, t| b.union(&t.bounds()));
        let mut rays = random_rays(&bounds, n, seed);
        for (k, r) in random_rays(&bounds, n, seed + 1).iter().enumerate() {
            let t = &tris[(k * 7919) % tris.len()];
            if !t.is_finite() {
                continue;
            }
            rays.push(Ray::new(
                r.origin,
                (t.v[0] + t.v[1] + t.v[2]) / 3.0 - r.origin,
            ));
        }
        let want = Oracle::new(tris).closest_hits(&rays);
        let reference = rays
            .par_iter()
            .zip(&want)
            .map(|(r, w)| (!w.is_decidable()).then(|| reference::closest_hit(tris, r)))
            .collect();
        Rays {
            rays,
            want,
            reference,
            scale: 1.0,
        }
    }

    /// The same rays through the pose scaled by `s` (a power of two).
    fn scaled(&self, s: f32) -> Rays {
        Rays {
            rays: self
                .rays
                .iter()
                .map(|r| Ray {
                    origin: r.origin * s,
                    ..*r
                })
                .collect(),
            want: self.want.clone(),
            reference: self.reference.clone(),
            scale: self.scale * s,
        }
    }

    fn decidable_hits(&self) -> usize {
        self.want
            .iter()
            .filter(|w| w.is_decidable() && w.hit.is_some())
            .count()
    }
}

/// `refit` answers every query as `fresh` does, and the oracle's (or, in its band, the
/// reference's) answer.
fn check<Q: RayQuery<Hit = Hit> + Sync>(refit: &Q, fresh: &Q, set: &Rays, what: &str) {
    set.rays
        .par_iter()
        .zip(&set.want)
        .zip(&set.reference)
        .enumerate()
        .for_each(|(i, ((ray, want), reference))| {
            let got = refit.closest_hit(ray);
            assert_eq!(got, fresh.closest_hit(ray), "{what}: ray {i} {ray:?}");
            assert_eq!(
                refit.any_hit(ray),
                fresh.any_hit(ray),
                "{what}: any, ray {i}"
            );
            assert_eq!(refit.any_hit(ray), got.is_some(), "{what}: any, ray {i}");
            let unit = got.map(|h| Hit {
                t: h.t / set.scale,
                ..h
            });
            if let Err(e) = want.check(unit) {
                panic!("{what}: ray {i} {ray:?}: {e}");
            }
            if let Some(r) = reference {
                assert_eq!(
                    unit, *r,
                    "{what}: ray {i} in the oracle's band: not brute force"
                );
            }
        });
    for mode in [PacketMode::Always, PacketMode::Auto] {
        let (hits, occluded) = packet_answers(refit, &set.rays, mode);
        assert!(
            (hits, occluded) == packet_answers(fresh, &set.rays, mode),
            "{what}: {mode:?} packets differ from the fresh layout's"
        );
    }
}

/// Every instruction set `layout` has kernels for here.
fn isas(layout: Layout) -> Vec<Isa> {
    let tri = [Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)];
    Isa::ALL
        .into_iter()
        .filter(|&isa| {
            Bvh::build(&tri, &BuildOptions::default().layout(layout).isa(isa))
                .unwrap()
                .isa()
                == isa
        })
        .collect()
}

#[test]
fn every_layout_refit_through_a_bunnys_poses_answers_as_fresh_layouts_and_the_oracle() {
    let a = Mesh::bunny();
    assert_eq!(a.indices.len(), 3674);
    assert!(
        a.positions.len() < 3 * a.indices.len() / 2,
        "vertices are shared"
    );
    let list = poses(&a);
    let mut poses: Vec<(&str, Mesh, Vec<Triangle>, Rays)> = Vec::new();
    for (k, (name, m, scale)) in list.into_iter().enumerate() {
        let tris = m.tris();
        // A scaled pose takes the rays of the wave it scales.
        let rays = if scale == 1.0 {
            Rays::new(&tris, 1500, 40 + k as u64)
        } else {
            poses[0].3.scaled(scale)
        };
        poses.push((name, m, tris, rays));
    }
    for (name, _, _, rays) in &poses {
        let hits = rays.decidable_hits();
        assert!(hits > rays.rays.len() / 4, "{name}: {hits} decidable hits");
    }
    let tris_a = a.tris();
    for layout in Layout::ALL {
        for isa in isas(layout) {
            let options = BuildOptions::default().layout(layout).isa(isa);
            let (mut bvh, tree) = Bvh::build_with_tree(&tris_a, &options).unwrap();
            let (mut from_mesh, mesh_tree) =
                Bvh::build_mesh_with_tree(&a.positions, &a.indices, &options).unwrap();
            assert_eq!(tree, mesh_tree);
            let (built, footprint) = (bvh.sah_cost(), bvh.footprint());
            for (name, m, tris, rays) in &poses {
                let what = format!("{layout} {isa} {name}");
                bvh.refit(tris).unwrap();
                from_mesh.refit_mesh(&m.positions, &m.indices).unwrap();
                let fresh = Bvh::from_tree(&tree, tris, &options).unwrap();
                check(&bvh, &fresh, rays, &what);
                check(&from_mesh, &fresh, rays, &format!("{what} (mesh)"));
                assert_eq!(bvh.bounds(), fresh.bounds(), "{what}");
                assert_eq!(bvh.footprint(), footprint, "{what}: nothing reallocated");
                assert_eq!(bvh.isa(), isa, "{what}");
                let cost = bvh.sah_cost();
                // The binary layouts whose shape does not follow the boxes are the fresh
                // layout node for node.
                if layout.name().starts_with("bvh2") && layout != Layout::Bvh2SubtreePage {
                    assert_eq!(cost, fresh.sah_cost(), "{what}");
                }
                match *name {
                    "scrambled" => assert!(cost > 2.0 * built, "{what}: {cost} against {built}"),
                    "home" => assert_eq!(cost, built, "{what}: the tree as built"),
                    _ => {}
                }
            }
        }
    }
}

/// [`check`] where the oracle models the scene (`unit`); elsewhere (a layout has no frame,
/// so far from unit size its f32 tests are the scaled scene's, which the oracle does not
/// model: see [`Rays`]) the same closest and any hits as `fresh`.
fn judge<Q: RayQuery<Hit = Hit> + Sync>(refit: &Q, fresh: &Q, set: &Rays, unit: bool, what: &str) {
    if unit {
        return check(refit, fresh, set, what);
    }
    for (i, r) in set.rays.iter().enumerate() {
        assert_eq!(
            refit.closest_hit(r),
            fresh.closest_hit(r),
            "{what}: ray {i}"
        );
        assert_eq!(refit.any_hit(r), fresh.any_hit(r), "{what}: any, ray {i}");
    }
}

/// Each layout type refit on its own (not through `Bvh`): the same answers as a fresh layout
/// of the build tree over the moved triangles and as the oracle, through every pose, and the
/// same SAH cost as the `Bvh` of that layout refit alike.
#[test]
fn every_layout_type_refits_on_its_own_as_a_fresh_layout_and_the_oracle() {
    use quiver_rt::layout::{Bvh2, Bvh2Mapping, Bvh4, Bvh4Mapping, Bvh8, QBvh4};
    let a = Mesh::bunny();
    let tris_a = a.tris();
    let (_, tree) = Bvh::build_with_tree(&tris_a, &BuildOptions::default()).unwrap();
    let isa = Isa::detect();
    let config = quiver_rt::builders::BuildConfig::default();
    let mut b2 = Bvh2::from_tree(&tree, &tris_a, Bvh2Mapping::Subtree).unwrap();
    let mut b4: Bvh4 = Bvh4::from_tree(&tree, &tris_a, Bvh4Mapping::DepthFirst, isa).unwrap();
    let mut q4: QBvh4 = QBvh4::from_tree(&tree, &tris_a, Bvh4Mapping::DepthFirst, isa).unwrap();
    let mut b8: Bvh8 = Bvh8::from_tree(&tree, &tris_a, &config, isa).unwrap();
    let laid = |layout: Layout| {
        let options = BuildOptions::default().layout(layout).isa(isa);
        Bvh::from_tree(&tree, &tris_a, &options).unwrap()
    };
    let mut bvhs = [
        laid(Layout::Bvh2Subtree),
        laid(Layout::Bvh4Dfs),
        laid(Layout::Bvh4Quant),
        laid(Layout::Bvh8Dfs),
    ];
    for (k, (name, m, scale)) in poses(&a).into_iter().enumerate() {
        let tris = m.tris();
        let rays = Rays::new(&tris, 600, 70 + k as u64);
        let unit = scale == 1.0;
        let what = format!("pose {name}");
        b2.refit(&tris).unwrap();
        b4.refit(&tris).unwrap();
        q4.refit(&tris).unwrap();
        b8.refit(&tris).unwrap();
        for bvh in &mut bvhs {
            bvh.refit(&tris).unwrap();
        }
        let fresh2 = Bvh2::from_tree(&tree, &tris, Bvh2Mapping::Subtree).unwrap();
        judge(&b2, &fresh2, &rays, unit, &format!("bvh2 {what}"));
        let fresh4: Bvh4 = Bvh4::from_tree(&tree, &tris, Bvh4Mapping::DepthFirst, isa).unwrap();
        judge(&b4, &fresh4, &rays, unit, &format!("bvh4 {what}"));
        let freshq: QBvh4 = QBvh4::from_tree(&tree, &tris, Bvh4Mapping::DepthFirst, isa).unwrap();
        judge(&q4, &freshq, &rays, unit, &format!("qbvh4 {what}"));
        let fresh8: Bvh8 = Bvh8::from_tree(&tree, &tris, &config, isa).unwrap();
        judge(&b8, &fresh8, &rays, unit, &format!("bvh8 {what}"));
        let costs = [b2.sah_cost(), b4.sah_cost(), q4.sah_cost(), b8.sah_cost()];
        for (bvh, cost) in bvhs.iter().zip(costs) {
            assert_eq!(cost, bvh.sah_cost(), "{what}");
        }
        // The binary layout is the fresh one node for node.
        assert_eq!(b2.sah_cost(), fresh2.sah_cost(), "{what}");
    }
    // Another count is refused and changes nothing.
    let before = b8.sah_cost();
    assert_eq!(
        b8.refit(&tris_a[1..]),
        Err(RefitError::Count {
            expected: tris_a.len(),
            given: tris_a.len() - 1
        })
    );
    assert_eq!(b8.sah_cost(), before);
}

/// The same answers from a refit on one thread and on two.
#[test]
fn a_refit_answers_alike_on_any_pool() {
    let a = Mesh::bunny();
    let b = poses(&a).swap_remove(1).1.tris();
    let rays = random_rays(
        &b.iter()
            .fold(quiver_rt::Aabb::EMPTY, |x, t| x.union(&t.bounds())),
        3000,
        8,
    );
    for layout in Layout::ALL {
        let mut one = Bvh::build(&a.tris(), &BuildOptions::default().layout(layout)).unwrap();
        let mut two = one.clone();
        crate::common::in_pool(1, || one.refit(&b)).unwrap();
        crate::common::in_pool(2, || two.refit(&b)).unwrap();
        for r in &rays {
            assert_eq!(one.closest_hit(r), two.closest_hit(r), "{layout}");
        }
        assert_eq!(one.sah_cost(), two.sah_cost(), "{layout}");
    }
}

#[test]
fn refits_it_cannot_make_are_errors_that_change_nothing() {
    let a = Mesh::bunny();
    let tris = a.tris();
    let n = tris.len();
    let probe = random_rays(
        &quiver_rt::Aabb::new(Vec3A::splat(-0.1), Vec3A::splat(0.1)),
        500,
        2,
    );
    let answers =
        |bvh: &Bvh| -> Vec<Option<Hit>> { probe.iter().map(|r| bvh.closest_hit(r)).collect() };
    for layout in Layout::ALL {
        let mut bvh = Bvh::build(&tris, &BuildOptions::default().layout(layout)).unwrap();
        let before = answers(&bvh);
        let cost = bvh.sah_cost();
        let refused = |bvh: &mut Bvh, got: Result<(), RefitError>, want: RefitError| {
            assert_eq!(got, Err(want.clone()), "{layout}");
            assert_eq!(answers(bvh), before, "{layout}: {want} changed the BVH");
            assert_eq!(bvh.sah_cost(), cost, "{layout}: {want}");
        };
        let count = RefitError::Count {
            expected: n,
            given: n - 1,
        };
        let r = bvh.refit(&tris[..n - 1]);
        refused(&mut bvh, r, count.clone());
        let r = bvh.refit_mesh(&a.positions, &a.indices[1..]);
        refused(&mut bvh, r, count);
        // A vertex moved to NaN or infinity: the lowest triangle that uses it is named.
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let mut moved = tris.clone();
            moved[17].v[1].y = bad;
            moved[700].v[0].x = bad;
            let r = bvh.refit(&moved);
            refused(&mut bvh, r, RefitError::NonFinite { prim: 17 });
            let mut positions = a.positions.clone();
            let v = a.indices[1200][2] as usize;
            positions[v][2] = bad;
            let first = a
                .indices
                .iter()
                .position(|t| t.contains(&(v as u32)))
                .unwrap();
            let r = bvh.refit_mesh(&positions, &a.indices);
            refused(&mut bvh, r, RefitError::NonFinite { prim: first });
        }
        // An index past the vertices.
        let r = bvh.refit_mesh(&a.positions[..10], &a.indices);
        let Err(RefitError::Mesh(MeshError::IndexOutOfRange { vertices: 10, .. })) = r else {
            panic!("{layout}: {r:?}");
        };
        assert_eq!(answers(&bvh), before, "{layout}");
    }

    // A triangle the build dropped (non-finite) must stay so; those it holds, finite.
    let mut dropping = tris.clone();
    dropping[5].v[2].z = f32::NAN;
    let (mut bvh, tree) = Bvh::build_with_tree(&dropping, &BuildOptions::default()).unwrap();
    assert_eq!(tree.dropped, 1);
    let wave = poses(&a).swap_remove(0).1.tris();
    let mut still = wave.clone();
    still[5].v[0].x = f32::INFINITY;
    bvh.refit(&still).unwrap();
    let fresh = Bvh::from_tree(&tree, &still, &BuildOptions::default()).unwrap();
    let set = Rays::new(&still, 800, 5);
    check(&bvh, &fresh, &set, "with a dropped triangle");
    let before = answers(&bvh);
    assert_eq!(bvh.refit(&wave), Err(RefitError::NotInTree { prim: 5 }));
    let mut lost = still.clone();
    lost[9].v[1].z = f32::NAN;
    assert_eq!(bvh.refit(&lost), Err(RefitError::NonFinite { prim: 9 }));
    assert_eq!(answers(&bvh), before);
    assert_eq!(
        bvh.refit(&wave[..3]),
        Err(RefitError::Count {
            expected: n,
            given: 3
        })
    );

    // The messages name the numbers.
    for (e, has) in [
        (
            RefitError::Count {
                expected: 12,
                given: 11,
            },
            ["12", "11"],
        ),
        (RefitError::NonFinite { prim: 33 }, ["33", "non-finite"]),
        (RefitError::NotInTree { prim: 44 }, ["44", "rebuild"]),
    ] {
        let s = e.to_string();
        assert!(has.iter().all(|h| s.contains(h)), "{s}");
    }
}

/// The world tests' scene moved: every geometry's triangles waved (the mesh geometry through
/// its positions), every third instance placed anew, one re-masked.
fn moved_setup(s: &Placements) -> Placements {
    let wave = |t: &Triangle| {
        let w = |p: Vec3A| {
            p + 0.05 * Vec3A::new((5.0 * p.y).sin(), (4.0 * p.z).cos(), (3.0 * p.x).sin())
        };
        Triangle::new(w(t.v[0]), w(t.v[1]), w(t.v[2]))
    };
    let mut rng = Rng::new(77);
    Placements {
        geometries: s
            .geometries
            .iter()
            .map(|g| g.iter().map(wave).collect())
            .collect(),
        instances: s
            .instances
            .iter()
            .enumerate()
            .map(|(i, inst)| match i % 3 {
                0 if i > 0 => {
                    let at = Vec3::from(rng.in_box(Vec3A::splat(-5.0), Vec3A::splat(5.0)));
                    let turn = Quat::from_rotation_y(rng.range(0.0, 6.0));
                    inst.transform(Affine3A::from_scale_rotation_translation(
                        Vec3::new(1.2, 0.7, -0.9),
                        turn,
                        at,
                    ))
                }
                1 if i == 4 => inst.mask(0b10),
                _ => *inst,
            })
            .collect(),
    }
}

/// The edits that take the world of `a` to the world of `b`.
fn edit_to(world: &mut World, a: &Placements, b: &Placements) {
    let mut edit = world.edit();
    for (g, tris) in b.geometries.iter().enumerate() {
        if g == 1 {
            // Placements::world gives the second geometry as a mesh, three vertices a triangle.
            let positions: Vec<[f32; 3]> = tris
                .iter()
                .flat_map(|t| t.v.map(|v| v.to_array()))
                .collect();
            let indices: Vec<[u32; 3]> = (0..tris.len() as u32)
                .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
                .collect();
            edit.refit_mesh(GeometryId(1), &positions, &indices)
                .unwrap();
        } else {
            edit.refit_triangles(GeometryId(g as u32), tris).unwrap();
        }
    }
    for (i, (old, new)) in a.instances.iter().zip(&b.instances).enumerate() {
        if old.transform != new.transform {
            edit.set_transform(InstanceId(i as u32), new.transform)
                .unwrap();
        }
        if old.mask != new.mask {
            edit.set_mask(InstanceId(i as u32), new.mask).unwrap();
        }
    }
    edit.commit();
}

#[test]
fn an_edited_world_answers_as_the_world_built_afresh_and_the_flattened_scene() {
    let a = crate::world::setup(21);
    let b = moved_setup(&a);
    let rays = b.rays(1200, 31);
    let (flat, names) = b.flattened(|_, _| true);
    let answers = Oracle::with_slack(&flat, b.slack()).closest_hits(&rays);
    let decidable_hits = answers
        .iter()
        .filter(|w| w.is_decidable() && w.hit.is_some())
        .count();
    assert!(decidable_hits > rays.len() / 4, "{decidable_hits}");
    let masked: Vec<Ray> = rays
        .iter()
        .enumerate()
        .map(|(i, r)| r.with_mask([0b01, 0b10, u32::MAX][i % 3]))
        .collect();
    for layout in Layout::ALL {
        for isa in isas(layout) {
            let options = BuildOptions::default().layout(layout).isa(isa);
            let mut world = a.world(&options);
            edit_to(&mut world, &a, &b);
            let fresh = b.world(&options);
            assert_eq!(world.bounds(), fresh.bounds(), "{layout} {isa}");
            for (i, r) in rays.iter().enumerate() {
                let got = world.closest_hit(r);
                assert_eq!(got, fresh.closest_hit(r), "{layout} {isa} ray {i}");
                assert_eq!(
                    world.any_hit(r),
                    got.is_some(),
                    "{layout} {isa} any, ray {i}"
                );
                check_world(&answers[i], got, &names)
                    .unwrap_or_else(|e| panic!("{layout} {isa} ray {i}: {e}"));
            }
            for set in [&rays, &masked] {
                for mode in [PacketMode::Always, PacketMode::Never] {
                    let got = packet_answers(&world, set, mode);
                    let want = packet_answers(&fresh, set, mode);
                    assert!(
                        got == want,
                        "{layout} {isa} {mode:?}: packets differ from the fresh world's"
                    );
                }
            }
            // Back to where it started, by another edit.
            edit_to(&mut world, &b, &a);
            let start = a.world(&options);
            for r in &rays {
                assert_eq!(
                    world.closest_hit(r),
                    start.closest_hit(r),
                    "{layout} {isa}: back"
                );
            }
        }
    }
}

#[test]
fn an_instance_moved_out_of_range_and_back_answers_as_fresh_worlds() {
    let tri = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
    let placed = |far: bool| Placements {
        geometries: vec![vec![tri], vec![tri]],
        instances: (0..20)
            .map(|i| {
                let m = if far && i == 3 {
                    // Finite and invertible, but its world box leaves f32's range.
                    Affine3A::from_translation(Vec3::splat(f32::MAX))
                } else {
                    Affine3A::from_translation(Vec3::new(i as f32, 0.0, 0.0))
                };
                Instance::of(GeometryId(i % 2)).transform(m)
            })
            .collect(),
    };
    let (near, far) = (placed(false), placed(true));
    let rays: Vec<Ray> = (0..200)
        .map(|k| Ray::new(Vec3A::new(k as f32 * 0.1 + 0.05, 0.2, 1.0), -Vec3A::Z))
        .collect();
    let options = BuildOptions::default();
    let mut world = near.world(&options);
    for (to, from) in [(&far, &near), (&near, &far), (&far, &near)] {
        edit_to(&mut world, from, to);
        let fresh = to.world(&options);
        for r in &rays {
            assert_eq!(world.closest_hit(r), fresh.closest_hit(r), "{r:?}");
        }
        assert_eq!(world.bounds().is_finite(), fresh.bounds().is_finite());
    }
    let hit = Ray::new(Vec3A::new(3.2, 0.2, 1.0), -Vec3A::Z);
    edit_to(&mut world, &far, &near);
    assert_eq!(
        world.closest_hit(&hit).map(|h| h.instance),
        Some(InstanceId(3))
    );
}

#[test]
fn world_edits_it_cannot_make_are_errors_that_change_nothing() {
    let a = crate::world::setup(22);
    let mut world = a.world(&BuildOptions::default());
    let rays = a.rays(300, 3);
    let before: Vec<_> = rays.iter().map(|r| world.closest_hit(r)).collect();
    let n_tris = a.geometries[0].len();
    {
        let mut edit = world.edit();
        assert_eq!(
            edit.refit_triangles(GeometryId(9), &a.geometries[0]),
            Err(WorldError::NoGeometry {
                geometry: 9,
                geometries: 3
            })
        );
        assert_eq!(
            edit.refit_triangles(GeometryId(0), &a.geometries[0][1..]),
            Err(WorldError::Refit {
                geometry: 0,
                error: RefitError::Count {
                    expected: n_tris,
                    given: n_tris - 1
                }
            })
        );
        assert!(matches!(
            edit.refit_mesh(GeometryId(1), &[[0.0; 3]; 2], &[[0, 1, 2]; 80]),
            Err(WorldError::Refit { geometry: 1, .. })
        ));
        assert_eq!(
            edit.set_transform(InstanceId(40), Affine3A::IDENTITY),
            Err(WorldError::NoInstance {
                instance: 40,
                instances: 40
            })
        );
        assert_eq!(
            edit.set_transform(
                InstanceId(2),
                Affine3A::from_scale(Vec3::new(1.0, 0.0, 1.0))
            ),
            Err(WorldError::Transform {
                instance: 2,
                why: "not invertible"
            })
        );
        assert_eq!(
            edit.set_mask(InstanceId(41), 0),
            Err(WorldError::NoInstance {
                instance: 41,
                instances: 40
            })
        );
    }
    for (r, b) in rays.iter().zip(&before) {
        assert_eq!(world.closest_hit(r), *b);
    }
    // A geometry of the world's own type takes only those.
    let mut builder = quiver_rt::WorldBuilder::<Triangle>::new();
    let g = builder.add_prims(a.geometries[0].clone());
    builder.add_instance(Instance::of(g));
    let mut prims = builder.build(&BuildOptions::default()).unwrap();
    let mut edit = prims.edit();
    let e = edit.refit_triangles(g, &a.geometries[0]).unwrap_err();
    assert_eq!(
        e,
        WorldError::GeometryKind {
            geometry: 0,
            holds: "primitives of the world's type"
        }
    );
    assert!(e.to_string().contains("geometry 0"));
    edit.refit_prims(g, &a.geometries[0]).unwrap();
}
