//! Mesh files: PLY (ASCII, binary little- and big-endian, gzipped) and glTF (JSON with data
//! URIs or a .bin file, GLB) load to exactly the triangles written into them, node transforms
//! applied as computed here independently; groups name the meshes; every fault is an error
//! naming file and line, element or JSON item; hostile sizes fail without allocating.

use glam::Vec3A;
use quiver_scenes::scene::{gltf, ply, Group, LoadOptions, NonFinite, Scene, SceneError};
use std::io::Write;
use std::path::PathBuf;

/// A directory of its own per test, removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new(test: &str) -> TempDir {
        let dir = std::env::temp_dir().join(format!("quiver-meshes-{}-{test}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }

    fn file(&self, name: &str, bytes: &[u8]) -> String {
        let path = self.0.join(name);
        std::fs::write(&path, bytes).unwrap();
        path.to_str().unwrap().to_string()
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn lax() -> LoadOptions {
    LoadOptions::default().non_finite(NonFinite::Drop)
}

/// Every triangle of a loaded scene as coordinate arrays.
fn corners(scene: &Scene) -> Vec<[[f32; 3]; 3]> {
    scene
        .triangles()
        .iter()
        .map(|t| t.v.map(|p| p.to_array()))
        .collect()
}

/// A mesh with a quad, a pentagon and a triangle over seven vertices, some coordinates
/// negative and fractional (exact in f32), so fan triangulation and every byte order show.
const VERTS: [[f32; 3]; 7] = [
    [0.0, 0.0, 0.0],
    [1.5, 0.0, -0.25],
    [1.5, 2.0, 0.0],
    [0.0, 2.0, 0.75],
    [-1.0, 1.0, 3.0],
    [0.5, -2.5, 1.0],
    [4.0, 4.0, -4.0],
];
const FACES: [&[u32]; 3] = [&[0, 1, 2, 3], &[3, 2, 4, 5, 6], &[6, 0, 5]];

/// The triangles the faces make, fanned from each face's first corner: what the file holds,
/// written out here from the lists above.
fn expected() -> Vec<[[f32; 3]; 3]> {
    let v = |i: u32| VERTS[i as usize];
    vec![
        [v(0), v(1), v(2)],
        [v(0), v(2), v(3)],
        [v(3), v(2), v(4)],
        [v(3), v(4), v(5)],
        [v(3), v(5), v(6)],
        [v(6), v(0), v(5)],
    ]
}

/// The PLY header for [`VERTS`] and [`FACES`]: x as float, y as double, z as float, between
/// them properties quiver does not use, and an element after the faces it skips.
fn ply_header(format: &str) -> String {
    format!(
        "ply\nformat {format} 1.0\ncomment written by quiver's tests\nobj_info none\n\
         element vertex 7\nproperty float x\nproperty uchar red\nproperty double y\n\
         property float z\nproperty list uchar short ranks\n\
         element face 3\nproperty int flags\nproperty list uchar uint vertex_indices\n\
         element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n"
    )
}

fn ply_ascii() -> Vec<u8> {
    let mut s = ply_header("ascii");
    for (i, v) in VERTS.iter().enumerate() {
        // Each vertex lists `i % 3` ranks: lists of other elements are read past.
        let ranks: Vec<String> = (0..i % 3).map(|k| (k as i32 - 1).to_string()).collect();
        s += &format!(
            "{} 200 {} {} {} {}\n",
            v[0],
            v[1],
            v[2],
            i % 3,
            ranks.join(" ")
        );
    }
    for f in FACES {
        let list: Vec<String> = f.iter().map(|i| i.to_string()).collect();
        s += &format!("7 {} {}\n", f.len(), list.join(" "));
    }
    s += "0 1\n";
    s.into_bytes()
}

fn ply_binary(big: bool) -> Vec<u8> {
    let mut b = ply_header(if big {
        "binary_big_endian"
    } else {
        "binary_little_endian"
    })
    .into_bytes();
    let order = |bytes: &mut [u8]| {
        if big {
            bytes.reverse();
        }
    };
    let put = |b: &mut Vec<u8>, mut bytes: Vec<u8>| {
        order(&mut bytes);
        b.extend_from_slice(&bytes);
    };
    for (i, v) in VERTS.iter().enumerate() {
        put(&mut b, v[0].to_le_bytes().to_vec());
        b.push(200);
        put(&mut b, (v[1] as f64).to_le_bytes().to_vec());
        put(&mut b, v[2].to_le_bytes().to_vec());
        b.push((i % 3) as u8);
        for k in 0..i % 3 {
            put(&mut b, (k as i16 - 1).to_le_bytes().to_vec());
        }
    }
    for f in FACES {
        put(&mut b, 7i32.to_le_bytes().to_vec());
        b.push(f.len() as u8);
        for &i in f {
            put(&mut b, i.to_le_bytes().to_vec());
        }
    }
    put(&mut b, 0i32.to_le_bytes().to_vec());
    put(&mut b, 1i32.to_le_bytes().to_vec());
    b
}

#[test]
fn ply_ascii_little_and_big_endian_load_to_the_written_triangles() {
    let dir = TempDir::new("ply_formats");
    for (name, bytes) in [
        ("m-ascii.ply", ply_ascii()),
        ("m-le.ply", ply_binary(false)),
        ("m-be.PLY", ply_binary(true)),
    ] {
        let path = dir.file(name, &bytes);
        let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(corners(&scene), expected(), "{name}");
        assert_eq!(
            scene.groups,
            [Group {
                name: name.into(),
                objects: 0..6
            }],
            "{name}"
        );
        assert_eq!(scene.lights.len(), 1);
        scene.camera.validate().unwrap();
    }
}

#[test]
fn ply_gz_is_inflated() {
    let dir = TempDir::new("ply_gz");
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    gz.write_all(&ply_binary(true)).unwrap();
    let path = dir.file("m.ply.gz", &gz.finish().unwrap());
    assert_eq!(corners(&Scene::load(&path).unwrap()), expected());
    let path = dir.file("broken.ply.gz", b"\x1f\x8b\x08\x00garbage");
    let e = Scene::load(&path).unwrap_err().to_string();
    assert!(
        e.starts_with(&format!("{path}: cannot inflate (gzip): ")),
        "{e}"
    );
}

#[test]
fn ply_integer_coordinates_of_every_type() {
    for ty in [
        "char", "uchar", "short", "ushort", "int", "uint", "int8", "uint16",
    ] {
        let text = format!(
            "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty {ty} x\n\
             property {ty} y\nproperty {ty} z\nelement face 1\n\
             property list uint8 uint8 vertex_indices\nend_header\n"
        );
        let size = match ty {
            "char" | "uchar" | "int8" => 1,
            "short" | "ushort" | "uint16" => 2,
            _ => 4,
        };
        let mut b = text.into_bytes();
        for v in [[1u8, 2, 3], [4, 5, 6], [7, 8, 9]] {
            for c in v {
                b.push(c);
                b.extend(std::iter::repeat_n(0, size - 1));
            }
        }
        b.extend_from_slice(&[3, 0, 1, 2]);
        let scene = ply::parse(&b, "ints.ply").unwrap_or_else(|e| panic!("{ty}: {e}"));
        assert_eq!(
            corners(&scene),
            [[[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0]]],
            "{ty}"
        );
    }
    // Negative values of the signed types, big-endian.
    let head = "ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty short x\n\
                property char y\nproperty int z\nelement face 1\n\
                property list uchar int vertex_indices\nend_header\n";
    let mut b = head.as_bytes().to_vec();
    for (x, y, z) in [(-300i16, -5i8, -70000i32), (0, 0, 0), (1, 1, 1)] {
        b.extend_from_slice(&x.to_be_bytes());
        b.extend_from_slice(&y.to_be_bytes());
        b.extend_from_slice(&z.to_be_bytes());
    }
    b.push(3);
    for i in [0i32, 1, 2] {
        b.extend_from_slice(&i.to_be_bytes());
    }
    let scene = ply::parse(&b, "neg.ply").unwrap();
    assert_eq!(corners(&scene)[0][0], [-300.0, -5.0, -70000.0]);
}

/// The error of `ply::parse` on `data`.
fn ply_err(data: &[u8]) -> String {
    ply::parse(data, "t.ply").unwrap_err().to_string()
}

const HEAD3: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                     property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                     end_header\n";

#[test]
fn ply_header_faults_name_their_line() {
    assert_eq!(ply_err(b""), "t.ply:1: the file is empty, expected 'ply'");
    assert_eq!(
        ply_err(b"PLY\n"),
        "t.ply:1: expected 'ply' as the first line, got 'PLY'"
    );
    assert_eq!(
        ply_err(b"ply\nformat binary 1.0\n"),
        "t.ply:2: expected ascii, binary_little_endian or binary_big_endian after 'format', got 'binary'"
    );
    assert_eq!(
        ply_err(b"ply\nformat ascii 2.0\n"),
        "t.ply:2: expected version 1.0 after the format, got '2.0'"
    );
    assert_eq!(
        ply_err(b"ply\nformat ascii 1.0\nproperty float x\n"),
        "t.ply:3: a property before any element"
    );
    assert_eq!(
        ply_err(b"ply\nformat ascii 1.0\nelement vertex many\n"),
        "t.ply:3: expected a whole number for the count of element vertex, got 'many'"
    );
    assert_eq!(
        ply_err(b"ply\nformat ascii 1.0\nelement vertex 1\nproperty real x\n"),
        "t.ply:4: expected a property type (char, uchar, short, ushort, int, uint, float, double or int8 ... float64), got 'real'"
    );
    assert_eq!(
        ply_err(b"ply\nformat ascii 1.0\nelement face 1\nproperty list float int vertex_indices\n"),
        "t.ply:4: a list's count type must be an integer type, got float"
    );
    assert_eq!(
        ply_err(b"ply\nformat ascii 1.0\nvertices 3\n"),
        "t.ply:3: unknown header line 'vertices' (expected format, element, property, comment, obj_info or end_header)"
    );
    assert_eq!(
        ply_err(b"ply\nformat ascii 1.0\nelement vertex 0\n"),
        "t.ply:4: the header ends without 'end_header'"
    );
    assert_eq!(
        ply_err(b"ply\nelement vertex 0\nend_header\n"),
        "t.ply:3: the header ends without a 'format' line"
    );
    assert_eq!(
        ply_err(
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float z\n\
              element face 0\nproperty list uchar int vertex_indices\nend_header\n"
        ),
        "t.ply:3: element vertex has no property y"
    );
    assert_eq!(
        ply_err(
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
              property float z\nelement face 0\nproperty list uchar float vertex_indices\nend_header\n"
        ),
        "t.ply:7: face property vertex_indices must be a list of an integer type"
    );
    let e = ply_err(
        b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
          property float z\nend_header\n0 0 0\n",
    );
    assert_eq!(
        e,
        "t.ply: has vertices but no face element: quiver traces faces, and a point cloud has none"
    );
}

#[test]
fn ply_ascii_body_faults_name_their_line() {
    let with = |body: &str| ply_err(format!("{HEAD3}{body}").as_bytes());
    assert_eq!(
        with("0 0 0\n1 0\n"),
        "t.ply:11: vertex 1: expected a float for z, got the end of the line"
    );
    assert_eq!(
        with("0 0 0\n1 0 0 9\n"),
        "t.ply:11: vertex 1: expected 3 value(s) on the line, got more: '9'"
    );
    assert_eq!(
        with("0 0 0\n1 zero 0\n"),
        "t.ply:11: vertex 1: expected a number (float) for y, got 'zero'"
    );
    assert_eq!(
        with("0 0 0\n1 0 0\n0 1 0\n300 0 1 2\n"),
        "t.ply:13: face 0: expected a uchar (0 to 255) for the count of vertex_indices, got '300'"
    );
    assert_eq!(
        with("0 0 0\n1 0 0\n0 1 0\n2 0 1\n"),
        "t.ply:13: face 0: a face needs at least 3 vertices, got 2"
    );
    assert_eq!(
        with("0 0 0\n1 0 0\n0 1 0\n3 0 1 -1\n"),
        "t.ply:13: face 0: a vertex index is negative or too large: the file has 3 vertices"
    );
    assert_eq!(
        with("0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n"),
        "t.ply:13: face 0: vertex index 3 is out of range: the file has 3 vertices"
    );
    assert_eq!(
        with("0 0 0\n1 0 0\n"),
        "t.ply:11: the file ends after 2 of 3 vertex lines"
    );
    assert_eq!(
        with("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n"),
        "t.ply:14: text after the last element: '3 0 1 2'"
    );
    assert_eq!(
        with("0 0 0\n1 0 0\n0 inf 0\n3 0 1 2\n"),
        "t.ply:12: vertex 2: y is infinite ('inf')"
    );
    assert_eq!(
        with("0 0 0\n1 0 0\n0 1e39 0\n3 0 1 2\n"),
        "t.ply:12: vertex 2: y is infinite ('1e39')"
    );
}

#[test]
fn ply_binary_body_faults_name_element_property_and_byte() {
    let head = HEAD3.replace("ascii", "binary_little_endian");
    let at = head.len();
    let body = |verts: &[[f32; 3]], faces: &[&[i32]]| {
        let mut b = head.as_bytes().to_vec();
        for v in verts {
            for c in v {
                b.extend_from_slice(&c.to_le_bytes());
            }
        }
        for f in faces {
            b.push(f.len() as u8);
            for i in *f {
                b.extend_from_slice(&i.to_le_bytes());
            }
        }
        b
    };
    let tri = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    // The face starts after three vertices of 12 bytes.
    let face = at + 36;
    assert_eq!(
        ply_err(&body(&tri, &[&[0, 1, 7]])),
        format!(
            "t.ply: face 0 (byte {face}): vertex index 7 is out of range: the file has 3 vertices"
        )
    );
    assert_eq!(
        ply_err(&body(&tri, &[&[0, 1]])),
        format!("t.ply: face 0 (byte {face}): a face needs at least 3 vertices, got 2")
    );
    let mut trailing = body(&tri, &[&[0, 1, 2]]);
    trailing.extend_from_slice(b"xy");
    assert_eq!(
        ply_err(&trailing),
        format!("t.ply: byte {}: 2 bytes after the last element", face + 13)
    );
    let mut short = body(&tri, &[&[0, 1, 2]]);
    short.truncate(face + 1 + 8);
    assert_eq!(
        ply_err(&short),
        format!(
            "t.ply: face 0, property vertex_indices (byte {face}): the list claims 3 items of 4 bytes, and 8 bytes are left in the file"
        )
    );
    let nan = [[0.0, 0.0, 0.0], [1.0, f32::NAN, 0.0], [0.0, 1.0, 0.0]];
    assert_eq!(
        ply_err(&body(&nan, &[&[0, 1, 2]])),
        format!("t.ply: vertex 1 (byte {}): y is NaN in f32 (NaN)", at + 12)
    );
    let (scene, report) = ply::parse_with(&body(&nan, &[&[0, 1, 2]]), "t.ply", &lax()).unwrap();
    assert_eq!((scene.objects.len(), report.dropped_primitives), (0, 1));
    assert_eq!(
        report.reasons,
        [format!(
            "t.ply: face 0 (byte {face}) dropped: its vertex 1 (byte {}) is not finite",
            at + 12
        )]
    );
}

#[test]
fn ply_hostile_counts_fail_before_allocating() {
    // Four billion vertices (48 GB) and a billion faces claimed by files of a few hundred
    // bytes: errors, at once, without reserving room for them.
    let binary = "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\n\
                  property float x\nproperty float y\nproperty float z\nelement face 1\n\
                  property list uchar int vertex_indices\nend_header\n";
    let mut b = binary.as_bytes().to_vec();
    b.extend_from_slice(&[0; 40]);
    assert_eq!(
        ply_err(&b),
        format!(
            "t.ply: element vertex (byte {}): 4000000000 instances of at least 12 bytes each do not fit in the 40 bytes left in the file",
            binary.len()
        )
    );
    let ascii = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                 property float z\nelement face 1000000000\n\
                 property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    assert_eq!(
        ply_err(ascii.as_bytes()),
        "t.ply:7: element face claims 1000000000 instances, and the body has only 26 bytes"
    );
    let too_many = "ply\nformat ascii 1.0\nelement vertex 5000000000\nproperty float x\n\
                    property float y\nproperty float z\nend_header\n";
    assert_eq!(
        ply_err(too_many.as_bytes()),
        "t.ply:3: 5000000000 vertices, more than 4294967295 are not supported"
    );
    // A list count far past the bytes left.
    let mut b = HEAD3
        .replace("ascii", "binary_little_endian")
        .replace("list uchar int", "list uint int")
        .into_bytes();
    b.extend_from_slice(&[0; 36]);
    b.extend_from_slice(&u32::MAX.to_le_bytes());
    let e = ply_err(&b);
    assert!(
        e.contains("the list claims 4294967295 items of 4 bytes, and 0 bytes are left"),
        "{e}"
    );
}

#[test]
fn ply_dropping_non_finite_vertices_counts_the_faces() {
    let text = format!("{HEAD3}0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n")
        .replace("element face 1", "element face 2")
        + "3 0 2 0\n";
    let e = ply::parse(text.as_bytes(), "d.ply")
        .unwrap_err()
        .to_string();
    assert_eq!(e, "d.ply:11: vertex 1: y is NaN ('nan')");
    let (scene, report) = ply::parse_with(text.as_bytes(), "d.ply", &lax()).unwrap();
    // The second face does not use vertex 1, so it stays (a degenerate triangle, kept as
    // written).
    assert_eq!(corners(&scene), [[[0.0; 3], [0.0, 1.0, 0.0], [0.0; 3]]]);
    assert_eq!(report.dropped_primitives, 1);
    assert_eq!(
        report.reasons,
        ["d.ply:13: face 0 dropped: its vertex 1 (line 11) is not finite"]
    );
}

// ---------------------------------------------------------------------------------------
// glTF

/// A little glTF writer for the tests: buffers of bytes, views, accessors.
#[derive(Default)]
struct Gltf {
    bin: Vec<u8>,
    views: Vec<serde_json::Value>,
    accessors: Vec<serde_json::Value>,
}

impl Gltf {
    /// Appends `bytes` as a view of buffer 0 (4-byte aligned) and an accessor over it.
    fn accessor(&mut self, bytes: &[u8], component: u32, ty: &str, count: usize) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.views.push(serde_json::json!({
            "buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()
        }));
        self.bin.extend_from_slice(bytes);
        self.accessors.push(serde_json::json!({
            "bufferView": self.views.len() - 1, "componentType": component, "type": ty,
            "count": count
        }));
        self.accessors.len() - 1
    }

    fn positions(&mut self, p: &[[f32; 3]]) -> usize {
        let bytes: Vec<u8> = p.iter().flatten().flat_map(|c| c.to_le_bytes()).collect();
        self.accessor(&bytes, 5126, "VEC3", p.len())
    }

    /// The document with `rest` (meshes, nodes, scenes) and buffer 0 as `uri` (a data: URI
    /// when `None`, or no URI at all for GLB).
    fn json(&self, rest: serde_json::Value, uri: Option<Option<&str>>) -> serde_json::Value {
        let mut buffer = serde_json::json!({ "byteLength": self.bin.len() });
        match uri {
            None => {
                buffer["uri"] =
                    format!("data:application/octet-stream;base64,{}", base64(&self.bin)).into()
            }
            Some(Some(u)) => buffer["uri"] = u.into(),
            Some(None) => {}
        }
        let mut doc = serde_json::json!({
            "asset": {"version": "2.0"},
            "buffers": [buffer],
            "bufferViews": self.views,
            "accessors": self.accessors,
        });
        for (k, v) in rest.as_object().unwrap() {
            doc[k] = v.clone();
        }
        doc
    }

    /// The GLB container of `doc` with the buffer as its BIN chunk.
    fn glb(&self, doc: &serde_json::Value) -> Vec<u8> {
        let mut json = serde_json::to_vec(doc).unwrap();
        while !json.len().is_multiple_of(4) {
            json.push(b' ');
        }
        let mut bin = self.bin.clone();
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let total = 12 + 8 + json.len() + 8 + bin.len();
        let mut out = Vec::new();
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(json.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&json);
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
        out
    }
}

/// Base64 written out here, apart from the reader's decoder.
fn base64(b: &[u8]) -> String {
    const A: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in b.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// A unit right triangle and a quad (as two indexed triangles) for the node tests.
const TRI: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

/// Rotating 90° about z, then scaling, then translating, written out for this test: the
/// transform `T · R · S` of a glTF node with that translation, rotation and scale.
fn trs(p: [f32; 3], t: [f32; 3], s: [f32; 3]) -> [f32; 3] {
    let scaled = [p[0] * s[0], p[1] * s[1], p[2] * s[2]];
    let rotated = [-scaled[1], scaled[0], scaled[2]];
    [rotated[0] + t[0], rotated[1] + t[1], rotated[2] + t[2]]
}

fn close(a: [[f32; 3]; 3], b: [[f32; 3]; 3]) -> bool {
    a.iter()
        .flatten()
        .zip(b.iter().flatten())
        .all(|(x, y)| (x - y).abs() <= 1e-6 * (1.0 + y.abs()))
}

#[test]
fn gltf_node_transforms_compose_down_the_tree() {
    let mut g = Gltf::default();
    let pos = g.positions(&TRI);
    let doc = g.json(
        serde_json::json!({
            "meshes": [{"name": "tri", "primitives": [{"attributes": {"POSITION": pos}}]}],
            "nodes": [
                // Parent: a matrix translating by (10, 0, 0), column-major.
                {"name": "base", "matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 10,0,0,1], "children": [1, 2]},
                // 90° about z (quaternion z = w = sin 45°), scale 2, 3, 1, translation 0 0 5.
                {"name": "arm", "mesh": 0, "rotation": [0, 0, std::f64::consts::FRAC_1_SQRT_2, std::f64::consts::FRAC_1_SQRT_2],
                 "scale": [2, 3, 1], "translation": [0, 0, 5]},
                {"mesh": 0}
            ],
            "scenes": [{"nodes": [0]}], "scene": 0
        }),
        None,
    );
    let scene = gltf::parse(&serde_json::to_vec(&doc).unwrap(), "nodes.gltf").unwrap();
    let got = corners(&scene);
    assert_eq!(got.len(), 2);
    let arm = TRI.map(|p| {
        let q = trs(p, [0.0, 0.0, 5.0], [2.0, 3.0, 1.0]);
        [q[0] + 10.0, q[1], q[2]]
    });
    assert!(close(got[0], arm), "{:?} against {arm:?}", got[0]);
    let plain = TRI.map(|p| [p[0] + 10.0, p[1], p[2]]);
    assert_eq!(got[1], plain);
    assert_eq!(
        scene.groups,
        [
            Group {
                name: "arm/tri/0".into(),
                objects: 0..1
            },
            Group {
                name: "nodes[2]/tri/0".into(),
                objects: 1..2
            },
        ]
    );
}

#[test]
fn gltf_indexed_strips_fans_and_interleaved_views() {
    let quad: [[f32; 3]; 4] = [
        [0.0, 0.0, 0.0],
        [2.0, 0.0, 0.0],
        [2.0, 2.0, 0.0],
        [0.0, 2.0, 0.0],
    ];
    let mut g = Gltf::default();
    let pos = g.positions(&quad);
    let i8s = g.accessor(&[0, 1, 2, 0, 2, 3], 5121, "SCALAR", 6);
    let i16s: Vec<u8> = [2u16, 3, 0].iter().flat_map(|i| i.to_le_bytes()).collect();
    let i16s = g.accessor(&i16s, 5123, "SCALAR", 3);
    let i32s: Vec<u8> = [3u32, 1, 0].iter().flat_map(|i| i.to_le_bytes()).collect();
    let i32s = g.accessor(&i32s, 5125, "SCALAR", 3);
    // Positions interleaved with a 4-byte pad per vertex (stride 16).
    let mut inter = Vec::new();
    for p in &quad {
        for c in p {
            inter.extend_from_slice(&c.to_le_bytes());
        }
        inter.extend_from_slice(&[0xff; 4]);
    }
    let inter_pos = g.accessor(&inter, 5126, "VEC3", 4);
    g.views[inter_pos]["byteStride"] = 16.into();
    let doc = g.json(
        serde_json::json!({
            "meshes": [{"name": "m", "primitives": [
                {"attributes": {"POSITION": pos}, "indices": i8s},
                {"attributes": {"POSITION": pos}, "indices": i16s},
                {"attributes": {"POSITION": pos}, "indices": i32s, "mode": 4},
                {"attributes": {"POSITION": inter_pos}, "mode": 5},
                {"attributes": {"POSITION": pos}, "mode": 6},
                {"attributes": {"POSITION": pos}, "mode": 1}
            ]}],
            "nodes": [{"mesh": 0}]
        }),
        None,
    );
    let scene = gltf::parse(&serde_json::to_vec(&doc).unwrap(), "modes.gltf").unwrap();
    let q = |i: usize| quad[i];
    assert_eq!(
        corners(&scene),
        [
            [q(0), q(1), q(2)],
            [q(0), q(2), q(3)],
            [q(2), q(3), q(0)],
            [q(3), q(1), q(0)],
            // The strip 0 1 2 3: (0 1 2), then (2 1 3) with its winding turned back.
            [q(0), q(1), q(2)],
            [q(2), q(1), q(3)],
            // The fan 0 1 2 3: (0 1 2), (0 2 3).
            [q(0), q(1), q(2)],
            [q(0), q(2), q(3)],
        ]
    );
    let names: Vec<&str> = scene.groups.iter().map(|g| g.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "nodes[0]/m/0",
            "nodes[0]/m/1",
            "nodes[0]/m/2",
            "nodes[0]/m/3",
            "nodes[0]/m/4"
        ]
    );
    assert_eq!(scene.groups[3].objects, 4..6);
}

#[test]
fn glb_and_external_bin_give_the_data_uri_triangles() {
    let dir = TempDir::new("gltf_files");
    let mut g = Gltf::default();
    let pos = g.positions(&TRI);
    let rest = serde_json::json!({
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos}}]}],
        "nodes": [{"mesh": 0, "translation": [0.5, 0.25, 0]}],
        "scenes": [{"nodes": [0]}]
    });
    let want = [TRI.map(|p| [p[0] + 0.5, p[1] + 0.25, p[2]])];
    let embedded = dir.file(
        "e.gltf",
        &serde_json::to_vec(&g.json(rest.clone(), None)).unwrap(),
    );
    assert_eq!(corners(&Scene::load(&embedded).unwrap()), want);
    let glb = dir.file("b.glb", &g.glb(&g.json(rest.clone(), Some(None))));
    assert_eq!(corners(&Scene::load(&glb).unwrap()), want);
    dir.file("my data.bin", &g.bin);
    let external = dir.file(
        "x.gltf",
        &serde_json::to_vec(&g.json(rest.clone(), Some(Some("my%20data.bin")))).unwrap(),
    );
    assert_eq!(corners(&Scene::load(&external).unwrap()), want);
    // A missing or short .bin file is an error naming the buffer and the file.
    let missing = dir.file(
        "m.gltf",
        &serde_json::to_vec(&g.json(rest.clone(), Some(Some("none.bin")))).unwrap(),
    );
    let e = Scene::load(&missing).unwrap_err().to_string();
    let bin = dir.0.join("none.bin");
    assert!(
        e.starts_with(&format!(
            "{missing}: buffers[0].uri: {}: cannot read: ",
            bin.display()
        )),
        "{e}"
    );
    dir.file("short.bin", &g.bin[..10]);
    let short = dir.file(
        "s.gltf",
        &serde_json::to_vec(&g.json(rest, Some(Some("short.bin")))).unwrap(),
    );
    assert_eq!(
        Scene::load(&short).unwrap_err().to_string(),
        format!(
            "{short}: buffers[0].uri: {}: has 10 bytes, and the buffer's byteLength is 36",
            dir.0.join("short.bin").display()
        )
    );
}

