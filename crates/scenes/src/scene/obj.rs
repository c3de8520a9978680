//! Wavefront OBJ: the polygons of `v` and `f` lines, every face fan-triangulated, one object
//! per triangle, with a camera that frames the mesh and one light.
//!
//! Read line by line so every fault names its line, in the form the NFF reader uses
//! (`file:line: message`, [`SceneError::Parse`]). Faces take `v`, `v/vt`, `v//vn` and
//! `v/vt/vn` corners with 1-based or negative (relative) indices; a positive index may point
//! at a vertex further down the file. Texture coordinates and normals are counted, so their
//! indices are checked, but not used. `o` and `g` statements name the [`Group`]s of
//! [`Scene::groups`]: each starts a new group, named by the latest `o` name and the latest `g`
//! names after it, joined by `/` (`g` with several names joins them with spaces; faces before
//! any `o` or `g` are the group `default`, as the OBJ spec names it); a group holds the
//! triangles of its faces, and one without faces is left out. Every other OBJ statement
//! (materials, smoothing, points, lines, free-form curves and surfaces) is skipped; a word that
//! is no OBJ statement is an error, and so is a file of points, lines or free-form geometry
//! without any face. A file with no geometry at all is an empty scene, as an empty NFF file is.
//!
//! ```
//! use quiver_scenes::scene::obj;
//! let quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 -1\n";
//! assert_eq!(obj::parse(quad, "quad.obj").unwrap().triangles().len(), 2);
//! let e = obj::parse("v 0 0 0\nv 1 abc 0\n", "bad.obj").unwrap_err();
//! assert_eq!(e.to_string(), "bad.obj:2: expected a number for vertex y, got 'abc'");
//! ```

use super::{Budget, Group, Groups, LoadOptions, LoadReport, NonFinite, Scene, SceneError};
use glam::Vec3A;
use quiver_rt::geometry::Triangle;
use std::path::Path;

/// The Wavefront spec's other statements, skipped on purpose.
const SKIPPED: &str = "vp cstype deg bmat step p l curv curv2 surf parm trim hole scrv sp end con \
                       s mg bevel c_interp d_interp lod usemtl mtllib shadow_obj trace_obj \
                       ctech stech maplib usemap call csh";

/// Parses OBJ text strictly (see [`parse_with`]). `path` names the source in error messages.
pub fn parse(text: &str, path: impl AsRef<Path>) -> Result<Scene, SceneError> {
    parse_with(text, path, &LoadOptions::default()).map(|(scene, _)| scene)
}

