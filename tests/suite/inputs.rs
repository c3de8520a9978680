//! Scene input: NFF and OBJ files are read strictly and fail alike, as `file:line: what was
//! expected`; NaN and infinity are errors unless dropping is asked for, and then counted;
//! degenerate views are rejected; no malformed input panics or loads as something else.

use glam::Vec3A;
use quiver_scenes::rng::Rng;
use quiver_scenes::scene::{
    nff, obj, Camera, CameraError, LoadOptions, NonFinite, Scene, SceneError, Shape, GENERATORS,
};
use std::path::PathBuf;

/// A directory of its own per test, removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new(test: &str) -> TempDir {
        let dir = std::env::temp_dir().join(format!("quiver-inputs-{}-{test}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }

    /// Writes `text` to `name` in the directory and returns the path.
    fn file(&self, name: &str, text: &str) -> String {
        let path = self.0.join(name);
        std::fs::write(&path, text).unwrap();
        path.to_str().unwrap().to_string()
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The error `Scene::load` gives for a file `name` holding `text`, with the file's path.
fn load_err(dir: &TempDir, name: &str, text: &str) -> (String, String) {
    let path = dir.file(name, text);
    let e = Scene::load(&path).map(|_| ()).unwrap_err().to_string();
    (path, e)
}

fn nff_err(text: &str) -> String {
    nff::parse(text, "t.nff").unwrap_err().to_string()
}

fn obj_err(text: &str) -> String {
    obj::parse(text, "t.obj").unwrap_err().to_string()
}

const VIEW: &str = "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 45\nhither 1\nresolution 64 64\n";
const WHITE: &str = "f 1 1 1 1 0 0 0 1\n";

fn lax() -> LoadOptions {
    LoadOptions::default().non_finite(NonFinite::Drop)
}

#[test]
fn obj_nan_vertex_is_an_error() {
    let dir = TempDir::new("obj_nan");
    let (path, e) = load_err(&dir, "x.obj", "v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n");
    assert_eq!(e, format!("{path}:3: vertex x is NaN ('nan')"));
}

#[test]
fn obj_infinite_vertex_is_an_error() {
    let dir = TempDir::new("obj_inf");
    let (path, e) = load_err(&dir, "x.obj", "v 0 0 0\nv 1 0 0\nv 0 1e39 0\nf 1 2 3\n");
    assert_eq!(e, format!("{path}:3: vertex y is infinite ('1e39')"));
}

#[test]
fn obj_two_vertex_face_is_an_error() {
    let dir = TempDir::new("obj_two");
    let (path, e) = load_err(
        &dir,
        "scene.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2\n",
    );
    assert_eq!(
        e,
        format!("{path}:5: face needs at least 3 vertices, got 2")
    );
}

#[test]
fn obj_error_names_the_line() {
    let dir = TempDir::new("obj_line");
    let (path, e) = load_err(&dir, "scene.obj", "# a\nv 0 0 0\nv 1 abc 0\n");
    assert_eq!(
        e,
        format!("{path}:3: expected a number for vertex y, got 'abc'")
    );
    let (path, e) = load_err(&dir, "range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 4\n");
    assert_eq!(
        e,
        format!("{path}:5: vertex index 4 is out of range: the file has 3 vertices")
    );
}

#[test]
fn obj_unreadable_file_error_gives_the_os_reason() {
    let dir = TempDir::new("obj_os");
    let path = dir.0.join("missing.obj");
    let e = Scene::load(path.to_str().unwrap()).unwrap_err().to_string();
    let os = std::fs::read(&path).unwrap_err().to_string();
    assert_eq!(e, format!("{}: cannot read: {os}", path.display()));
}

#[test]
fn obj_of_points_and_lines_without_faces_is_an_error() {
    let dir = TempDir::new("obj_points");
    let (path, e) = load_err(&dir, "points.obj", "v 0 0 0\nv 1 0 0\np 1 2\nl 1 2\n");
    assert_eq!(
        e,
        format!(
            "{path}:3: 'p' has no surface to trace (quiver reads 'f' faces), and the file has no faces"
        )
    );
}

#[test]
fn obj_without_geometry_loads_empty_with_a_finite_light() {
    let dir = TempDir::new("obj_nothing");
    for text in ["", "# nothing\n", "v 0 0 0\nv 1 0 0\n"] {
        let s = Scene::load(&dir.file("empty.obj", text)).unwrap();
        assert!(s.objects.is_empty());
        assert!(s.camera.ray(0.0, 0.0).dir.is_finite());
        assert!(s.lights.iter().all(|l| l.pos.is_finite()), "{:?}", s.lights);
    }
}

#[test]
fn obj_trailing_garbage_is_an_error() {
    let dir = TempDir::new("obj_trailing");
    let (path, e) = load_err(&dir, "t.obj", "v 0 0 0 junk\n");
    assert_eq!(
        e,
        format!("{path}:1: expected a number after the vertex's x y z, got 'junk'")
    );
    let (path, e) = load_err(&dir, "t.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3 x\n");
    assert_eq!(
        e,
        format!(
            "{path}:4: expected a vertex index (a whole number, not 0) in the face corner, got 'x'"
        )
    );
}

#[test]
fn obj_unknown_statement_is_an_error() {
    let dir = TempDir::new("obj_unknown");
    let (path, e) = load_err(&dir, "t.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nF 1 2 3\n");
    assert_eq!(
        e,
        format!("{path}:4: unknown statement 'F' (expected v, vt, vn, f or another OBJ statement)")
    );
}

/// Malformed OBJ lines, each with the exact message for its line.
#[test]
fn obj_malformed_lines_name_line_and_expectation() {
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    let table: &[(&str, &str)] = &[
        ("v 1 2\n", "t.obj:4: expected a number for vertex z, got the end of the line"),
        ("v\n", "t.obj:4: expected a number for vertex x, got the end of the line"),
        (
            "v 1 2 3 4 5\n",
            "t.obj:4: a vertex is x y z, optionally followed by w or by r g b, got 5 numbers",
        ),
        ("v -inf 0 0\n", "t.obj:4: vertex x is infinite ('-inf')"),
        ("f 0 1 2\n", "t.obj:4: vertex index 0 in '0': OBJ indices start at 1"),
        (
            "f -4 1 2\n",
            "t.obj:4: vertex index -4 is out of range: 3 vertices before this line",
        ),
        (
            "f 1 2 99999999999999999999\n",
            "t.obj:4: expected a vertex index (a whole number, not 0) in the face corner, \
             got '99999999999999999999'",
        ),
        ("f 1.5 2 3\n", "t.obj:4: expected a vertex index (a whole number, not 0) in the face corner, got '1.5'"),
        ("f\n", "t.obj:4: face needs at least 3 vertices, got 0"),
        ("f 1/ 2 3\n", "t.obj:4: expected a face corner (v, v/vt, v//vn or v/vt/vn), got '1/'"),
        ("f 1// 2 3\n", "t.obj:4: expected a face corner (v, v/vt, v//vn or v/vt/vn), got '1//'"),
        (
            "f 1/1/1/1 2 3\n",
            "t.obj:4: expected a face corner (v, v/vt, v//vn or v/vt/vn), got '1/1/1/1'",
        ),
        (
            "f 1/1 2/1 3/1\n",
            "t.obj:4: texture coordinate index 1 is out of range: the file has 0 texture coordinates",
        ),
        (
            "vn 0 0 1\nf 1//1 2//2 3//1\n",
            "t.obj:5: normal index 2 is out of range: the file has 1 normal",
        ),
        ("vn 0 0\n", "t.obj:4: a normal has 3 numbers, got 2"),
        ("vt 0 x\n", "t.obj:4: expected a number for texture coordinate, got 'x'"),
        ("f 1 2 3 \\\n4\n", "t.obj:4: expected a vertex index (a whole number, not 0) in the face corner, got '\\'"),
    ];
    for (tail, want) in table {
        assert_eq!(obj_err(&format!("{tri}{tail}")), *want, "{tail:?}");
    }
}

/// What OBJ files may hold: every corner form, negative and forward indices, polygons,
/// comments, CRLF, skipped statements.
#[test]
fn obj_accepts_every_corner_form_and_skips_other_statements() {
    let text = "# header\r\nmtllib m.mtl\r\no thing\r\nv 0 0 0 1\r\nv 1 0 0 0.5 0.5 0.5\r\n\
                vt 0 0\r\nvt 1 0 0\r\nvn 0 0 1\r\ng side\r\nusemtl red\r\ns off\r\n\
                f 1/1/1 2/2/1 3//1 4/1 # a quad with a forward reference\r\n\
                v 1 1 0\r\nv 0 1 0\r\nf -3 -2 -1\r\nl 1 2\r\n";
    let s = obj::parse(text, "ok.obj").unwrap();
    let tris = s.triangles();
    assert_eq!(tris.len(), 3);
    assert_eq!(
        tris[0].v,
        [Vec3A::ZERO, Vec3A::X, Vec3A::new(1.0, 1.0, 0.0)]
    );
    assert_eq!(
        tris[1].v,
        [Vec3A::ZERO, Vec3A::new(1.0, 1.0, 0.0), Vec3A::Y]
    );
    assert_eq!(tris[2].v, [Vec3A::X, Vec3A::new(1.0, 1.0, 0.0), Vec3A::Y]);
    assert!(s.camera.validate().is_ok());
    assert!(s.lights.iter().all(|l| l.pos.is_finite()));
}

#[test]
fn nff_and_obj_errors_have_the_same_form() {
    assert_eq!(
        nff_err(&format!("{WHITE}s 0 abc 0 1\n")),
        "t.nff:2: expected a number for sphere centre y, got 'abc'"
    );
    assert_eq!(
        obj_err("v 0 abc 0\n"),
        "t.obj:1: expected a number for vertex y, got 'abc'"
    );
    assert_eq!(
        nff_err(&format!("{WHITE}p 3\n0 0 0\n1 nan 0\n0 1 0\n")),
        "t.nff:4: vertex 2 y is NaN ('nan')"
    );
    assert_eq!(obj_err("v 1 nan 0\n"), "t.obj:1: vertex y is NaN ('nan')");
    assert_eq!(
        nff_err(&format!("{WHITE}p 2\n0 0 0\n1 0 0\n")),
        "t.nff:2: polygon needs at least 3 vertices, got 2"
    );
    assert_eq!(
        obj_err("v 0 0 0\nv 1 0 0\nf 1 2\n"),
        "t.obj:3: face needs at least 3 vertices, got 2"
    );
    let e = nff::parse("s 0 0 0", "t.nff").unwrap_err();
    assert!(matches!(e, SceneError::Parse { line: 1, .. }), "{e:?}");
    assert_eq!(e.line(), Some(1));
    let e = obj::parse("v 0", "t.obj").unwrap_err();
    assert!(matches!(e, SceneError::Parse { line: 1, .. }), "{e:?}");
}

#[test]
fn nff_camera_up_parallel_to_view_is_an_error() {
    let dir = TempDir::new("nff_up");
    let text = "v\nfrom 0 0 5\nat 0 0 0\nup 0 0 1\nangle 45\nhither 1\nresolution 64 64\n";
    let (path, e) = load_err(&dir, "scene.nff", text);
    assert_eq!(
        e,
        format!(
            "{path}:4: camera 'up' is zero or parallel to the view direction from 'from' to 'at'"
        )
    );
}

/// Every way a view can fail, reported against the line of the field at fault.
#[test]
fn nff_degenerate_views_name_the_field_and_its_line() {
    let ok = ["0 0 5", "0 0 0", "0 1 0", "45", "1", "64 64"];
    let same = "t.nff:3: camera 'at' gives no view direction: it is the same point as 'from' \
                (or so far from it that the difference overflows f32)";
    let along =
        "t.nff:4: camera 'up' is zero or parallel to the view direction from 'from' to 'at'";
    let table: &[(usize, &str, &str)] = &[
        (1, "0 0 5", same),
        (
            2,
            "0 0 10",
            "t.nff:4: camera 'up' is zero or parallel to the view direction from 'from' to 'at'",
        ),
        (2, "0 0 -3e38", along),
        (2, "0 nan 0", "t.nff:4: up y is NaN ('nan')"),
        (2, "0 0 0", along),
        (2, "0 0 -2", along),
        (2, "1e-30 0 1", along),
        (
            3,
            "0",
            "t.nff:5: camera 'angle' 0 must lie strictly between 0 and 180 degrees",
        ),
        (
            3,
            "180",
            "t.nff:5: camera 'angle' 180 must lie strictly between 0 and 180 degrees",
        ),
        (
            3,
            "-10",
            "t.nff:5: camera 'angle' -10 must lie strictly between 0 and 180 degrees",
        ),
        (3, "inf", "t.nff:5: angle is infinite ('inf')"),
        (0, "0 inf 5", "t.nff:2: from y is infinite ('inf')"),
        (4, "-1", "t.nff:6: hither -1 must not be negative"),
        (5, "0 64", "t.nff:7: resolution x must be at least 1"),
        (
            5,
            "64 -1",
            "t.nff:7: expected resolution y (a whole number), got '-1'",
        ),
        (
            5,
            "64",
            "t.nff:7: unexpected end of file, expected resolution y (a whole number)",
        ),
    ];
    for &(field, value, want) in table {
        let mut v = ok;
        v[field] = value;
        let text = format!(
            "v\nfrom {}\nat {}\nup {}\nangle {}\nhither {}\nresolution {}\n",
            v[0], v[1], v[2], v[3], v[4], v[5]
        );
        let got = match nff::parse(&text, "t.nff") {
            Ok(_) => format!("no error for field {field} = {value}"),
            Err(e) => e.to_string(),
        };
        assert_eq!(got, want, "field {field} = {value}");
    }
    // Nearly parallel but well defined is fine.
    assert!(nff::parse(&VIEW.replace("up 0 1 0", "up 0 0.001 1"), "t.nff").is_ok());
    // A view is a direction at any scale: 1e-45 or 3e38 away is as good as 5.
    for from in ["0 0 1e-45", "0 0 3e38"] {
        assert!(nff::parse(
            &VIEW.replace("from 0 0 5", &format!("from {from}")),
            "t.nff"
        )
        .is_ok());
    }
    // But not when the difference itself overflows.
    let overflow = VIEW
        .replace("from 0 0 5", "from 0 0 3e38")
        .replace("at 0 0 0", "at 0 0 -3e38");
    assert_eq!(
        nff::parse(&overflow, "t.nff").unwrap_err().to_string(),
        same
    );
}

#[test]
fn lattice_size_zero_with_its_non_finite_view_is_refused() {
    assert_eq!(
        Scene::load("lattice0").unwrap_err().to_string(),
        "scene 'lattice': size '0' must be a number from 1 to 60"
    );
}

#[test]
fn camera_try_new_rejects_degenerate_views() {
    let (o, z) = (Vec3A::ZERO, Vec3A::Z);
    let table = [
        (Camera::try_new(z, o, Vec3A::Y, 45.0), Ok(())),
        (
            Camera::try_new(z, o, z, 45.0),
            Err(CameraError::UpAlongView),
        ),
        (
            Camera::try_new(z, o, Vec3A::ZERO, 45.0),
            Err(CameraError::UpAlongView),
        ),
        (
            Camera::try_new(z, z, Vec3A::Y, 45.0),
            Err(CameraError::NoViewDirection),
        ),
        (
            Camera::try_new(z, o, Vec3A::Y, 0.0),
            Err(CameraError::Angle(0.0)),
        ),
        (
            Camera::try_new(z, o, Vec3A::Y, 180.0),
            Err(CameraError::Angle(180.0)),
        ),
        (
            Camera::try_new(z, o, Vec3A::Y, f32::NAN),
            Err(CameraError::NonFinite("angle")),
        ),
        (
            Camera::try_new(z * f32::INFINITY, o, Vec3A::Y, 45.0),
            Err(CameraError::NonFinite("from")),
        ),
        (
            Camera::try_new(z, o * f32::NAN, Vec3A::Y, 45.0),
            Err(CameraError::NonFinite("at")),
        ),
        (
            Camera::try_new(z, o, Vec3A::Y * f32::NAN, 45.0),
            Err(CameraError::NonFinite("up")),
        ),
    ];
    for (i, (got, want)) in table.into_iter().enumerate() {
        assert_eq!(got.map(|_| ()), want, "row {i}");
    }
    // What `validate` accepts makes finite eye rays at the corners and the centre.
    let cam = Camera::try_new(z, o, Vec3A::new(0.0, 1e-3, 1.0), 179.0).unwrap();
    for (x, y) in [(-1.0, -1.0), (1.0, 1.0), (0.0, 0.0)] {
        assert!(cam.ray(x, y).dir.is_finite());
    }
}

/// Cameras made by code: every generator's view and the framing view of any bounds.
#[test]
fn generator_and_framing_cameras_are_valid() {
    for g in GENERATORS {
        for size in g.min_size..=(g.min_size + 2).min(g.max_size) {
            let s = Scene::load(&format!("{}{size}", g.name)).unwrap();
            assert_eq!(s.camera.validate(), Ok(()), "{}{size}", g.name);
            assert!(s.hither >= 0.0, "{}{size}", g.name);
        }
    }
    let b = |lo: f32, hi: f32| quiver_rt::geometry::Aabb::new(Vec3A::splat(lo), Vec3A::splat(hi));
    // Every finite extent f32 can frame from outside, however large (2e19 used to overflow
    // the f32 length of the extent and fall back to a fixed view of the origin) or small;
    // beyond that, and for bounds that are not finite, an error instead of a view that shows
    // something else.
    for bounds in [
        quiver_rt::geometry::Aabb::EMPTY,
        b(0.0, 0.0),
        b(1e30, 1e30),
        b(-1e19, 1e19),
        b(-2e19, 2e19),
        b(-3e37, 3e37),
        b(-1e-40, 1e-40),
        b(-1e-45, 0.0),
        b(3e38, 3e38),
    ] {
        let cam = Camera::framing(&bounds).unwrap_or_else(|e| panic!("{bounds:?}: {e}"));
        assert_eq!(cam.validate(), Ok(()), "{bounds:?}");
        let c = (bounds.min + bounds.max) * 0.5;
        // (A point, or bounds a few ulps across, get a view whose direction is as coarse as
        // its f32 ends: only its validity is checked.)
        if !bounds.is_empty()
            && (bounds.max - bounds.min).min_element() > c.abs().max_element() * 1e-4
        {
            // It looks at the centre, and every corner lies within the 45° view.
            let c = (bounds.min + bounds.max) * 0.5;
            let close = |a: f32, b: f32| (a - b).abs() <= a.abs().max(b.abs()) * 1e-6;
            assert!(
                (0..3).all(|k| close(cam.at[k], c[k])),
                "{bounds:?}: {cam:?}"
            );
            // In f64: the f32 length of these differences overflows at 1e19.
            let d = |v: Vec3A| glam::DVec3::new(v.x as f64, v.y as f64, v.z as f64);
            let w = (d(cam.at) - d(cam.from)).normalize();
            for corner in [bounds.min, bounds.max] {
                let to = (d(corner) - d(cam.from)).normalize();
                assert!(w.dot(to) >= 22.5f64.to_radians().cos() - 1e-6, "{bounds:?}");
            }
        }
    }
    for bounds in [
        b(-3e38, 3e38),
        b(-1e38, 1e38),
        b(f32::NAN, 1.0),
        b(0.0, f32::INFINITY),
    ] {
        assert_eq!(
            Camera::framing(&bounds),
            Err(quiver_scenes::scene::CameraError::CannotFrame),
            "{bounds:?}"
        );
    }
    // Scaled by a power of two, the same camera scaled (its f64 arithmetic is exact under it).
    let base = Camera::framing(&quiver_rt::geometry::Aabb::new(
        Vec3A::new(-1.0, 0.25, 3.0),
        Vec3A::new(2.0, 5.0, 3.5),
    ))
    .unwrap();
    for k in [-100, -20, 20, 100] {
        let s = 2f32.powi(k);
        let scaled = Camera::framing(&quiver_rt::geometry::Aabb::new(
            Vec3A::new(-1.0, 0.25, 3.0) * s,
            Vec3A::new(2.0, 5.0, 3.5) * s,
        ))
        .unwrap();
        assert_eq!(
            (scaled.from, scaled.at),
            (base.from * s, base.at * s),
            "2^{k}"
        );
    }
}

#[test]
fn nff_polygon_count_larger_than_its_vertices_says_so() {
    assert_eq!(
        nff_err(&format!("{WHITE}p 4\n0 0 0\n1 0 0\n1 1 0\ns 0 0 0 1\n")),
        "t.nff:6: expected a number for vertex 4 x, got 's' (the 'p' on line 2 says 4 vertices)"
    );
    assert_eq!(
        nff_err(&format!("{WHITE}pp 3\n0 0 0 0 0 1\n1 0 0 0 0 1\n1 1 0\n")),
        "t.nff:5: unexpected end of file, expected a number for normal 3 x \
         (the 'pp' on line 2 says 3 vertices)"
    );
}

#[test]
fn nff_polygon_count_smaller_than_its_vertices_says_so() {
    assert_eq!(
        nff_err(&format!("{WHITE}p 3\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n")),
        "t.nff:6: expected an entity (v, b, l, f, c, s, p or pp), got the number '0'; \
         the 'p' on line 2 says 3 vertices, are there more?"
    );
    assert_eq!(
        nff_err(&format!("{WHITE}s 0 0 0 1 2\n")),
        "t.nff:2: expected an entity (v, b, l, f, c, s, p or pp), got the number '2'; \
         too many numbers for the 's' on line 2?"
    );
}

#[test]
fn nff_degenerate_cone_is_an_error() {
    assert_eq!(
        nff_err(&format!("{WHITE}c\n1 2 3 1\n1 2 3 0.5\n")),
        "t.nff:4: cone apex must differ from its base"
    );
    assert_eq!(
        nff_err(&format!("{WHITE}c\n0 0 0 0\n0 0 1 0\n")),
        "t.nff:4: cone radii must not both be zero"
    );
    assert_eq!(
        nff_err(&format!("{WHITE}c\n0 0 0 1\n0 0 1 -1\n")),
        "t.nff:4: cone radii must not be negative"
    );
}

#[test]
fn nff_negative_hither_is_an_error() {
    assert_eq!(
        nff_err(&VIEW.replace("hither 1", "hither -0.5")),
        "t.nff:6: hither -0.5 must not be negative"
    );
}

/// Malformed NFF, each with the exact message for its line.
#[test]
fn nff_malformed_input_names_line_and_expectation() {
    let table: &[(&str, &str)] = &[
        ("s 0 0 0 1\n", "t.nff:1: 's' before any 'f' material"),
        (
            "f 1 1 1 1 1 1 1\ns 0 0 0 1\n",
            "t.nff:2: expected a number for index of refraction, got 's'",
        ),
        (
            "f 1 1 nan 1 1 1 1 1\n",
            "t.nff:1: fill colour z is NaN ('nan')",
        ),
        (
            "b 0 0 inf\n",
            "t.nff:1: background colour z is infinite ('inf')",
        ),
        (
            "l 0 0\n",
            "t.nff:1: unexpected end of file, expected a number for light position z",
        ),
        (
            "l 0 0 1 1 nan 1\n",
            "t.nff:1: light colour y is NaN ('nan')",
        ),
        ("l nan 0 1\n", "t.nff:1: light position x is NaN ('nan')"),
        (
            "f 1 1 1 1 1 1 1 1\n\ns 0 0 0 0\n",
            "t.nff:3: sphere radius 0 must be positive",
        ),
        (
            "f 1 1 1 1 1 1 1 1\ns 0 0 0\n1e40\n",
            "t.nff:3: sphere radius is infinite ('1e40')",
        ),
        (
            "f 1 1 1 1 1 1 1 1\np x\n",
            "t.nff:2: expected vertex count (a whole number), got 'x'",
        ),
        (
            "f 1 1 1 1 1 1 1 1\npp -3\n",
            "t.nff:2: expected vertex count (a whole number), got '-3'",
        ),
        (
            "v\nfrom 0 0 5\n",
            "t.nff:2: unexpected end of file, expected 'at'",
        ),
        (
            "v from 0 0 5 lookat 0 0 0\n",
            "t.nff:1: expected 'at', got 'lookat'",
        ),
        (
            "x\n",
            "t.nff:1: unknown entity 'x' (expected v, b, l, f, c, s, p or pp)",
        ),
        (
            "# only a comment\n7\n",
            "t.nff:2: expected an entity (v, b, l, f, c, s, p or pp), got the number '7'",
        ),
    ];
    for (text, want) in table {
        let got = nff_err(text);
        assert_eq!(got, *want, "{text:?}");
    }
}

#[test]
fn nff_non_finite_primitives_and_lights_can_be_dropped_and_counted() {
    let text = format!(
        "{VIEW}l 0 0 9\nl 0 nan 9\n{WHITE}s 0 0 0 1\ns 0 0 0 inf\nc\n0 0 0 1\n0 nan 1 1\n\
         p 3\n0 0 0\n1 0 0\n0 1 0\npp 3\n0 0 0 0 0 1\n1 0 0 0 0 nan\n0 1 0 0 0 1\n"
    );
    let e = nff::parse(&text, "d.nff").unwrap_err().to_string();
    assert_eq!(e, "d.nff:9: light position y is NaN ('nan')");
    let (s, report) = nff::parse_with(&text, "d.nff", &lax()).unwrap();
    assert_eq!(s.lights.len(), 1);
    assert_eq!(s.objects.len(), 2);
    assert!(matches!(s.objects[0].shape, Shape::Sphere(_)));
    assert!(matches!(s.objects[1].shape, Shape::Triangle(_)));
    assert_eq!((report.dropped_primitives, report.dropped_lights), (3, 1));
    assert_eq!(
        report.reasons,
        [
            "d.nff:9: light dropped: light position y is NaN ('nan')",
            "d.nff:12: sphere dropped: sphere radius is infinite ('inf')",
            "d.nff:15: cone dropped: cone apex y is NaN ('nan')",
            "d.nff:22: patch dropped: normal 2 z is NaN ('nan')",
        ]
    );
    assert_eq!(
        report.to_string(),
        "dropped 3 primitives and 1 light with non-finite numbers \
         (d.nff:9: light dropped: light position y is NaN ('nan'); \
         d.nff:12: sphere dropped: sphere radius is infinite ('inf'); \
         d.nff:15: cone dropped: cone apex y is NaN ('nan'); \
         d.nff:22: patch dropped: normal 2 z is NaN ('nan'))"
    );
    // What no primitive owns is an error even when dropping.
    let e = nff::parse_with(&VIEW.replace("from 0 0 5", "from 0 0 nan"), "d.nff", &lax());
    assert_eq!(e.unwrap_err().to_string(), "d.nff:2: from z is NaN ('nan')");
    let e = nff::parse_with("f 1 1 1 inf 1 1 1 1\n", "d.nff", &lax());
    assert_eq!(
        e.unwrap_err().to_string(),
        "d.nff:1: Kd is infinite ('inf')"
    );
    // Syntax errors stay errors.
    let e = nff::parse_with(&format!("{WHITE}s 0 0 nan x\n"), "d.nff", &lax());
    assert_eq!(
        e.unwrap_err().to_string(),
        "d.nff:2: expected a number for sphere radius, got 'x'"
    );
}

#[test]
fn obj_non_finite_faces_can_be_dropped_and_counted() {
    let mut text = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\nv nan 0 0\nv 0 inf 0\n");
    text += "f 1 2 3\nf 1 2 4\nf 5 1 2 3\nf 1 2 3\n";
    for _ in 0..10 {
        text += "f 4 1 2\n";
    }
    let (s, report) = obj::parse_with(&text, "d.obj", &lax()).unwrap();
    assert_eq!(s.objects.len(), 2);
    // The quad `f 5 1 2 3` counts its two triangles.
    assert_eq!((report.dropped_primitives, report.dropped_lights), (13, 0));
    assert_eq!(report.reasons.len(), 8);
    assert_eq!(
        report.reasons[..2],
        [
            "d.obj:7: face dropped: its vertex 4 (line 4) is not finite",
            "d.obj:8: face dropped: its vertex 5 (line 5) is not finite",
        ]
    );
    // Twelve faces dropped, eight reasons kept.
    assert!(report.to_string().ends_with("; 4 more)"), "{report}");
    assert!(s
        .triangles()
        .iter()
        .all(|t| t.v.iter().all(|v| v.is_finite())));
    assert!(s.camera.validate().is_ok() && s.lights[0].pos.is_finite());
    // Unused non-finite vertices drop nothing; all faces dropped leaves an empty scene.
    let (s, report) = obj::parse_with(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv nan 0 0\nf 1 2 3\n",
        "u.obj",
        &lax(),
    )
    .unwrap();
    assert_eq!((s.objects.len(), report.is_empty()), (1, true));
    let (s, report) =
        obj::parse_with("v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "e.obj", &lax()).unwrap();
    assert_eq!((s.objects.len(), report.dropped_primitives), (0, 1));
    assert!(s.camera.validate().is_ok() && s.lights[0].pos.is_finite());
}

#[test]
fn load_with_drops_from_files_and_load_stays_strict() {
    let dir = TempDir::new("load_with");
    let nff_path = dir.file("a.nff", &format!("{WHITE}s 0 0 0 1\ns nan 0 0 1\n"));
    let obj_path = dir.file(
        "a.OBJ",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 -inf\nf 1 2 3\nf 2 3 4\n",
    );
    for (path, line, what) in [
        (&nff_path, 3, "sphere centre x is NaN ('nan')"),
        (&obj_path, 4, "vertex z is infinite ('-inf')"),
    ] {
        let e = Scene::load(path).unwrap_err();
        assert_eq!(e.to_string(), format!("{path}:{line}: {what}"));
        assert!(Scene::load_with(path, &LoadOptions::default()).is_err());
        let (s, report) = Scene::load_with(path, &lax()).unwrap();
        assert_eq!(
            (s.objects.len(), report.dropped_primitives),
            (1, 1),
            "{path}"
        );
    }
}

/// A seeded fuzz over small valid files: tokens replaced by junk, NaN, huge, negative or zero
/// numbers, deleted, duplicated, or the file cut short. Nothing may panic; an error names the
/// file and a line of it; what loads is finite with a valid camera, whatever the options.
#[test]
fn mutated_files_fail_cleanly_or_load_sanely() {
    let nff_text = format!(
        "{VIEW}b 0.1 0.2 0.3\nl 1 2 3\nl 4 5 6 0.5 0.5 0.5\n{WHITE}s 0 0 0 1\n\
         c\n0 0 0 1\n0 0 2 0.5\np 4\n-1 -1 0\n1 -1 0\n1 1 0\n-1 1 0\n\
         pp 3\n0 0 1 0 0 1\n1 0 1 0 0 1\n0 1 1 0 0 1\n"
    );
    let obj_text = "# quad and a triangle\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n\
                    g g\nf 1/1/1 2/1/1 3/1/1 4/1/1\nf -4 -3 -2\n";
    let junk = [
        "x", "nan", "-inf", "1e39", "-1", "0", "3", "2.5", "/", "1//", "p", "f", "#", "v",
    ];
    let mut rng = Rng::new(16);
    let mut loaded = [0usize; 2];
    for round in 0..3000 {
        let (text, name) = if round % 2 == 0 {
            (nff_text.as_str(), "m.nff")
        } else {
            (obj_text, "m.obj")
        };
        let mut lines: Vec<Vec<String>> = text
            .lines()
            .map(|l| l.split_whitespace().map(String::from).collect())
            .collect();
        for _ in 0..1 + rng.next_u64() % 3 {
            let l = (rng.next_u64() as usize) % lines.len();
            let n = lines[l].len();
            match rng.next_u64() % 5 {
                0 if n > 0 => {
                    let t = (rng.next_u64() as usize) % n;
                    lines[l][t] = junk[(rng.next_u64() as usize) % junk.len()].to_string();
                }
                1 if n > 0 => {
                    lines[l].remove((rng.next_u64() as usize) % n);
                }
                2 if n > 0 => {
                    let t = (rng.next_u64() as usize) % n;
                    let dup = lines[l][t].clone();
                    lines[l].insert(t, dup);
                }
                3 => lines.truncate(l + 1),
                _ => lines[l].push(junk[(rng.next_u64() as usize) % junk.len()].to_string()),
            }
        }
        let mutated: String = lines.iter().map(|l| l.join(" ") + "\n").collect();
        let line_count = mutated.lines().count();
        for opts in [LoadOptions::default(), lax()] {
            let r = if name.ends_with("nff") {
                nff::parse_with(&mutated, name, &opts)
            } else {
                obj::parse_with(&mutated, name, &opts)
            };
            match r {
                Err(SceneError::Parse { ref path, line, .. }) => {
                    assert_eq!(path.to_str(), Some(name));
                    assert!((1..=line_count.max(1)).contains(&line), "{mutated}\n{r:?}");
                }
                Err(e) => panic!("{mutated}\n{e:?}"),
                Ok((s, report)) => {
                    loaded[round % 2] += 1;
                    assert_eq!(s.camera.validate(), Ok(()), "{mutated}");
                    assert!(s.hither >= 0.0 && s.hither.is_finite(), "{mutated}");
                    assert!(s
                        .lights
                        .iter()
                        .all(|l| l.pos.is_finite() && l.color.is_finite()));
                    let (prims, _) = s.prims();
                    assert!(
                        prims.iter().all(|p| {
                            use quiver_rt::Primitive;
                            p.bounds().is_finite()
                        }),
                        "{mutated}"
                    );
                    if opts.non_finite == NonFinite::Error {
                        assert!(report.is_empty());
                    }
                }
            }
        }
    }
    // The mutations leave some files valid (a number for a number), so both paths ran.
    assert!(loaded[0] > 50 && loaded[1] > 50, "{loaded:?}");
}