/// The error of `gltf::parse` on the document.
fn gltf_err(doc: &serde_json::Value) -> String {
    gltf::parse(&serde_json::to_vec(doc).unwrap(), "t.gltf")
        .unwrap_err()
        .to_string()
}

/// A valid one-triangle document to break one part of at a time.
fn one_triangle() -> (Gltf, serde_json::Value) {
    let mut g = Gltf::default();
    let pos = g.positions(&TRI);
    let idx = g.accessor(&[0, 1, 2, 0], 5121, "SCALAR", 3);
    let doc = g.json(
        serde_json::json!({
            "meshes": [{"primitives": [{"attributes": {"POSITION": pos}, "indices": idx}]}],
            "nodes": [{"mesh": 0}],
            "scenes": [{"nodes": [0]}]
        }),
        None,
    );
    (g, doc)
}

#[test]
fn gltf_faults_name_the_item() {
    let (_, ok) = one_triangle();
    assert_eq!(
        gltf::parse(&serde_json::to_vec(&ok).unwrap(), "t.gltf")
            .unwrap()
            .objects
            .len(),
        1
    );
    let broken = |f: &dyn Fn(&mut serde_json::Value)| {
        let mut d = ok.clone();
        f(&mut d);
        gltf_err(&d)
    };
    assert_eq!(
        broken(&|d| d["accessors"][0]["count"] = 4.into()),
        "t.gltf: meshes[0].primitives[0].attributes.POSITION (accessors[0]): 4 elements of 12 bytes from byte 0 need 48 bytes, and bufferViews[0] has 36"
    );
    assert_eq!(
        broken(&|d| d["bufferViews"][1]["byteOffset"] = 1000.into()),
        "t.gltf: bufferViews[1]: bytes 1000 to 1004 reach past buffers[0], which has 40"
    );
    assert_eq!(
        broken(&|d| d["meshes"][0]["primitives"][0]["indices"] = 7.into()),
        "t.gltf: meshes[0].primitives[0].indices: refers to accessors[7], and the file has 2"
    );
    assert_eq!(
        broken(&|d| d["accessors"][1]["count"] = 4.into()),
        "t.gltf: meshes[0].primitives[0]: 4 vertices in triangle mode, expected a multiple of 3"
    );
    assert_eq!(
        broken(
            &|d| d["meshes"][0]["primitives"][0]["attributes"] = serde_json::json!({"NORMAL": 0})
        ),
        "t.gltf: meshes[0].primitives[0]: has no POSITION attribute: nothing to trace"
    );
    assert_eq!(
        broken(&|d| d["nodes"][0]["children"] = serde_json::json!([0])),
        "t.gltf: nodes[0].children[0]: nodes[0] is reached a second time: glTF nodes must form a forest"
    );
    assert_eq!(
        broken(&|d| d["extensionsRequired"] = serde_json::json!(["KHR_draco_mesh_compression"])),
        "t.gltf: extensionsRequired: the file requires \"KHR_draco_mesh_compression\", which quiver does not read (core glTF 2.0 only)"
    );
    assert_eq!(
        broken(&|d| d["buffers"][0]["uri"] = "data:application/octet-stream;base64,AA*A".into()),
        "t.gltf: buffers[0].uri: invalid base64 character '*' at position 2 of the data"
    );
    assert_eq!(
        broken(&|d| d["buffers"][0]["uri"] = "http://example.invalid/a.bin".into()),
        "t.gltf: buffers[0].uri: 'http://example.invalid/a.bin': a URI scheme other than data:; quiver reads data: URIs and files inside the glTF file's folder (LoadOptions::outside_files, --outside-files, allows others)"
    );
    assert_eq!(
        broken(&|d| d["accessors"][0]["componentType"] = 5123.into()),
        "t.gltf: meshes[0].primitives[0].attributes.POSITION (accessors[0]): positions must be VEC3 of FLOAT (5126), got VEC3 of 5123"
    );
    assert_eq!(
        broken(&|d| d["accessors"][0]["sparse"] = serde_json::json!({})),
        "t.gltf: meshes[0].primitives[0].attributes.POSITION (accessors[0]): sparse accessors are not supported"
    );
    assert_eq!(
        broken(&|d| d["nodes"][0]["rotation"] = serde_json::json!([0, 0, 0, 2])),
        "t.gltf: nodes[0].rotation: not a unit quaternion (length 2)"
    );
    assert_eq!(
        broken(&|d| d["nodes"][0]["translation"] = serde_json::json!([0, 0])),
        "t.gltf: nodes[0].translation: expected an array of 3 numbers"
    );
    assert_eq!(
        broken(&|d| d["meshes"][0]["primitives"][0]["mode"] = 9.into()),
        "t.gltf: meshes[0].primitives[0].mode: 9 is no glTF primitive mode (0 to 6)"
    );
    assert_eq!(
        broken(&|d| d["meshes"][0]["primitives"][0]["mode"] = 1.into()),
        "t.gltf: meshes[0].primitives[0]: points and lines have no surface to trace, and the file has no triangles"
    );
    assert_eq!(
        broken(&|d| d["bufferViews"][0]["byteStride"] = 6.into()),
        "t.gltf: bufferViews[0].byteStride: 6, expected a multiple of 4 from 4 to 252"
    );
    assert_eq!(
        broken(&|d| d["asset"]["version"] = "1.0".into()),
        "t.gltf: asset.version: '1.0', quiver reads glTF 2.0"
    );
    let e = gltf::parse(
        b"{\n  \"asset\": {\"version\": \"2.0\"},\n  \"nodes\": [}\n",
        "t.gltf",
    )
    .unwrap_err();
    assert!(matches!(e, SceneError::Parse { line: 3, .. }), "{e:?}");
    assert!(e.to_string().starts_with("t.gltf:3: invalid JSON: "), "{e}");
}