/// Parses OBJ text; `path` names the source in error messages. A vertex with a NaN or
/// infinite coordinate is an error on its line, or under [`NonFinite::Drop`] every face that
/// uses it is left out and counted.
///
/// ```
/// use quiver_scenes::scene::{obj, LoadOptions, NonFinite};
/// let text = "v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n";
/// let e = obj::parse(text, "x.obj").unwrap_err();
/// assert_eq!(e.to_string(), "x.obj:3: vertex x is NaN ('nan')");
/// let lax = LoadOptions::default().non_finite(NonFinite::Drop);
/// let (scene, report) = obj::parse_with(text, "x.obj", &lax).unwrap();
/// assert_eq!((scene.objects.len(), report.dropped_primitives), (0, 1));
/// ```
pub fn parse_with(
    text: &str,
    path: impl AsRef<Path>,
    opts: &LoadOptions,
) -> Result<(Scene, LoadReport), SceneError> {
    let path = path.as_ref();
    let text = super::strip_bom(text);
    let err = |line: usize, message: String| SceneError::Parse {
        path: path.into(),
        line,
        message,
    };
    let lines = || {
        text.lines().enumerate().map(|(n, l)| {
            let mut words = l.split('#').next().unwrap_or("").split_whitespace();
            (n + 1, words.next(), words)
        })
    };

    // Totals first, so that a positive index pointing further down is checked on its face's
    // own line.
    let mut total = Counts::default();
    // The triangles the faces fan into, counted before any is made, so that a file past
    // `LoadOptions::max_primitives` costs no memory for them.
    let mut triangles = 0u64;
    let (mut all_corners, mut all_faces) = (0usize, 0usize);
    for (line, keyword, words) in lines() {
        total.add(keyword);
        if keyword == Some("f") {
            let n = words.count();
            all_corners += n;
            all_faces += 1;
            triangles += (n as u64).saturating_sub(2);
            if triangles > opts.max_primitives {
                return Err(SceneError::TooLarge {
                    path: path.into(),
                    line,
                    limit: opts.max_primitives,
                });
            }
        }
    }
    if total.v > u32::MAX as usize {
        return Err(SceneError::File {
            path: path.into(),
            message: format!(
                "{} vertices, more than {} are not supported",
                total.v,
                u32::MAX
            ),
        });
    }

    // Everything the reader holds, from the counts, before any of it is allocated: the
    // text, the vertex, corner and face lists, the triangles and the objects they become.
    let mut budget = Budget::new(path, opts);
    let lists = total.v as u64 * 16 + all_corners as u64 * 4 + all_faces as u64 * 16;
    let made =
        triangles.saturating_mul(std::mem::size_of::<Triangle>() as u64 + super::OBJECT_BYTES);
    budget.bytes(text.len() as u64 + lists + made, || {
        format!(
            "{} vertices, {all_faces} faces of {all_corners} corners, {triangles} triangles",
            total.v
        )
    })?;
    let mut seen = Counts::default();
    let mut verts = Vec::with_capacity(total.v);
    // Under `NonFinite::Drop`: the non-finite vertices, by index, with their lines.
    let mut bad_verts: Vec<(u32, usize)> = Vec::new();
    let mut corners: Vec<u32> = Vec::with_capacity(all_corners);
    // Each face's line and the end of its corners in `corners`.
    let mut faces: Vec<(usize, usize)> = Vec::with_capacity(all_faces);
    // The first point, line or free-form statement: a file of only these is not an empty
    // scene but one quiver cannot read.
    let mut first_unsurfaced: Option<(usize, &str)> = None;
    // Each `o`/`g` statement: the group name it sets and the number of faces before it.
    let mut group_starts: Vec<(String, usize)> = Vec::new();
    let mut object_name: Option<String> = None;
    for (line, keyword, mut words) in lines() {
        match keyword {
            None => {}
            Some(k @ ("o" | "g")) => {
                let named = words.collect::<Vec<_>>().join(" ");
                let named = if named.is_empty() {
                    "default".to_string()
                } else {
                    named
                };
                let name = if k == "o" {
                    object_name = Some(named.clone());
                    named
                } else {
                    match &object_name {
                        Some(o) => format!("{o}/{named}"),
                        None => named,
                    }
                };
                let name = if name.is_empty() {
                    "default".into()
                } else {
                    name
                };
                group_starts.push((name, faces.len()));
            }
            Some("v") => {
                let mut p = [0.0f32; 3];
                for (axis, x) in ["x", "y", "z"].into_iter().zip(&mut p) {
                    let what = format!("vertex {axis}");
                    let tok = words.next().ok_or_else(|| {
                        err(
                            line,
                            format!("expected a number for {what}, got the end of the line"),
                        )
                    })?;
                    *x = super::number(tok, &what).map_err(|m| err(line, m))?;
                    if !x.is_finite() {
                        match opts.non_finite {
                            NonFinite::Error => {
                                return Err(err(line, super::non_finite(&what, tok, *x)))
                            }
                            NonFinite::Drop => {
                                if bad_verts.last().map(|b| b.0) != Some(verts.len() as u32) {
                                    bad_verts.push((verts.len() as u32, line));
                                }
                            }
                        }
                    }
                }
                // Optional w, or an r g b colour (a common extension); read, not used.
                let mut extra = 0;
                for tok in words {
                    if tok.parse::<f32>().is_err() {
                        return Err(err(
                            line,
                            format!("expected a number after the vertex's x y z, got '{tok}'"),
                        ));
                    }
                    extra += 1;
                }
                if !matches!(extra, 0 | 1 | 3) {
                    return Err(err(
                        line,
                        format!(
                            "a vertex is x y z, optionally followed by w or by r g b, \
                             got {} numbers",
                            3 + extra
                        ),
                    ));
                }
                verts.push(Vec3A::from(p));
            }
            Some("f") => {
                let start = corners.len();
                for tok in words {
                    let mut parts = tok.split('/');
                    let v = parts.next().unwrap_or("");
                    let (vt, vn) = (parts.next(), parts.next());
                    let shape_ok = parts.next().is_none()
                        && match (vt, vn) {
                            (Some(vt), None) => !vt.is_empty(),
                            (_, Some(vn)) => !vn.is_empty(),
                            (None, None) => true,
                        };
                    if !shape_ok {
                        return Err(err(
                            line,
                            format!(
                                "expected a face corner (v, v/vt, v//vn or v/vt/vn), got '{tok}'"
                            ),
                        ));
                    }
                    let v = index(v, tok, "vertex", seen.v, total.v).map_err(|m| err(line, m))?;
                    if let Some(vt) = vt.filter(|s| !s.is_empty()) {
                        index(vt, tok, "texture coordinate", seen.vt, total.vt)
                            .map_err(|m| err(line, m))?;
                    }
                    if let Some(vn) = vn {
                        index(vn, tok, "normal", seen.vn, total.vn).map_err(|m| err(line, m))?;
                    }
                    corners.push(v as u32);
                }
                let n = corners.len() - start;
                if n < 3 {
                    return Err(err(
                        line,
                        format!("face needs at least 3 vertices, got {n}"),
                    ));
                }
                faces.push((line, corners.len()));
            }
            Some(k @ ("vt" | "vn")) => {
                // Their values are not used, but a malformed one is still a malformed file.
                let what = if k == "vt" {
                    "texture coordinate"
                } else {
                    "normal"
                };
                let mut n = 0;
                for tok in words {
                    super::number(tok, what).map_err(|m| err(line, m))?;
                    n += 1;
                }
                let want = if k == "vt" { 1..=3 } else { 3..=3 };
                if !want.contains(&n) {
                    return Err(err(
                        line,
                        format!(
                            "a {what} has {} numbers, got {n}",
                            if k == "vt" { "1 to 3" } else { "3" }
                        ),
                    ));
                }
            }
            Some(k) if SKIPPED.split_whitespace().any(|s| s == k) => {
                if matches!(k, "p" | "l" | "curv" | "curv2" | "surf") {
                    first_unsurfaced.get_or_insert((line, k));
                }
            }
            Some(k) => {
                return Err(err(
                    line,
                    format!(
                        "unknown statement '{k}' (expected v, vt, vn, f or another OBJ statement)"
                    ),
                ))
            }
        }
        seen.add(keyword);
    }
    if let (true, Some((line, k))) = (faces.is_empty(), first_unsurfaced) {
        return Err(err(
            line,
            format!(
                "'{k}' has no surface to trace (quiver reads 'f' faces), and the file has no faces"
            ),
        ));
    }

    let mut report = LoadReport::default();
    let mut tris = Vec::with_capacity(corners.len().saturating_sub(2 * faces.len()));
    let mut groups = Groups::default();
    groups.start("default".into(), 0);
    let mut next_group = group_starts.iter().peekable();
    let mut start = 0;
    for (f, &(line, end)) in faces.iter().enumerate() {
        while let Some((name, _)) = next_group.next_if(|g| g.1 == f) {
            groups.start(name.clone(), tris.len());
        }
        let face = &corners[start..end];
        start = end;
        if !bad_verts.is_empty() {
            let bad = face
                .iter()
                .find_map(|&i| bad_verts.binary_search_by_key(&i, |b| b.0).ok());
            if let Some(b) = bad {
                let (i, l) = bad_verts[b];
                report.drop_primitives(
                    face.len() - 2,
                    format!(
                        "{}:{line}: face dropped: its vertex {} (line {l}) is not finite",
                        path.display(),
                        i + 1
                    ),
                );
                continue;
            }
        }
        let v = |k: usize| verts[face[k] as usize];
        for k in 1..face.len() - 1 {
            tris.push(Triangle::new(v(0), v(k), v(k + 1)));
        }
    }
    let groups: Vec<Group> = groups.finish(tris.len());
    Ok((super::mesh_scene(path, tris, groups)?, report))
}

