//! SPD scenes: object counts equal the SPD programs' (measured from the compiled C sources,
//! curve and patch mode), NFF round trips, OBJ loading.

use quiver_scenes::scene::{nff, Scene, Shape};

/// (spheres, cones and cylinders, polygons, polygonal patches)
fn counts(s: &Scene) -> [usize; 4] {
    let mut c = [0; 4];
    for o in &s.objects {
        c[match o.shape {
            Shape::Sphere(_) => 0,
            Shape::Cone(_) => 1,
            Shape::Triangle(_) | Shape::Polygon(_) => 2,
            Shape::Patch { .. } => 3,
        }] += 1;
    }
    c
}

/// Curve mode: the SPD programs' output at small, default and large sizes.
#[test]
fn curve_mode_counts_equal_the_spd_programs() {
    let table: &[(&str, [usize; 4])] = &[
        ("balls1", [10, 0, 1, 0]),
        ("balls", [7381, 0, 1, 0]),
        ("balls5", [66430, 0, 1, 0]),
        ("gears1", [0, 0, 147, 0]),
        ("gears2", [0, 0, 1169, 0]),
        ("gears", [0, 0, 9345, 0]),
        ("gears5", [0, 0, 18251, 0]),
        ("mount1", [4, 0, 8, 0]),
        ("mount", [4, 0, 8192, 0]),
        ("mount7", [4, 0, 32768, 0]),
        ("rings1", [30, 30, 1, 0]),
        ("rings", [4200, 4200, 1, 0]),
        ("rings8", [6120, 6120, 1, 0]),
        ("teapot1", [0, 0, 1, 56]),
        ("teapot", [0, 0, 36, 2256]),
        ("teapot12", [0, 0, 144, 9120]),
        ("tetra1", [0, 0, 4, 0]),
        ("tetra", [0, 0, 4096, 0]),
        ("tetra7", [0, 0, 16384, 0]),
        ("tree1", [3, 3, 1, 0]),
        ("tree", [4095, 4095, 1, 0]),
        ("tree12", [8191, 8191, 1, 0]),
        ("lattice1", [8, 12, 0, 0]),
        ("lattice", [2197, 6084, 0, 0]),
        ("lattice13", [2744, 7644, 0, 0]),
        ("jacks", [6, 3, 0, 0]),
        ("jacks2", [54, 27, 0, 0]),
        ("jacks4", [3510, 1755, 0, 0]),
        ("sombrero", [0, 0, 1922, 0]),
        ("sombrero2", [0, 0, 7938, 0]),
        ("sombrero4", [0, 0, 130050, 0]),
    ];
    for &(name, want) in table {
        let s = Scene::load(name).unwrap();
        assert_eq!(counts(&s), want, "{name}");
        assert_eq!(s.objects.len(), want.iter().sum::<usize>(), "{name}");
    }
}

/// Patch mode at the programs' resolution 3 and the Readme's 4 (jacks fixes its own
/// resolution, so it is left out here).
#[test]
fn patch_mode_counts_equal_the_spd_programs() {
    let table: &[(&str, u32, [usize; 4])] = &[
        ("balls2", 3, [0, 0, 1, 9828]),
        ("balls2", 4, [0, 0, 1, 17472]),
        ("balls2", 1, [0, 0, 1, 1092]),
        ("balls", 4, [0, 0, 1, 1417152]),
        ("mount2", 3, [0, 0, 32, 432]),
        ("mount2", 4, [0, 0, 32, 768]),
        ("rings2", 3, [0, 0, 1, 19800]),
        ("rings2", 4, [0, 0, 1, 33600]),
        ("rings", 4, [0, 0, 1, 940800]),
        ("tree2", 3, [0, 0, 1, 924]),
        ("tree2", 4, [0, 0, 1, 1568]),
        ("tree", 3, [0, 0, 1, 540540]),
        ("lattice2", 3, [0, 0, 0, 4212]),
        ("lattice2", 1, [0, 0, 0, 756]),
        ("gears2", 4, [0, 0, 1169, 0]),
        ("tetra3", 4, [0, 0, 64, 0]),
    ];
    for &(name, res, want) in table {
        let s = Scene::load(name).unwrap().into_patches(res);
        assert_eq!(counts(&s), want, "{name} at resolution {res}");
    }
}

/// `quiver gen` output read back gives the same scene, for every generator.
#[test]
fn nff_round_trip_for_every_generator() {
    for g in quiver_scenes::scene::GENERATORS {
        let name = format!(
            "{}{}",
            g.name,
            if g.name == "soup" {
                500
            } else {
                g.default_size.min(3)
            }
        );
        for patches in [false, true] {
            let mut s = Scene::load(&name).unwrap();
            if patches {
                s = s.into_patches(2);
            }
            let mut text = Vec::new();
            nff::write(&s, &mut text).unwrap();
            let back = nff::parse(std::str::from_utf8(&text).unwrap(), "x.nff").unwrap();
            assert_eq!(back.objects, s.objects, "{name} patches {patches}");
            assert_eq!(back.materials, s.materials, "{name}");
            assert_eq!(back.lights, s.lights, "{name}");
            assert_eq!(
                (back.camera, back.background, back.hither, back.resolution),
                (s.camera, s.background, s.hither, s.resolution),
                "{name}"
            );
        }
    }
}

#[test]
fn obj_files_load_as_triangles_with_a_framing_camera() {
    let dir = std::env::temp_dir().join(format!("quiver-obj-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("quad.obj");
    std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n").unwrap();
    let s = Scene::load(path.to_str().unwrap()).unwrap();
    assert_eq!(s.triangles().len(), 2);
    let hit = quiver_rt::traverse::reference::closest_hit(&s.triangles(), &s.camera.ray(0.0, 0.0));
    assert!(hit.is_some(), "the framing camera looks at the mesh");
    std::fs::write(&path, "v 0 0 0\nf 1 2 3\n").unwrap();
    let err = Scene::load(path.to_str().unwrap()).unwrap_err().to_string();
    assert!(err.contains("quad.obj"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_names_and_files_are_clear_errors() {
    let e = |s: &str| Scene::load(s).unwrap_err().to_string();
    assert!(e("balls99").contains("size '99' must be a number from 0 to 7"));
    assert!(e("nosuch").contains("balls, gears"));
    assert!(e("/nonexistent/x.nff").contains("/nonexistent/x.nff: cannot read"));
}