#[test]
fn gltf_index_past_the_positions_is_an_error() {
    let mut g = Gltf::default();
    let pos = g.positions(&TRI);
    let idx = g.accessor(&[0, 1, 5], 5121, "SCALAR", 3);
    let doc = g.json(
        serde_json::json!({
            "meshes": [{"primitives": [{"attributes": {"POSITION": pos}, "indices": idx}]}],
            "nodes": [{"mesh": 0}]
        }),
        None,
    );
    assert_eq!(
        gltf_err(&doc),
        "t.gltf: meshes[0].primitives[0].indices (accessors[1]): element 2: vertex index 5 is out of range: POSITION has 3 elements"
    );
}

#[test]
fn gltf_hostile_sizes_fail_without_allocating() {
    let (g, ok) = one_triangle();
    let mut d = ok.clone();
    d["accessors"][0]["count"] = 4_000_000_000u64.into();
    assert_eq!(
        gltf_err(&d),
        "t.gltf: meshes[0].primitives[0].attributes.POSITION (accessors[0]): 4000000000 elements of 12 bytes from byte 0 need 48000000000 bytes, and bufferViews[0] has 36"
    );
    let mut d = ok.clone();
    d["accessors"][0]["count"] = u64::MAX.into();
    let e = gltf_err(&d);
    assert!(
        e.ends_with("need more than 2^64 bytes, and bufferViews[0] has 36"),
        "{e}"
    );
    let mut d = ok.clone();
    d["buffers"][0]["byteLength"] = 4_000_000_000u64.into();
    assert_eq!(
        gltf_err(&d),
        "t.gltf: buffers[0]: byteLength is 4000000000, and the data has 40 bytes"
    );
    // A GLB whose header claims more bytes than the file, and a chunk claiming more.
    let mut no_uri = ok.clone();
    no_uri["buffers"][0].as_object_mut().unwrap().remove("uri");
    let mut glb = g.glb(&no_uri);
    let real = glb.len();
    glb[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
    assert_eq!(
        gltf::parse(&glb, "t.glb").unwrap_err().to_string(),
        format!("t.glb: GLB header: the header gives the length 4294967295, and the file has {real} bytes")
    );
    glb[8..12].copy_from_slice(&(real as u32).to_le_bytes());
    glb[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
    assert_eq!(
        gltf::parse(&glb, "t.glb").unwrap_err().to_string(),
        format!(
            "t.glb: GLB chunk 0 (byte 12): the chunk claims 4294967295 bytes, and {} are left",
            real - 20
        )
    );
    glb[4..8].copy_from_slice(&1u32.to_le_bytes());
    assert_eq!(
        gltf::parse(&glb, "t.glb").unwrap_err().to_string(),
        "t.glb: GLB header: version 1, quiver reads GLB version 2"
    );
}

#[test]
fn gltf_non_finite_positions_are_errors_or_dropped() {
    let mut g = Gltf::default();
    let pos = g.positions(&[
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, f32::INFINITY, 0.0],
        [1.0, 1.0, 0.0],
    ]);
    let idx = g.accessor(&[0, 1, 2, 0, 1, 3], 5121, "SCALAR", 6);
    let doc = g.json(
        serde_json::json!({
            "meshes": [{"primitives": [{"attributes": {"POSITION": pos}, "indices": idx}]}],
            "nodes": [{"mesh": 0}]
        }),
        None,
    );
    let bytes = serde_json::to_vec(&doc).unwrap();
    assert_eq!(
        gltf::parse(&bytes, "n.gltf").unwrap_err().to_string(),
        "n.gltf: meshes[0].primitives[0].attributes.POSITION (accessors[0]): element 2: y is infinite"
    );
    let (scene, report) = gltf::parse_with(&bytes, "n.gltf", &lax()).unwrap();
    assert_eq!(
        corners(&scene),
        [[[0.0; 3], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]]]
    );
    assert_eq!(report.dropped_primitives, 1);
    assert_eq!(
        report.reasons,
        ["n.gltf: meshes[0].primitives[0]: triangle 0 dropped: its vertex 2 (meshes[0].primitives[0].attributes.POSITION element 2) is not finite"]
    );
    // A transform that carries a finite position out of f32's range.
    let mut g2 = Gltf::default();
    let pos = g2.positions(&TRI.map(|p| [p[0] * 10.0, p[1] * 10.0, p[2]]));
    let big = g2.json(
        serde_json::json!({
            "meshes": [{"primitives": [{"attributes": {"POSITION": pos}}]}],
            "nodes": [{"mesh": 0, "scale": [1e38, 1e38, 1e38]}]
        }),
        None,
    );
    assert_eq!(
        gltf::parse(&serde_json::to_vec(&big).unwrap(), "big.gltf").unwrap_err().to_string(),
        "big.gltf: meshes[0].primitives[0].attributes.POSITION (accessors[0]): element 1: the node transform carries it out of f32's range"
    );
}

