//! glTF 2.0: `.gltf` (JSON, with buffers in `data:` URIs or in `.bin` files beside it) and
//! `.glb` (the binary container: a JSON chunk and a BIN chunk).
//!
//! quiver reads the triangles of every mesh primitive that a node of the scene places (the
//! `scene` property's scene, else the first, else every root node), in node order, each
//! vertex moved by its node's world transform (`matrix`, or `translation`, `rotation` and
//! `scale`, composed down the node tree in f64): indexed and non-indexed primitives in the
//! triangle, strip and fan modes, every triangle one object. Point and line primitives are
//! skipped (a file of nothing else is an error, as for OBJ), and so are materials, textures,
//! cameras, skins, morph targets and animations. Each placed primitive is one
//! [`Group`](super::Group), named `node/mesh/primitive index` by the node's and the mesh's
//! names (or `nodes[i]` and `meshes[j]` when they have none).
//!
//! Strict, as the other readers: invalid JSON is `file:line: message` ([`SceneError::Parse`]);
//! every other fault names the JSON item, `file: meshes[0].primitives[1].indices
//! (accessors[4]): message` ([`SceneError::Item`]): a missing or mistyped property, an index
//! past its array, a buffer view or accessor reaching past its buffer, a vertex index past the
//! positions, a node reached twice, a required extension quiver does not read. Sizes are
//! checked against the bytes actually present before anything is allocated for them. A NaN or
//! infinite position (also one that a transform carries out of `f32`'s range) is an error,
//! unless [`NonFinite::Drop`] leaves out (and counts) the triangles that use it; a non-finite
//! transform is always an error.
//!
//! ```
//! use quiver_scenes::scene::gltf;
//! // One triangle, non-indexed, its node moved up by 2.
//! let json = r#"{"asset": {"version": "2.0"},
//!   "buffers": [{"byteLength": 36, "uri": "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}],
//!   "bufferViews": [{"buffer": 0, "byteLength": 36}],
//!   "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}],
//!   "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
//!   "nodes": [{"mesh": 0, "translation": [0, 2, 0]}],
//!   "scenes": [{"nodes": [0]}]}"#;
//! let scene = gltf::parse(json.as_bytes(), "up.gltf").unwrap();
//! assert_eq!(scene.triangles()[0].v[2].to_array(), [0.0, 3.0, 0.0]);
//! assert_eq!(scene.groups[0].name, "nodes[0]/meshes[0]/0");
//! let bad = json.replace(r#""count": 3"#, r#""count": 4"#);
//! assert_eq!(
//!     gltf::parse(bad.as_bytes(), "up.gltf").unwrap_err().to_string(),
//!     "up.gltf: meshes[0].primitives[0].attributes.POSITION (accessors[0]): 4 elements \
//!      of 12 bytes from byte 0 need 48 bytes, and bufferViews[0] has 36"
//! );
//! ```

use super::{Budget, Groups, LoadOptions, LoadReport, NonFinite, Scene, SceneError};
use glam::{DMat4, DQuat, DVec3, Vec3A};
use quiver_rt::geometry::Triangle;
use serde_json::Value;
use std::path::Path;
use std::path::{Component, PathBuf};
use std::rc::Rc;

/// Parses a `.gltf` or `.glb` file's bytes strictly (see [`parse_with`]).
pub fn parse(data: &[u8], path: impl AsRef<Path>) -> Result<Scene, SceneError> {
    parse_with(data, path, &LoadOptions::default()).map(|(scene, _)| scene)
}

/// Parses a `.gltf` (JSON) or `.glb` (binary, told apart by its `glTF` magic) file's bytes;
/// `path` names the source in messages, and relative buffer URIs are read from its directory.
///
/// ```
/// use quiver_scenes::scene::gltf;
/// let e = gltf::parse(br#"{"asset": {"version": "1.0"}}"#, "old.gltf").unwrap_err();
/// assert_eq!(e.to_string(), "old.gltf: asset.version: '1.0', quiver reads glTF 2.0");
/// let e = gltf::parse(b"{\"asset\": \n{]", "broken.gltf").unwrap_err();
/// assert!(e.to_string().starts_with("broken.gltf:2: invalid JSON: "), "{e}");
/// ```
pub fn parse_with(
    data: &[u8],
    path: impl AsRef<Path>,
    opts: &LoadOptions,
) -> Result<(Scene, LoadReport), SceneError> {
    let path = path.as_ref();
    let mut budget = Budget::new(path, opts);
    budget.bytes(data.len() as u64, || "the file's bytes".into())?;
    let (json, bin) = if data.starts_with(b"glTF") {
        let (json, bin) = glb_chunks(data, path)?;
        budget.bytes(json_bytes(json), || "the JSON chunk's parsed values".into())?;
        let root: Value = serde_json::from_slice(json).map_err(|e| {
            item(
                path,
                format!("JSON chunk, line {}", e.line()),
                json_message(&e),
            )
        })?;
        (root, bin)
    } else {
        let data = data.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(data);
        budget.bytes(json_bytes(data), || "the JSON's parsed values".into())?;
        let root: Value = serde_json::from_slice(data).map_err(|e| SceneError::Parse {
            path: path.into(),
            line: e.line(),
            message: json_message(&e),
        })?;
        (root, None)
    };
    let mut reader = Reader {
        path,
        root: &json,
        bin,
        buffers: Vec::new(),
        files: Vec::new(),
        budget,
        opts,
        report: LoadReport::default(),
        tris: Vec::new(),
        groups: Groups::default(),
        skipped: None,
    };
    reader.read()?;
    let Reader {
        tris,
        groups,
        report,
        skipped,
        ..
    } = reader;
    if let (true, Some(what)) = (tris.is_empty(), skipped) {
        return Err(item(
            path,
            what,
            "points and lines have no surface to trace, and the file has no triangles".into(),
        ));
    }
    let groups = groups.finish(tris.len());
    Ok((super::mesh_scene(path, tris, groups)?, report))
}