/// How many `v`, `vt` and `vn` lines.
#[derive(Default)]
struct Counts {
    v: usize,
    vt: usize,
    vn: usize,
}

impl Counts {
    fn add(&mut self, keyword: Option<&str>) {
        match keyword {
            Some("v") => self.v += 1,
            Some("vt") => self.vt += 1,
            Some("vn") => self.vn += 1,
            _ => {}
        }
    }
}

/// A face corner's index `tok` (part of `corner`) into `total` elements of which `seen` come
/// before it, 0-based.
fn index(tok: &str, corner: &str, what: &str, seen: usize, total: usize) -> Result<usize, String> {
    let many = |n: usize| match (n, what) {
        (1, _) => format!("1 {what}"),
        (n, "vertex") => format!("{n} vertices"),
        (n, _) => format!("{n} {what}s"),
    };
    let i: i64 = tok.parse().map_err(|_| {
        format!(
            "expected a {what} index (a whole number, not 0) in the face corner, got '{corner}'"
        )
    })?;
    let resolved = match i {
        0 => {
            return Err(format!(
                "{what} index 0 in '{corner}': OBJ indices start at 1"
            ))
        }
        i if i > 0 => (i as u64 - 1)
            .try_into()
            .ok()
            .filter(|&k: &usize| k < total),
        i => seen.checked_sub(i.unsigned_abs().try_into().unwrap_or(usize::MAX)),
    };
    resolved.ok_or_else(|| {
        if i > 0 {
            format!(
                "{what} index {i} is out of range: the file has {}",
                many(total)
            )
        } else {
            format!(
                "{what} index {i} is out of range: {} before this line",
                many(seen)
            )
        }
    })
}