#[test]
fn obj_groups_follow_o_and_g() {
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n\
                f 1 2 3\n\
                o body\ng\nf 1 2 3 4\n\
                g left wing\nf 2 4 3\ng empty\no tail\nf 1 2 3\n";
    let scene = quiver_scenes::scene::obj::parse(text, "g.obj").unwrap();
    let g = |name: &str, objects: std::ops::Range<u32>| Group {
        name: name.into(),
        objects,
    };
    assert_eq!(
        scene.groups,
        [
            g("default", 0..1),
            g("body/default", 1..3),
            g("body/left wing", 3..4),
            g("tail", 4..5)
        ]
    );
}

#[test]
fn into_patches_moves_groups_with_their_objects() {
    // A sphere before two triangles: patch mode turns the sphere into many patches, and the
    // triangles' group must follow them.
    let text = "f 1 1 1 1 0 0 0 1\ns 0 0 0 1\np 3\n0 0 0\n1 0 0\n0 1 0\np 3\n0 0 1\n1 0 1\n0 1 1\n";
    let mut scene = quiver_scenes::scene::nff::parse(text, "g.nff").unwrap();
    assert!(scene.groups.is_empty());
    scene.groups = vec![Group {
        name: "pair".into(),
        objects: 1..3,
    }];
    let tri_shapes = scene.objects[1..3].to_vec();
    let patched = scene.into_patches(quiver_scenes::scene::tessellate::DEFAULT_RESOLUTION);
    let moved = &patched.groups[0].objects;
    assert_eq!(moved.end as usize, patched.objects.len());
    assert_eq!(moved.len(), 2);
    assert_eq!(
        patched.objects[moved.start as usize..moved.end as usize],
        tri_shapes
    );
}