/// An upper bound of the memory serde_json takes for `text` parsed as a [`Value`] tree: the
/// text itself (strings are copied), and for every value or object entry one can start (at
/// most one per `,`, `:`, `[` and `{`, counted without parsing), a value twice over (arrays
/// and maps grow by doubling) and a map entry's key, hash and index.
fn json_bytes(text: &[u8]) -> u64 {
    let starts = text
        .iter()
        .filter(|&&b| matches!(b, b',' | b':' | b'[' | b'{'))
        .count() as u64;
    let per = 2 * std::mem::size_of::<Value>() as u64 + 48;
    text.len() as u64 + (starts + 1) * per
}

fn item(path: &Path, item: String, message: String) -> SceneError {
    SceneError::Item {
        path: path.into(),
        item,
        message,
    }
}

/// serde_json's message without its " at line L column C", which the error gives by itself.
fn json_message(e: &serde_json::Error) -> String {
    let mut m = e.to_string();
    if let Some(i) = m.rfind(" at line ") {
        m.truncate(i);
    }
    format!("invalid JSON: {m} (column {})", e.column())
}

fn u32_at(data: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([data[at], data[at + 1], data[at + 2], data[at + 3]])
}

/// The JSON chunk and the BIN chunk (if any) of a GLB file.
fn glb_chunks<'a>(data: &'a [u8], path: &Path) -> Result<(&'a [u8], Option<&'a [u8]>), SceneError> {
    let head = |m: String| item(path, "GLB header".into(), m);
    if data.len() < 12 {
        return Err(head(format!(
            "the file has {} bytes, a GLB header needs 12",
            data.len()
        )));
    }
    let version = u32_at(data, 4);
    if version != 2 {
        return Err(head(format!(
            "version {version}, quiver reads GLB version 2"
        )));
    }
    let length = u32_at(data, 8) as usize;
    if length > data.len() || length < 12 {
        return Err(head(format!(
            "the header gives the length {length}, and the file has {} bytes",
            data.len()
        )));
    }
    let data = &data[..length];
    let mut chunks = Vec::new();
    let mut at = 12;
    while at < data.len() {
        let chunk = |m: String| item(path, format!("GLB chunk {} (byte {at})", chunks.len()), m);
        if data.len() - at < 8 {
            return Err(chunk(format!(
                "{} bytes left, a chunk header needs 8",
                data.len() - at
            )));
        }
        let (len, ty) = (u32_at(data, at) as usize, u32_at(data, at + 4));
        if len > data.len() - at - 8 {
            return Err(chunk(format!(
                "the chunk claims {len} bytes, and {} are left",
                data.len() - at - 8
            )));
        }
        chunks.push((ty, &data[at + 8..at + 8 + len]));
        at += 8 + len;
    }
    const JSON: u32 = 0x4E4F_534A;
    const BIN: u32 = 0x004E_4942;
    match chunks.first() {
        Some(&(JSON, json)) => {
            // A second chunk is BIN if anything; later chunks of other types are ignored, as
            // the spec asks.
            let bin = chunks.get(1).filter(|c| c.0 == BIN).map(|c| c.1);
            Ok((json, bin))
        }
        _ => Err(item(
            path,
            "GLB chunk 0 (byte 12)".into(),
            "the first chunk must be the JSON chunk (type 0x4E4F534A)".into(),
        )),
    }
}

/// One JSON value with its path for messages (`meshes[0].primitives[1]`).
#[derive(Clone, Copy)]
struct Node<'a> {
    v: &'a Value,
}

struct Reader<'a> {
    path: &'a Path,
    root: &'a Value,
    bin: Option<&'a [u8]>,
    /// Buffers read so far, by index.
    buffers: Vec<Option<Rc<[u8]>>>,
    /// External files read so far, by their resolved path: several buffers naming one file
    /// read (and hold) it once.
    files: Vec<(PathBuf, Rc<[u8]>)>,
    /// What the load holds, against its limits.
    budget: Budget<'a>,
    opts: &'a LoadOptions,
    report: LoadReport,
    tris: Vec<Triangle>,
    groups: Groups,
    /// The first point or line primitive skipped.
    skipped: Option<String>,
}