#[test]
fn load_dispatches_on_every_mesh_extension() {
    let dir = TempDir::new("dispatch");
    let (g, doc) = one_triangle();
    let want = [TRI];
    for (name, bytes) in [
        ("a.gltf", serde_json::to_vec(&doc).unwrap()),
        (
            "a.GLB",
            g.glb(&{
                let mut d = doc.clone();
                d["buffers"][0].as_object_mut().unwrap().remove("uri");
                d
            }),
        ),
    ] {
        let path = dir.file(name, &bytes);
        assert_eq!(corners(&Scene::load(&path).unwrap()), want, "{name}");
    }
    let e = Scene::load("mesh.stl").unwrap_err().to_string();
    assert!(e.contains(".ply, .ply.gz, .gltf or .glb"), "{e}");
    let _ = Vec3A::ZERO;
}

// ---------------------------------------------------------------------------------------
// Issue 49: loops bounded by the bytes read, one budget, confined URIs, node graphs.

/// A binary PLY whose element has no properties claims instances of zero bytes: nothing is
/// read for them and nothing loops over them (a count of 10^12 ran for an hour, 2^64 - 1
/// never ended). The load finishes, with the file's (no) triangles.
#[test]
fn ply_property_less_elements_are_not_looped_over() {
    for count in ["1000000000000", "18446744073709551615"] {
        let text =
            format!("ply\nformat binary_little_endian 1.0\nelement nothing {count}\nend_header\n");
        let scene = ply::parse(text.as_bytes(), "z.ply").unwrap();
        assert_eq!(scene.objects.len(), 0);
    }
    // The same before a real mesh: its triangles still load.
    let mut b = ply_binary(false);
    let at = b.windows(11).position(|w| w == b"end_header\n").unwrap();
    b.splice(
        at..at,
        b"element nothing 18446744073709551615\n".iter().copied(),
    );
    assert_eq!(corners(&ply::parse(&b, "z.ply").unwrap()), expected());
}

/// A binary PLY whose lists are all empty (`list uchar double`: each instance one count
/// byte) is valid; the minimum size counted the item type (8 bytes) and refused it. It loads
/// as the same data in ASCII does.
#[test]
fn ply_binary_empty_lists_take_their_count_bytes_only() {
    let head = |format: &str| {
        format!(
            "ply\nformat {format} 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
             property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
             element extra 5\nproperty list uchar double values\nend_header\n"
        )
    };
    let mut bin = head("binary_little_endian").into_bytes();
    for p in TRI {
        for c in p {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    bin.push(3);
    for i in 0..3i32 {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    bin.extend_from_slice(&[0; 5]);
    let ascii = head("ascii") + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n0\n0\n0\n0\n0\n";
    let from_ascii = corners(&ply::parse(ascii.as_bytes(), "a.ply").unwrap());
    assert_eq!(from_ascii, [TRI]);
    assert_eq!(corners(&ply::parse(&bin, "b.ply").unwrap()), from_ascii);
}

/// A quad with one NaN corner is dropped whole, and counted as the two primitives (its
/// triangles) it would have been, as `max_primitives` counts it.
#[test]
fn ply_dropped_quad_counts_its_two_triangles() {
    let text = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
                property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                end_header\n0 0 0\n1 0 0\n1 nan 0\n0 1 0\n4 0 1 2 3\n";
    let (scene, report) = ply::parse_with(text.as_bytes(), "q.ply", &lax()).unwrap();
    assert_eq!((scene.objects.len(), report.dropped_primitives), (0, 2));
    assert_eq!(report.reasons.len(), 1);
    // OBJ counts the same way.
    let obj = "v 0 0 0\nv 1 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3 4\n";
    let (_, report) = quiver_scenes::scene::obj::parse_with(obj, "q.obj", &lax()).unwrap();
    assert_eq!(report.dropped_primitives, 2);
}

/// `max_primitives` binds PLY files (it was ignored): a face that would pass it is refused
/// at that face, in ASCII and binary, before its triangles are stored.
#[test]
fn ply_max_primitives_refuses_at_the_face_that_passes_it() {
    // FACES make 2, 3 and 1 triangles: a limit of 4 is passed by the second face.
    let four = LoadOptions::default().max_primitives(4);
    let e = ply::parse_with(&ply_ascii(), "m.ply", &four).unwrap_err();
    assert!(
        matches!(
            e,
            SceneError::OverBudget {
                needs: 5,
                limit: 4,
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().starts_with("m.ply: face 1 (line "), "{e}");
    let e = ply::parse_with(&ply_binary(true), "m.ply", &four).unwrap_err();
    assert!(e.to_string().starts_with("m.ply: face 1 (byte "), "{e}");
    assert!(ply::parse_with(
        &ply_binary(true),
        "m.ply",
        &LoadOptions::default().max_primitives(6)
    )
    .is_ok());
}

/// `max_bytes` is checked from what each reader is about to hold, never from a file's packed
/// size: a small `.ply.gz` that inflates past it is refused while inflating, a PLY whose
/// single face claims more corners than the budget holds is refused at the face, and an OBJ
/// or NFF past it is refused before its lists are made.
#[test]
fn every_reader_refuses_what_passes_max_bytes() {
    let dir = TempDir::new("max_bytes");
    // 16 MiB of zeros after a header: a few KB packed.
    let mut big = b"ply\nformat binary_little_endian 1.0\nelement extra 16777216\nproperty uchar v\nend_header\n".to_vec();
    big.resize(big.len() + (16 << 20), 0);
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    gz.write_all(&big).unwrap();
    let packed = gz.finish().unwrap();
    assert!(packed.len() < 100_000);
    let path = dir.file("bomb.ply.gz", &packed);
    let limit = LoadOptions::default().max_bytes(1 << 20);
    let e = Scene::load_with(&path, &limit).unwrap_err();
    assert!(
        matches!(e, SceneError::OverBudget { limit: 1048576, .. }),
        "{e}"
    );
    assert!(e.to_string().contains("the inflated data (gzip)"), "{e}");
    assert!(Scene::load_with(&path, &LoadOptions::default().max_bytes(64 << 20)).is_ok());
    // One face of a million corners (4 MB of indices as uchar? no: uint count, uchar items).
    let mut one = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uint uchar vertex_indices\nend_header\n".to_vec();
    one.extend(TRI.iter().flatten().flat_map(|c| c.to_le_bytes()));
    one.extend_from_slice(&1_000_000u32.to_le_bytes());
    one.extend((0..1_000_000).map(|i| (i % 3) as u8));
    let e = ply::parse_with(&one, "f.ply", &LoadOptions::default().max_bytes(8 << 20)).unwrap_err();
    assert!(e.to_string().starts_with("f.ply: face 0 (byte "), "{e}");
    assert!(matches!(e, SceneError::OverBudget { .. }));
    let e =
        ply::parse_with(&one, "f.ply", &LoadOptions::default().max_primitives(1000)).unwrap_err();
    assert!(
        matches!(e, SceneError::OverBudget { needs: 999_998, .. }),
        "{e}"
    );
    // OBJ and NFF.
    let obj: String = "v 0 0 0\nv 1 0 0\nv 0 1 0\n".to_string() + &"f 1 2 3\n".repeat(1000);
    let e = quiver_scenes::scene::obj::parse_with(
        &obj,
        "m.obj",
        &LoadOptions::default().max_bytes(obj.len() as u64 * 2),
    )
    .unwrap_err();
    assert!(matches!(e, SceneError::OverBudget { .. }), "{e}");
    let nff = "f 1 1 1 1 0 0 0 1\n".to_string() + &"s 0 0 0 1\n".repeat(1000);
    let e = quiver_scenes::scene::nff::parse_with(
        &nff,
        "m.nff",
        &LoadOptions::default().max_bytes(nff.len() as u64 * 2),
    )
    .unwrap_err();
    assert!(e.to_string().starts_with("m.nff: line "), "{e}");
}

/// A count-0 accessor with a byteOffset past its view panicked slicing the view (the size
/// check asked for 0 bytes); now the offset must lie inside the view whatever the count, for
/// positions and indices alike.
#[test]
fn gltf_count_zero_accessor_past_its_view_is_an_error() {
    let (_, ok) = one_triangle();
    let mut d = ok.clone();
    d["accessors"][0]["count"] = 0.into();
    d["accessors"][0]["byteOffset"] = 100.into();
    assert_eq!(
        gltf_err(&d),
        "t.gltf: meshes[0].primitives[0].attributes.POSITION (accessors[0]): 0 elements of 12 bytes from byte 100 need 100 bytes, and bufferViews[0] has 36"
    );
    let mut d = ok.clone();
    d["accessors"][1]["count"] = 0.into();
    d["accessors"][1]["byteOffset"] = 100.into();
    let e = gltf_err(&d);
    assert!(
        e.starts_with("t.gltf: meshes[0].primitives[0].indices (accessors[1]): 0 elements"),
        "{e}"
    );
    // Count 0 at the end of the view is an empty accessor: no triangles.
    let mut d = ok;
    d["accessors"][1]["count"] = 0.into();
    d["accessors"][1]["byteOffset"] = 4.into();
    let scene = gltf::parse(&serde_json::to_vec(&d).unwrap(), "t.gltf").unwrap();
    assert_eq!(scene.objects.len(), 0);
}

/// Buffer URIs are read only inside the glTF file's folder, after percent-decoding and
/// normalising: `..` out, `%2e%2e`, `%2F`, absolute paths, schemes and a symbolic link
/// leading out are refused naming the URI; `sub/../x.bin` stays inside and loads;
/// `LoadOptions::outside_files` lets them all through.
#[test]
fn gltf_buffers_are_confined_to_the_folder() {
    let root = TempDir::new("confined");
    let inside = root.0.join("in");
    std::fs::create_dir_all(inside.join("sub")).unwrap();
    let mut g = Gltf::default();
    let pos = g.positions(&TRI);
    let rest = serde_json::json!({
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos}}]}],
        "nodes": [{"mesh": 0}]
    });
    std::fs::write(inside.join("x.bin"), &g.bin).unwrap();
    std::fs::write(root.0.join("out.bin"), &g.bin).unwrap();
    std::os::unix::fs::symlink(root.0.join("out.bin"), inside.join("link.bin")).unwrap();
    let outside_abs = root.0.join("out.bin");
    let abs = outside_abs.to_str().unwrap().replace('/', "%2F");
    let load = |uri: &str, opts: &LoadOptions| {
        let doc = serde_json::to_vec(&g.json(rest.clone(), Some(Some(uri)))).unwrap();
        let path = inside.join("t.gltf");
        std::fs::write(&path, doc).unwrap();
        Scene::load_with(path.to_str().unwrap(), opts).map(|(s, _)| corners(&s))
    };
    let strict = LoadOptions::default();
    for uri in ["x.bin", "./x.bin", "sub/../x.bin", "sub%2F..%2Fx.bin"] {
        assert_eq!(load(uri, &strict).unwrap(), [TRI], "{uri}");
    }
    for (uri, why) in [
        ("../out.bin", "leads outside the glTF file's folder"),
        ("%2e%2e/out.bin", "leads outside the glTF file's folder"),
        ("sub/../../out.bin", "leads outside the glTF file's folder"),
        ("..%5Cout.bin", "leads outside the glTF file's folder"),
        (abs.as_str(), "an absolute path"),
        (
            "link.bin",
            "a symbolic link leads outside the glTF file's folder",
        ),
        ("file:///etc/passwd", "a URI scheme other than data:"),
    ] {
        let e = load(uri, &strict).unwrap_err().to_string();
        // The URI as quoted in messages: its first 40 characters.
        let quoted: String = uri.chars().take(40).collect();
        assert!(
            e.contains(&format!("buffers[0].uri: '{quoted}")),
            "{uri}: {e}"
        );
        assert!(e.contains(why), "{uri}: {e}");
        assert!(e.contains("LoadOptions::outside_files"), "{e}");
    }
    let outside = LoadOptions::default().outside_files(true);
    for uri in ["../out.bin", "%2e%2e/out.bin", abs.as_str(), "link.bin"] {
        assert_eq!(load(uri, &outside).unwrap(), [TRI], "{uri}");
    }
}