/// glTF's component types.
const BYTE: u64 = 5120;
const UNSIGNED_BYTE: u64 = 5121;
const SHORT: u64 = 5122;
const UNSIGNED_SHORT: u64 = 5123;
const UNSIGNED_INT: u64 = 5125;
const FLOAT: u64 = 5126;

/// An accessor's elements, read and checked: where they are and how to step through them.
struct View {
    /// The buffer, and where the accessor's first element starts in it.
    buffer: Rc<[u8]>,
    start: usize,
    stride: usize,
    count: usize,
    component: u64,
}

impl<'a> Reader<'a> {
    fn err(&self, at: impl Into<String>, m: impl Into<String>) -> SceneError {
        item(self.path, at.into(), m.into())
    }

    /// `root[key][i]`, or an error naming `from` (where the index came from).
    fn entry(&self, key: &str, i: u64, from: &str) -> Result<&'a Value, SceneError> {
        let arr = self.root.get(key).and_then(Value::as_array);
        let n = arr.map_or(0, |a| a.len());
        arr.and_then(|a| a.get(i as usize))
            .filter(|v| v.is_object())
            .ok_or_else(|| {
                self.err(
                    from,
                    if (i as usize) < n {
                        format!("{key}[{i}] is not an object")
                    } else {
                        format!("refers to {key}[{i}], and the file has {n}")
                    },
                )
            })
    }

    /// A whole number property, `None` when absent.
    fn uint(&self, obj: Node<'a>, key: &str, at: &str) -> Result<Option<u64>, SceneError> {
        match obj.v.get(key) {
            None => Ok(None),
            Some(v) => v.as_u64().map(Some).ok_or_else(|| {
                self.err(
                    format!("{at}.{key}"),
                    format!("expected a whole number >= 0, got {}", short(v)),
                )
            }),
        }
    }

    fn req_uint(&self, obj: Node<'a>, key: &str, at: &str) -> Result<u64, SceneError> {
        self.uint(obj, key, at)?
            .ok_or_else(|| self.err(at, format!("has no {key}, which glTF requires")))
    }

    /// An array of `n` finite numbers, `None` when absent.
    fn numbers(
        &self,
        obj: Node<'a>,
        key: &str,
        n: usize,
        at: &str,
    ) -> Result<Option<Vec<f64>>, SceneError> {
        let Some(v) = obj.v.get(key) else {
            return Ok(None);
        };
        let here = format!("{at}.{key}");
        let arr = v
            .as_array()
            .filter(|a| a.len() == n)
            .ok_or_else(|| self.err(&here, format!("expected an array of {n} numbers")))?;
        arr.iter()
            .map(|x| {
                x.as_f64().filter(|x| x.is_finite()).ok_or_else(|| {
                    self.err(&here, format!("expected finite numbers, got {}", short(x)))
                })
            })
            .collect::<Result<Vec<_>, _>>()
            .map(Some)
    }

    fn read(&mut self) -> Result<(), SceneError> {
        let root = self.root;
        if !root.is_object() {
            return Err(self.err("the JSON", "expected an object at the top level"));
        }
        let version = root
            .get("asset")
            .and_then(|a| a.get("version"))
            .ok_or_else(|| self.err("asset", "missing: glTF requires asset.version"))?;
        let version = version.as_str().unwrap_or("");
        if !version.starts_with("2.") {
            return Err(self.err(
                "asset.version",
                format!("'{version}', quiver reads glTF 2.0"),
            ));
        }
        if let Some(req) = root.get("extensionsRequired").and_then(Value::as_array) {
            if !req.is_empty() {
                let names: Vec<String> = req.iter().map(short).collect();
                return Err(self.err(
                    "extensionsRequired",
                    format!(
                        "the file requires {}, which quiver does not read (core glTF 2.0 only)",
                        names.join(", ")
                    ),
                ));
            }
        }
        let (roots, every) = self.scene_roots()?;
        // Depth-first over the node forest, each node's world transform from its parent's.
        let node_count = root
            .get("nodes")
            .and_then(Value::as_array)
            .map_or(0, |a| a.len());
        let mut seen = vec![false; node_count];
        let mut stack: Vec<(u64, DMat4, String)> = roots
            .into_iter()
            .rev()
            .map(|(i, from)| (i, DMat4::IDENTITY, from))
            .collect();
        while let Some((i, parent, from)) = stack.pop() {
            let at = format!("nodes[{i}]");
            let node = Node {
                v: self.entry("nodes", i, &from)?,
            };
            if std::mem::replace(&mut seen[i as usize], true) {
                return Err(self.err(
                    from,
                    format!("{at} is reached a second time: glTF nodes must form a forest"),
                ));
            }
            let world = parent * self.local(node, &at)?;
            if let Some(m) = self.uint(node, "mesh", &at)? {
                let name = |v: &Value, fallback: String| {
                    v.get("name")
                        .and_then(Value::as_str)
                        .map_or(fallback, String::from)
                };
                let mesh = self.entry("meshes", m, &format!("{at}.mesh"))?;
                let group = format!(
                    "{}/{}",
                    name(node.v, at.clone()),
                    name(mesh, format!("meshes[{m}]"))
                );
                self.mesh(m, mesh, &world, &group)?;
            }
            if let Some(children) = node.v.get("children") {
                let list = children.as_array().ok_or_else(|| {
                    self.err(
                        format!("{at}.children"),
                        "expected an array of node indices",
                    )
                })?;
                for (k, c) in list.iter().enumerate().rev() {
                    let c = c.as_u64().ok_or_else(|| {
                        self.err(
                            format!("{at}.children[{k}]"),
                            format!("expected a node index, got {}", short(c)),
                        )
                    })?;
                    stack.push((c, world, format!("{at}.children[{k}]")));
                }
            }
        }
        if every {
            // Every node should be placed; one that was not is no root, so some node names it
            // as a child, and only a cycle of children keeps all of them from the roots.
            if let Some(i) = seen.iter().position(|s| !s) {
                return Err(self.err(
                    format!("nodes[{i}]"),
                    "is in a cycle of children (or below one), so no root reaches it: glTF \
                     nodes must form a forest",
                ));
            }
        }
        Ok(())
    }

    /// The root nodes to place, each with where it was named, and whether they should reach
    /// every node (a file without scenes places all of its nodes).
    fn scene_roots(&self) -> Result<(Vec<(u64, String)>, bool), SceneError> {
        let root = Node { v: self.root };
        let scenes = self.root.get("scenes").and_then(Value::as_array);
        let chosen = match self.uint(root, "scene", "the file")? {
            Some(s) => Some(s),
            None if scenes.is_some_and(|s| !s.is_empty()) => Some(0),
            None => None,
        };
        let Some(s) = chosen else {
            // No scene: every node that is no other node's child.
            let nodes = self.root.get("nodes").and_then(Value::as_array);
            let n = nodes.map_or(0, |a| a.len());
            let mut child = vec![false; n];
            for node in nodes.into_iter().flatten() {
                for c in node
                    .get("children")
                    .and_then(Value::as_array)
                    .into_iter()
                    .flatten()
                {
                    if let Some(c) = c.as_u64().filter(|&c| (c as usize) < n) {
                        child[c as usize] = true;
                    }
                }
            }
            let roots = (0..n)
                .filter(|&i| !child[i])
                .map(|i| (i as u64, "nodes (no scene)".to_string()))
                .collect();
            return Ok((roots, true));
        };
        let at = format!("scenes[{s}]");
        let scene = Node {
            v: self.entry("scenes", s, "scene")?,
        };
        let Some(nodes) = scene.v.get("nodes") else {
            return Ok((Vec::new(), false));
        };
        let list = nodes
            .as_array()
            .ok_or_else(|| self.err(format!("{at}.nodes"), "expected an array of node indices"))?;
        list.iter()
            .enumerate()
            .map(|(k, v)| {
                v.as_u64()
                    .map(|i| (i, format!("{at}.nodes[{k}]")))
                    .ok_or_else(|| {
                        self.err(
                            format!("{at}.nodes[{k}]"),
                            format!("expected a node index, got {}", short(v)),
                        )
                    })
            })
            .collect::<Result<Vec<_>, _>>()
            .map(|roots| (roots, false))
    }

    /// A node's own transform: its matrix, or its translation, rotation and scale.
    fn local(&self, node: Node<'a>, at: &str) -> Result<DMat4, SceneError> {
        let matrix = self.numbers(node, "matrix", 16, at)?;
        let t = self.numbers(node, "translation", 3, at)?;
        let r = self.numbers(node, "rotation", 4, at)?;
        let s = self.numbers(node, "scale", 3, at)?;
        if let Some(m) = matrix {
            if t.is_some() || r.is_some() || s.is_some() {
                return Err(self.err(
                    at,
                    "has both a matrix and translation/rotation/scale; glTF allows one",
                ));
            }
            let mut a = [0.0; 16];
            a.copy_from_slice(&m);
            // Column-major: the bottom row is every fourth number from the fourth.
            let bottom = [a[3], a[7], a[11], a[15]];
            if bottom != [0.0, 0.0, 0.0, 1.0] {
                return Err(self.err(
                    format!("{at}.matrix"),
                    format!(
                        "the bottom row is {bottom:?}, not [0, 0, 0, 1]: glTF node matrices \
                         are affine"
                    ),
                ));
            }
            // glTF stores matrices column by column, as glam reads them.
            return Ok(DMat4::from_cols_array(&a));
        }
        let t = t.map_or(DVec3::ZERO, |v| DVec3::new(v[0], v[1], v[2]));
        let s = s.map_or(DVec3::ONE, |v| DVec3::new(v[0], v[1], v[2]));
        let q = match r {
            None => DQuat::IDENTITY,
            Some(q) => {
                let q = DQuat::from_xyzw(q[0], q[1], q[2], q[3]);
                // Writers store f32 quaternions, so a unit one is within rounding of 1.
                if (q.length() - 1.0).abs() > 1e-3 {
                    return Err(self.err(
                        format!("{at}.rotation"),
                        format!("not a unit quaternion (length {})", q.length()),
                    ));
                }
                q.normalize()
            }
        };
        Ok(DMat4::from_scale_rotation_translation(s, q, t))
    }

    fn mesh(
        &mut self,
        m: u64,
        mesh: &'a Value,
        world: &DMat4,
        group: &str,
    ) -> Result<(), SceneError> {
        let at = format!("meshes[{m}]");
        let prims = mesh
            .get("primitives")
            .and_then(Value::as_array)
            .ok_or_else(|| self.err(&at, "has no primitives array, which glTF requires"))?;
        for (p, prim) in prims.iter().enumerate() {
            let pat = format!("{at}.primitives[{p}]");
            if !prim.is_object() {
                return Err(self.err(pat, "expected an object"));
            }
            let prim = Node { v: prim };
            let mode = self.uint(prim, "mode", &pat)?.unwrap_or(4);
            match mode {
                0..=3 => {
                    self.skipped.get_or_insert(pat);
                    continue;
                }
                4..=6 => {}
                _ => {
                    return Err(self.err(
                        format!("{pat}.mode"),
                        format!("{mode} is no glTF primitive mode (0 to 6)"),
                    ))
                }
            }
            let attrs = prim
                .v
                .get("attributes")
                .filter(|a| a.is_object())
                .ok_or_else(|| self.err(&pat, "has no attributes object, which glTF requires"))?;
            let pos_at = format!("{pat}.attributes.POSITION");
            let pos = Node { v: attrs };
            let pos_index = self
                .uint(pos, "POSITION", &format!("{pat}.attributes"))?
                .ok_or_else(|| self.err(&pat, "has no POSITION attribute: nothing to trace"))?;
            let positions = self.positions(pos_index, &pos_at, world)?;
            let indices = match self.uint(prim, "indices", &pat)? {
                Some(a) => Some(self.indices(a, &format!("{pat}.indices"), positions.len())?),
                None => None,
            };
            let n = indices.as_ref().map_or(positions.len(), |i| i.len());
            let triangles = match mode {
                4 => n / 3,
                _ => n.saturating_sub(2),
            };
            // Every placement of a mesh counts: its triangles (and what they become) are
            // stored once per node that places it.
            let placed = || format!("{pat}, placed as {group}/{p}");
            let temporary = (positions.len() * 16 + indices.as_ref().map_or(0, |i| i.len()) * 4)
                as u64
                + triangles as u64 * 12;
            self.budget.bytes(triangles as u64 * 12, placed)?;
            self.budget.prims(triangles as u64, placed)?;
            self.budget.grow(&mut self.tris, triangles, placed)?;
            let corner = |k: usize| indices.as_ref().map_or(k as u32, |i| i[k]);
            let mut corners: Vec<[u32; 3]> = Vec::with_capacity(triangles);
            match mode {
                4 => {
                    if n % 3 != 0 {
                        return Err(self.err(
                            &pat,
                            format!("{n} vertices in triangle mode, expected a multiple of 3"),
                        ));
                    }
                    corners.extend(
                        (0..n / 3).map(|t| [corner(3 * t), corner(3 * t + 1), corner(3 * t + 2)]),
                    );
                }
                // Strips alternate their winding so every triangle faces the same way.
                5 => corners.extend((0..n.saturating_sub(2)).map(|t| {
                    if t % 2 == 0 {
                        [corner(t), corner(t + 1), corner(t + 2)]
                    } else {
                        [corner(t + 1), corner(t), corner(t + 2)]
                    }
                })),
                _ => corners.extend(
                    (1..n.saturating_sub(1)).map(|t| [corner(0), corner(t), corner(t + 1)]),
                ),
            }
            self.groups.start(format!("{group}/{p}"), self.tris.len());
            for (t, c) in corners.iter().enumerate() {
                let v = c.map(|k| positions[k as usize]);
                if let Some(k) = (0..3).find(|&k| !v[k].is_finite()) {
                    // Non-finite positions are errors unless dropping: `positions` said so.
                    self.report.drop_primitive(format!(
                        "{}: {pat}: triangle {t} dropped: its vertex {} ({pos_at} element {}) \
                         is not finite",
                        self.path.display(),
                        c[k],
                        c[k]
                    ));
                    continue;
                }
                self.tris.push(Triangle::new(v[0], v[1], v[2]));
            }
            self.groups.close(self.tris.len());
            // The positions, indices and corners are freed here.
            self.budget.release(temporary);
        }
        Ok(())
    }

    /// The accessor's bytes, checked against its view and buffer.
    fn accessor(&mut self, a: u64, at: &str) -> Result<(View, &'a Value), SceneError> {
        let here = format!("{at} (accessors[{a}])");
        let acc = self.entry("accessors", a, at)?;
        let accn = Node { v: acc };
        if acc.get("sparse").is_some() {
            return Err(self.err(&here, "sparse accessors are not supported"));
        }
        let component = self.req_uint(accn, "componentType", &here)?;
        let csize = match component {
            BYTE | UNSIGNED_BYTE => 1,
            SHORT | UNSIGNED_SHORT => 2,
            UNSIGNED_INT | FLOAT => 4,
            c => {
                return Err(self.err(
                    format!("{here}.componentType"),
                    format!("{c} is no glTF component type (5120 to 5126)"),
                ))
            }
        };
        let ty = acc.get("type").and_then(Value::as_str).unwrap_or("");
        let comps = match ty {
            "SCALAR" => 1,
            "VEC2" => 2,
            "VEC3" => 3,
            "VEC4" | "MAT2" => 4,
            "MAT3" => 9,
            "MAT4" => 16,
            _ => {
                return Err(self.err(
                    format!("{here}.type"),
                    format!("expected SCALAR, VEC2, VEC3, VEC4, MAT2, MAT3 or MAT4, got '{ty}'"),
                ))
            }
        };
        let count = self.req_uint(accn, "count", &here)?;
        let offset = self.uint(accn, "byteOffset", &here)?.unwrap_or(0);
        let Some(bv) = self.uint(accn, "bufferView", &here)? else {
            return Err(self.err(
                &here,
                "has no bufferView (its elements would all be zero): nothing to read",
            ));
        };
        let view = self.entry("bufferViews", bv, &here)?;
        let viewn = Node { v: view };
        let vat = format!("bufferViews[{bv}]");
        let buffer = self.req_uint(viewn, "buffer", &vat)?;
        let view_offset = self.uint(viewn, "byteOffset", &vat)?.unwrap_or(0);
        let view_len = self.req_uint(viewn, "byteLength", &vat)?;
        let elem = (comps * csize) as u64;
        let stride = match self.uint(viewn, "byteStride", &vat)? {
            None => elem,
            Some(s) if (4..=252).contains(&s) && s % 4 == 0 => s,
            Some(s) => {
                return Err(self.err(
                    format!("{vat}.byteStride"),
                    format!("{s}, expected a multiple of 4 from 4 to 252"),
                ))
            }
        };
        if stride < elem {
            return Err(self.err(
                &here,
                format!("elements of {elem} bytes overlap at {vat}'s stride of {stride}"),
            ));
        }
        // Every product below is checked: the counts are the file's word, not yet the bytes'.
        // Even count 0 needs its offset inside the view: the slice starts there.
        let need = count.checked_sub(1).map_or(Some(offset), |c| {
            c.checked_mul(stride)?
                .checked_add(elem)?
                .checked_add(offset)
        });
        if need.is_none_or(|n| n > view_len) {
            return Err(self.err(
                &here,
                format!(
                    "{count} elements of {elem} bytes from byte {offset} need {} bytes, and {vat} has {view_len}",
                    need.map_or("more than 2^64".to_string(), |n| n.to_string())
                ),
            ));
        }
        let path = self.path;
        let (data, buffer_len) = self.buffer(buffer, &vat)?;
        let end = view_offset.checked_add(view_len);
        if end.is_none_or(|e| e > buffer_len) {
            return Err(item(
                path,
                vat,
                format!(
                    "bytes {view_offset} to {} reach past buffers[{buffer}], which has {}",
                    end.map_or("past 2^64".to_string(), |e| e.to_string()),
                    buffer_len
                ),
            ));
        }
        // Inside the buffer: `need` put offset (and every element) inside the view.
        let start = (view_offset + offset) as usize;
        Ok((
            View {
                buffer: data,
                start,
                stride: stride as usize,
                count: count as usize,
                component,
            },
            acc,
        ))
    }

    /// The positions of accessor `a`, moved by `world`. Non-finite ones are errors, or under
    /// [`NonFinite::Drop`] kept for `mesh` to drop the triangles that use them.
    fn positions(&mut self, a: u64, at: &str, world: &DMat4) -> Result<Vec<Vec3A>, SceneError> {
        let here = format!("{at} (accessors[{a}])");
        let non_finite = self.opts.non_finite;
        let path = self.path;
        let (view, acc) = self.accessor(a, at)?;
        let ty = acc.get("type").and_then(Value::as_str).unwrap_or("");
        if ty != "VEC3" || view.component != FLOAT {
            return Err(item(
                path,
                here,
                format!(
                    "positions must be VEC3 of FLOAT (5126), got {ty} of {}",
                    view.component
                ),
            ));
        }
        let f = |b: &[u8], k: usize| {
            f32::from_le_bytes([b[4 * k], b[4 * k + 1], b[4 * k + 2], b[4 * k + 3]])
        };
        self.budget.bytes(view.count as u64 * 16, || here.clone())?;
        let mut out = Vec::with_capacity(view.count);
        for i in 0..view.count {
            let b = &view.buffer[view.start + i * view.stride..];
            let p = [f(b, 0), f(b, 1), f(b, 2)];
            let moved = world.transform_point3(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64));
            let q = Vec3A::new(moved.x as f32, moved.y as f32, moved.z as f32);
            if !q.is_finite() && non_finite == NonFinite::Error {
                let message = match p.iter().position(|x| !x.is_finite()) {
                    Some(k) => format!(
                        "element {i}: {} is {}",
                        ["x", "y", "z"][k],
                        if p[k].is_nan() { "NaN" } else { "infinite" }
                    ),
                    None => {
                        format!("element {i}: the node transform carries it out of f32's range")
                    }
                };
                return Err(item(path, here, message));
            }
            out.push(q);
        }
        Ok(out)
    }

    /// The vertex indices of accessor `a`, each checked against `vertices`.
    fn indices(&mut self, a: u64, at: &str, vertices: usize) -> Result<Vec<u32>, SceneError> {
        let here = format!("{at} (accessors[{a}])");
        let path = self.path;
        let (view, acc) = self.accessor(a, at)?;
        let ty = acc.get("type").and_then(Value::as_str).unwrap_or("");
        if ty != "SCALAR"
            || !matches!(
                view.component,
                UNSIGNED_BYTE | UNSIGNED_SHORT | UNSIGNED_INT
            )
        {
            return Err(item(
                path,
                here,
                format!(
                    "indices must be SCALAR of UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT \
                     (5121, 5123, 5125), got {ty} of {}",
                    view.component
                ),
            ));
        }
        self.budget.bytes(view.count as u64 * 4, || here.clone())?;
        let mut out = Vec::with_capacity(view.count);
        for i in 0..view.count {
            let b = &view.buffer[view.start + i * view.stride..];
            let k = match view.component {
                UNSIGNED_BYTE => b[0] as u32,
                UNSIGNED_SHORT => u16::from_le_bytes([b[0], b[1]]) as u32,
                _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            };
            if k as usize >= vertices {
                return Err(item(
                    path,
                    here,
                    format!(
                        "element {i}: vertex index {k} is out of range: POSITION has {vertices} elements"
                    ),
                ));
            }
            out.push(k);
        }
        Ok(out)
    }

    /// Buffer `b`'s bytes (at least its declared length of them, read once) and that length.
    fn buffer(&mut self, b: u64, from: &str) -> Result<(Rc<[u8]>, u64), SceneError> {
        let at = format!("buffers[{b}]");
        let buf = Node {
            v: self.entry("buffers", b, from)?,
        };
        let len = self.req_uint(buf, "byteLength", &at)?;
        let i = b as usize;
        if self.buffers.len() <= i {
            self.buffers.resize(i + 1, None);
        }
        if let Some(data) = &self.buffers[i] {
            return Ok((data.clone(), len));
        }
        let bytes: Rc<[u8]> = match buf.v.get("uri") {
            None => {
                let bin = self.bin.ok_or_else(|| {
                    self.err(&at, "has no uri, and the file has no GLB BIN chunk")
                })?;
                if b != 0 {
                    return Err(
                        self.err(&at, "has no uri; only buffers[0] can be the GLB BIN chunk")
                    );
                }
                self.budget.bytes(bin.len() as u64, || {
                    format!("{at} (a copy of the BIN chunk)")
                })?;
                bin.into()
            }
            Some(uri) => {
                let uri = uri
                    .as_str()
                    .ok_or_else(|| self.err(format!("{at}.uri"), "expected a string"))?;
                self.load_uri(uri, len, &format!("{at}.uri"))?
            }
        };
        // GLB pads its BIN chunk to 4 bytes, so the data may be longer, never shorter.
        if (bytes.len() as u64) < len {
            return Err(self.err(
                &at,
                format!(
                    "byteLength is {len}, and the data has {} bytes",
                    bytes.len()
                ),
            ));
        }
        self.buffers[i] = Some(bytes.clone());
        Ok((bytes, len))
    }

    /// A buffer's bytes from a `data:` URI or a file in the glTF file's folder
    /// ([`confined`]), each file read once however many buffers name it.
    fn load_uri(&mut self, uri: &str, len: u64, at: &str) -> Result<Rc<[u8]>, SceneError> {
        if let Some(rest) = uri.strip_prefix("data:") {
            let Some((_, payload)) = rest.split_once(";base64,") else {
                return Err(self.err(at, "a data: URI must be base64 (';base64,')"));
            };
            self.budget
                .bytes(payload.len() as u64 / 4 * 3 + 3, || at.to_string())?;
            return base64(payload).map(Rc::from).map_err(|m| self.err(at, m));
        }
        let folder = self.path.parent().unwrap_or(Path::new(""));
        let file = confined(folder, uri, self.opts.outside_files)
            .map_err(|m| self.err(at, format!("'{}': {m}", super::clip(uri))))?;
        if let Some((_, data)) = self.files.iter().find(|(f, _)| *f == file) {
            return Ok(data.clone());
        }
        let fail = |m: String| self.err(at, format!("{}: {m}", file.display()));
        // A regular file of at least the declared size: a device or a short file is refused
        // before anything is read.
        let meta = std::fs::metadata(&file).map_err(|e| fail(format!("cannot read: {e}")))?;
        if !meta.is_file() {
            return Err(fail("not a regular file".into()));
        }
        if meta.len() < len {
            return Err(fail(format!(
                "has {} bytes, and the buffer's byteLength is {len}",
                meta.len()
            )));
        }
        // The same bound as every file quiver reads (`read_bytes`).
        if meta.len() > self.opts.max_file_bytes {
            return Err(fail(format!(
                "{} bytes, more than the {} a file may hold",
                meta.len(),
                self.opts.max_file_bytes
            )));
        }
        // Read whole (other buffers may name more of it), and counted before it is read.
        self.budget
            .bytes(meta.len(), || format!("{at} ({})", file.display()))?;
        let data: Rc<[u8]> = super::read_bytes(&file, self.opts.max_file_bytes)
            .map_err(|e| self.err(at, e.to_string()))?
            .into();
        self.files.push((file, data.clone()));
        Ok(data)
    }
}

/// The file a relative URI names inside `folder`: percent-decoded, then normalised (`.` and
/// empty parts dropped, `..` taking back a part), and refused when it is absolute, names a
/// scheme, or leads outside `folder`, by its `..` parts or through a symbolic link; unless
/// `outside` allows files anywhere.
fn confined(folder: &Path, uri: &str, outside: bool) -> Result<PathBuf, String> {
    const HOW: &str = "quiver reads data: URIs and files inside the glTF file's folder \
                       (LoadOptions::outside_files, --outside-files, allows others)";
    // A scheme (`file:`, `http:`) is a letter and letters, digits, `+`, `-` or `.` up to `:`.
    let scheme = uri.split_once(':').is_some_and(|(s, _)| {
        s.starts_with(|c: char| c.is_ascii_alphabetic())
            && s.chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.'))
    });
    if scheme {
        return Err(format!("a URI scheme other than data:; {HOW}"));
    }
    let name = percent_decode(uri)?;
    if name.contains('\0') {
        return Err("decodes to a name with a NUL byte".into());
    }
    let absolute = name.starts_with('/')
        || name.starts_with('\\')
        || Path::new(&name).is_absolute()
        || Path::new(&name)
            .components()
            .any(|c| matches!(c, Component::Prefix(_)));
    if outside {
        return Ok(folder.join(&name));
    }
    if absolute {
        return Err(format!("an absolute path; {HOW}"));
    }
    // Both separators, so a name meant for Windows is judged as it would be read there.
    let mut parts: Vec<&str> = Vec::new();
    for part in name.split(['/', '\\']) {
        match part {
            "" | "." => {}
            ".." => {
                if parts.pop().is_none() {
                    return Err(format!("leads outside the glTF file's folder; {HOW}"));
                }
            }
            p => parts.push(p),
        }
    }
    if parts.is_empty() {
        return Err("names the folder itself, not a file".into());
    }
    let file: PathBuf = parts.iter().fold(folder.to_path_buf(), |f, p| f.join(p));
    // Symbolic links: where the file really is must still be inside the folder. A file that
    // does not exist is left for the read to report.
    if let (Ok(real), Ok(base)) = (file.canonicalize(), folder_real(folder)) {
        if !real.starts_with(&base) {
            return Err(format!(
                "a symbolic link leads outside the glTF file's folder (to {}); {HOW}",
                real.display()
            ));
        }
        return Ok(real);
    }
    Ok(file)
}