/// glTF under the budget: a mesh placed by many nodes counts every placement against
/// `max_primitives`, and several buffers naming one `.bin` read and hold it once.
#[test]
fn gltf_placements_and_shared_files_count_once_each() {
    let dir = TempDir::new("placements");
    let mut g = Gltf::default();
    let pos = g.positions(&TRI);
    let nodes: Vec<serde_json::Value> = (0..50)
        .map(|i| serde_json::json!({"mesh": 0, "translation": [i, 0, 0]}))
        .collect();
    let rest = serde_json::json!({
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos}}]}],
        "nodes": nodes
    });
    let doc = g.json(rest, None);
    let bytes = serde_json::to_vec(&doc).unwrap();
    assert_eq!(gltf::parse(&bytes, "p.gltf").unwrap().objects.len(), 50);
    let e =
        gltf::parse_with(&bytes, "p.gltf", &LoadOptions::default().max_primitives(49)).unwrap_err();
    assert!(
        matches!(
            e,
            SceneError::OverBudget {
                needs: 50,
                limit: 49,
                ..
            }
        ),
        "{e}"
    );
    assert!(
        e.to_string()
            .starts_with("p.gltf: meshes[0].primitives[0], placed as nodes[49]/"),
        "{e}"
    );
    // 40 buffers naming one 1 MiB file: within 4 MiB, since it is read once.
    let mut big = g.bin.clone();
    big.resize(1 << 20, 0);
    dir.file("big.bin", &big);
    let mut doc = g.json(
        serde_json::json!({
            "meshes": [{"primitives": [{"attributes": {"POSITION": pos}}]}],
            "nodes": [{"mesh": 0}]
        }),
        Some(Some("big.bin")),
    );
    let buffer = doc["buffers"][0].clone();
    doc["buffers"] = serde_json::Value::Array(vec![buffer; 40]);
    let views: Vec<serde_json::Value> = (0..40)
        .map(|b| serde_json::json!({"buffer": b, "byteLength": 36}))
        .collect();
    doc["bufferViews"] = views.into();
    let accessors: Vec<serde_json::Value> = (0..40).map(|v| serde_json::json!({"bufferView": v, "componentType": 5126, "type": "VEC3", "count": 3})).collect();
    doc["accessors"] = accessors.into();
    let prims: Vec<serde_json::Value> = (0..40)
        .map(|a| serde_json::json!({"attributes": {"POSITION": a}}))
        .collect();
    doc["meshes"][0]["primitives"] = prims.into();
    let path = dir.file("shared.gltf", &serde_json::to_vec(&doc).unwrap());
    let (scene, _) = Scene::load_with(&path, &LoadOptions::default().max_bytes(4 << 20)).unwrap();
    assert_eq!(scene.objects.len(), 40);
}