/// `folder` with its symbolic links resolved (the current directory for an empty one).
fn folder_real(folder: &Path) -> std::io::Result<PathBuf> {
    if folder.as_os_str().is_empty() {
        Path::new(".").canonicalize()
    } else {
        folder.canonicalize()
    }
}

/// A JSON value for a message, cut short.
fn short(v: &Value) -> String {
    super::clip(&v.to_string())
}

/// Standard base64 (RFC 4648, `=` padding optional).
fn base64(s: &str) -> Result<Vec<u8>, String> {
    let s = s.trim_end_matches('=');
    let mut out = Vec::with_capacity(s.len() / 4 * 3 + 2);
    let (mut acc, mut bits) = (0u32, 0);
    for (i, c) in s.bytes().enumerate() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => {
                return Err(format!(
                    "invalid base64 character '{}' at position {i} of the data",
                    c.escape_ascii()
                ))
            }
        };
        acc = (acc << 6) | v as u32;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    if bits >= 6 {
        return Err("base64 data ends in the middle of a byte".into());
    }
    Ok(out)
}

/// A URI path with its `%XX` escapes decoded.
fn percent_decode(s: &str) -> Result<String, String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = b
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| format!("invalid %-escape at position {i} of '{s}'"))?;
            out.push(hex);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).map_err(|_| format!("'{s}' does not decode to UTF-8"))
}