/// Without a `scene`, nodes in a cycle of children are no root and were dropped without a
/// word; now that is an error naming a node of the cycle, as it is with a scene. A matrix
/// whose bottom row is not (0, 0, 0, 1) is an error too (it was used as affine).
#[test]
fn gltf_cycles_without_a_scene_and_projective_matrices_are_errors() {
    let (_, ok) = one_triangle();
    let mut d = ok.clone();
    d.as_object_mut().unwrap().remove("scenes");
    d["nodes"] = serde_json::json!([{"mesh": 0}, {"mesh": 0, "children": [2]}, {"children": [1]}]);
    assert_eq!(
        gltf_err(&d),
        "t.gltf: nodes[1]: is in a cycle of children (or below one), so no root reaches it: glTF nodes must form a forest"
    );
    let mut d = ok;
    d["nodes"][0]["matrix"] = serde_json::json!([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0.5, 0, 0, 0, 1]);
    assert_eq!(
        gltf_err(&d),
        "t.gltf: nodes[0].matrix: the bottom row is [0.0, 0.0, 0.5, 1.0], not [0, 0, 0, 1]: glTF node matrices are affine"
    );
}

/// A UTF-8 byte order mark at the start of an OBJ, NFF, PLY or glTF file is not part of its
/// first word (it gave "unknown statement 'v'" with an invisible U+FEFF).
#[test]
fn byte_order_marks_are_skipped() {
    const BOM: &str = "\u{feff}";
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    let with = quiver_scenes::scene::obj::parse(&format!("{BOM}{obj}"), "b.obj").unwrap();
    assert_eq!(corners(&with), [TRI]);
    let nff = "f 1 1 1 1 0 0 0 1\np 3\n0 0 0\n1 0 0\n0 1 0\n";
    let with = quiver_scenes::scene::nff::parse(&format!("{BOM}{nff}"), "b.nff").unwrap();
    assert_eq!(corners(&with), [TRI]);
    let mut ply_bytes = BOM.as_bytes().to_vec();
    ply_bytes.extend_from_slice(&ply_ascii());
    assert_eq!(
        corners(&ply::parse(&ply_bytes, "b.ply").unwrap()),
        expected()
    );
    let (_, doc) = one_triangle();
    let mut json = BOM.as_bytes().to_vec();
    json.extend_from_slice(&serde_json::to_vec(&doc).unwrap());
    assert_eq!(corners(&gltf::parse(&json, "b.gltf").unwrap()), [TRI]);
}
