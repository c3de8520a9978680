//! PLY (Turk's polygon file format, as the Stanford scanning repository ships its meshes):
//! ASCII, binary little-endian and binary big-endian bodies, gzipped or not (`Scene::load`
//! inflates `.ply.gz`).
//!
//! quiver reads the `x`, `y` and `z` properties of the `vertex` element, of any scalar type
//! (`char`/`int8` to `double`/`float64`; integers are converted to `f32`), and the
//! `vertex_indices` (or `vertex_index`) list of the `face` element, of any integer types, every
//! face fan-triangulated, one object per triangle. Every other element and property is read
//! past and not used. A file has one [`Group`](super::Group), named by the file's name.
//!
//! Strict, as the OBJ and NFF readers are: a fault in the header or an ASCII body is
//! `file:line: message` ([`SceneError::Parse`]); one in a binary body names the element, its
//! index, the property and the byte offset, `file: vertex 12, property y (byte 345): message`
//! ([`SceneError::Item`]). An element count the rest of the file cannot hold is an error before
//! anything is allocated for it. A face with fewer than three corners or an index outside the
//! vertices is an error; a NaN or infinite coordinate is one too, unless
//! [`NonFinite::Drop`] leaves out (and counts) the faces that use the vertex.
//!
//! ```
//! use quiver_scenes::scene::ply;
//! let text = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
//!             property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
//!             end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n";
//! let scene = ply::parse(text.as_bytes(), "quad.ply").unwrap();
//! assert_eq!(scene.triangles().len(), 2);
//! let e = ply::parse(text.replace("4 0 1 2 3", "3 0 1 9").as_bytes(), "quad.ply").unwrap_err();
//! assert_eq!(e.to_string(), "quad.ply:14: face 0: vertex index 9 is out of range: the file has 4 vertices");
//! ```

use super::{clip, Budget, Groups, LoadOptions, LoadReport, NonFinite, Scene, SceneError};
use glam::Vec3A;
use quiver_rt::geometry::Triangle;
use std::path::Path;

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Ty {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Ty {
    /// Both spellings of the spec (the original names and the sized ones).
    fn parse(s: &str) -> Option<Ty> {
        Some(match s {
            "char" | "int8" => Ty::I8,
            "uchar" | "uint8" => Ty::U8,
            "short" | "int16" => Ty::I16,
            "ushort" | "uint16" => Ty::U16,
            "int" | "int32" => Ty::I32,
            "uint" | "uint32" => Ty::U32,
            "float" | "float32" => Ty::F32,
            "double" | "float64" => Ty::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Ty::I8 | Ty::U8 => 1,
            Ty::I16 | Ty::U16 => 2,
            Ty::I32 | Ty::U32 | Ty::F32 => 4,
            Ty::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Ty::F32 | Ty::F64)
    }

    /// The range of an integer type, for ASCII values and messages.
    fn range(self) -> (i64, i64) {
        match self {
            Ty::I8 => (i8::MIN.into(), i8::MAX.into()),
            Ty::U8 => (0, u8::MAX.into()),
            Ty::I16 => (i16::MIN.into(), i16::MAX.into()),
            Ty::U16 => (0, u16::MAX.into()),
            Ty::I32 => (i32::MIN.into(), i32::MAX.into()),
            Ty::U32 => (0, u32::MAX.into()),
            Ty::F32 | Ty::F64 => (i64::MIN, i64::MAX),
        }
    }

    fn name(self) -> &'static str {
        match self {
            Ty::I8 => "char",
            Ty::U8 => "uchar",
            Ty::I16 => "short",
            Ty::U16 => "ushort",
            Ty::I32 => "int",
            Ty::U32 => "uint",
            Ty::F32 => "float",
            Ty::F64 => "double",
        }
    }
}

/// A property: a scalar, or a list with its count and item types.
#[derive(Clone, Debug)]
struct Property {
    name: String,
    ty: Ty,
    list: Option<Ty>,
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: u64,
    props: Vec<Property>,
    /// The header line that declared it.
    line: usize,
}

impl Element {
    /// Bytes of one instance in a binary body, lists counted as empty (their count alone):
    /// the least it can take.
    fn min_size(&self) -> u64 {
        self.props
            .iter()
            .map(|p| p.list.unwrap_or(p.ty).size() as u64)
            .sum()
    }

    /// Singular noun for messages: `vertex 3`, `face 3`, `edge 3`.
    fn what(&self) -> &str {
        &self.name
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Ascii,
    Little,
    Big,
}

/// The header: its format, elements, and where the body starts (byte offset and line).
struct Header {
    format: Format,
    elements: Vec<Element>,
    body: usize,
    body_line: usize,
}

/// Where a value was read, for messages and for the faces checked after the body is read.
#[derive(Clone, Copy, Debug)]
enum At {
    Line(usize),
    Byte(u64),
}

/// Parses PLY data strictly (see [`parse_with`]). `path` names the source in error messages.
pub fn parse(data: &[u8], path: impl AsRef<Path>) -> Result<Scene, SceneError> {
    parse_with(data, path, &LoadOptions::default()).map(|(scene, _)| scene)
}

/// Parses PLY data (the file's bytes, inflated if it was gzipped); `path` names the source in
/// error messages and the scene's one group. A vertex with a NaN or infinite coordinate is an
/// error, or under [`NonFinite::Drop`] every face that uses it is left out and counted.
///
/// ```
/// use quiver_scenes::scene::{ply, LoadOptions, NonFinite};
/// let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\n\
///             property double z\nelement face 1\nproperty list uchar uint vertex_indices\n\
///             end_header\n0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n";
/// let e = ply::parse(text.as_bytes(), "n.ply").unwrap_err();
/// assert_eq!(e.to_string(), "n.ply:11: vertex 1: y is NaN ('nan')");
/// let lax = LoadOptions::default().non_finite(NonFinite::Drop);
/// let (scene, report) = ply::parse_with(text.as_bytes(), "n.ply", &lax).unwrap();
/// assert_eq!((scene.objects.len(), report.dropped_primitives), (0, 1));
/// assert_eq!(report.reasons, ["n.ply:13: face 0 dropped: its vertex 1 (line 11) is not finite"]);
/// ```
pub fn parse_with(
    data: &[u8],
    path: impl AsRef<Path>,
    opts: &LoadOptions,
) -> Result<(Scene, LoadReport), SceneError> {
    let path = path.as_ref();
    let data = data.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(data);
    let mut mesh = Mesh::new(Budget::new(path, opts));
    mesh.budget
        .bytes(data.len() as u64, || "the file's bytes".into())?;
    let header = read_header(data, path)?;
    let body = &data[header.body..];
    match header.format {
        Format::Ascii => read_ascii(body, header.body_line, &header, path, opts, &mut mesh)?,
        f => read_binary(body, header.body as u64, f, &header, path, opts, &mut mesh)?,
    }
    mesh.finish(path)
}

fn parse_err(path: &Path, line: usize, message: String) -> SceneError {
    SceneError::Parse {
        path: path.into(),
        line,
        message,
    }
}

fn item_err(path: &Path, item: String, message: String) -> SceneError {
    SceneError::Item {
        path: path.into(),
        item,
        message,
    }
}

/// Reads the header lines up to `end_header`, checking each.
fn read_header(data: &[u8], path: &Path) -> Result<Header, SceneError> {
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut at = 0;
    let mut line = 0;
    loop {
        line += 1;
        let Some(len) = data[at..].iter().position(|&b| b == b'\n') else {
            return Err(parse_err(
                path,
                line,
                if line == 1 && data.is_empty() {
                    "the file is empty, expected 'ply'".into()
                } else {
                    "the header ends without 'end_header'".into()
                },
            ));
        };
        let raw = &data[at..at + len];
        at += len + 1;
        let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
        let text = String::from_utf8_lossy(raw);
        let mut words = text.split_whitespace();
        let keyword = words.next();
        if line == 1 {
            if keyword != Some("ply") || words.next().is_some() {
                return Err(parse_err(
                    path,
                    1,
                    format!("expected 'ply' as the first line, got '{}'", clip(&text)),
                ));
            }
            continue;
        }
        let err = |m: String| parse_err(path, line, m);
        match keyword {
            Some("comment" | "obj_info") | None => {}
            Some("format") => {
                let f = match words.next() {
                    Some("ascii") => Format::Ascii,
                    Some("binary_little_endian") => Format::Little,
                    Some("binary_big_endian") => Format::Big,
                    other => {
                        return Err(err(format!(
                            "expected ascii, binary_little_endian or binary_big_endian after \
                             'format', got '{}'",
                            other.unwrap_or("")
                        )))
                    }
                };
                match words.next() {
                    Some("1.0") => {}
                    v => {
                        return Err(err(format!(
                            "expected version 1.0 after the format, got '{}'",
                            v.unwrap_or("")
                        )))
                    }
                }
                if format.replace(f).is_some() {
                    return Err(err("a second 'format' line".into()));
                }
            }
            Some("element") => {
                let (Some(name), Some(count), None) = (words.next(), words.next(), words.next())
                else {
                    return Err(err(format!(
                        "expected 'element NAME COUNT', got '{}'",
                        clip(&text)
                    )));
                };
                let count = count.parse::<u64>().map_err(|_| {
                    err(format!(
                        "expected a whole number for the count of element {name}, got '{count}'"
                    ))
                })?;
                if elements.iter().any(|e| e.name == name) {
                    return Err(err(format!("a second element named {name}")));
                }
                elements.push(Element {
                    name: name.into(),
                    count,
                    props: Vec::new(),
                    line,
                });
            }
            Some("property") => {
                let Some(element) = elements.last_mut() else {
                    return Err(err("a property before any element".into()));
                };
                let ty_of = |w: Option<&str>| {
                    let w = w.unwrap_or("");
                    Ty::parse(w).ok_or_else(|| {
                        err(format!(
                            "expected a property type (char, uchar, short, ushort, int, uint, \
                             float, double or int8 ... float64), got '{w}'"
                        ))
                    })
                };
                let first = words.next();
                let (ty, list) = if first == Some("list") {
                    let count = ty_of(words.next())?;
                    if !count.is_integer() {
                        return Err(err(format!(
                            "a list's count type must be an integer type, got {}",
                            count.name()
                        )));
                    }
                    (ty_of(words.next())?, Some(count))
                } else {
                    (ty_of(first)?, None)
                };
                let (Some(name), None) = (words.next(), words.next()) else {
                    return Err(err(format!(
                        "expected 'property TYPE NAME' or 'property list COUNT_TYPE TYPE \
                         NAME', got '{}'",
                        clip(&text)
                    )));
                };
                if element.props.iter().any(|p| p.name == name) {
                    return Err(err(format!(
                        "a second property {name} in element {}",
                        element.name
                    )));
                }
                element.props.push(Property {
                    name: name.into(),
                    ty,
                    list,
                });
            }
            Some("end_header") => {
                let format =
                    format.ok_or_else(|| err("the header ends without a 'format' line".into()))?;
                return Ok(Header {
                    format,
                    elements,
                    body: at,
                    body_line: line + 1,
                });
            }
            Some(k) => {
                return Err(err(format!(
                    "unknown header line '{}' (expected format, element, property, comment, \
                     obj_info or end_header)",
                    clip(k)
                )))
            }
        }
    }
}

/// What the body reader keeps: vertices and faces, with where each was read.
struct Mesh<'p> {
    /// What it holds, against the load's limits.
    budget: Budget<'p>,
    /// The vertex element's count (0 without one).
    vertex_count: u64,
    verts: Vec<Vec3A>,
    /// Under [`NonFinite::Drop`]: the non-finite vertices, by index, and where they were read.
    bad_verts: Vec<(u32, At)>,
    corners: Vec<u32>,
    /// Each face's end in `corners` and where it was read.
    faces: Vec<(usize, At)>,
}

/// Where the vertex coordinates and face indices are among an element's properties.
#[derive(Clone, Copy)]
enum Role {
    Vertex { x: usize, y: usize, z: usize },
    Face { indices: usize },
    Other,
}

/// Checks the vertex and face elements the reader needs and says which is which.
fn roles(header: &Header, path: &Path) -> Result<Vec<Role>, SceneError> {
    let mut has_face = false;
    let roles = header
        .elements
        .iter()
        .map(|e| {
            let err = |m: String| parse_err(path, e.line, m);
            match e.name.as_str() {
                "vertex" => {
                    let find = |axis: &str| {
                        let i =
                            e.props.iter().position(|p| p.name == axis).ok_or_else(|| {
                                err(format!("element vertex has no property {axis}"))
                            })?;
                        if e.props[i].list.is_some() {
                            return Err(err(format!(
                                "vertex property {axis} is a list, expected a number"
                            )));
                        }
                        Ok(i)
                    };
                    if e.count > u32::MAX as u64 {
                        return Err(err(format!(
                            "{} vertices, more than {} are not supported",
                            e.count,
                            u32::MAX
                        )));
                    }
                    Ok(Role::Vertex {
                        x: find("x")?,
                        y: find("y")?,
                        z: find("z")?,
                    })
                }
                "face" => {
                    has_face = true;
                    let i = e
                        .props
                        .iter()
                        .position(|p| p.name == "vertex_indices" || p.name == "vertex_index")
                        .ok_or_else(|| err("element face has no vertex_indices list".into()))?;
                    let p = &e.props[i];
                    if p.list.is_none() || !p.ty.is_integer() {
                        return Err(err(format!(
                            "face property {} must be a list of an integer type",
                            p.name
                        )));
                    }
                    Ok(Role::Face { indices: i })
                }
                _ => Ok(Role::Other),
            }
        })
        .collect::<Result<Vec<_>, _>>()?;
    let vertex = header.elements.iter().find(|e| e.name == "vertex");
    if !has_face && vertex.is_some_and(|v| v.count > 0) {
        return Err(SceneError::File {
            path: path.into(),
            message: "has vertices but no face element: quiver traces faces, and a point \
                      cloud has none"
                .into(),
        });
    }
    Ok(roles)
}

/// How many instances of `e` to reserve room for: its count, but no more than `room` bytes
/// could hold at `min` bytes each, so a hostile count allocates nothing.
fn capacity(count: u64, room: usize, min: u64) -> usize {
    count.min(room as u64 / min.max(1)) as usize
}

fn read_ascii(
    body: &[u8],
    first_line: usize,
    header: &Header,
    path: &Path,
    opts: &LoadOptions,
    mesh: &mut Mesh,
) -> Result<(), SceneError> {
    let roles = roles(header, path)?;
    let text = String::from_utf8_lossy(body);
    if let std::borrow::Cow::Owned(_) = text {
        // Not UTF-8: the text is a copy of the body.
        mesh.budget
            .bytes(body.len() as u64, || "the body as text".into())?;
    }
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(n, l)| (first_line + n, l))
        .filter(|(_, l)| !l.trim().is_empty());
    let mut last_line = first_line;
    for (e, role) in header.elements.iter().zip(roles) {
        // Every instance is one line of at least one character and a line break.
        if e.count > body.len() as u64 {
            return Err(parse_err(
                path,
                e.line,
                format!(
                    "element {} claims {} instances, and the body has only {} bytes",
                    e.name,
                    e.count,
                    body.len()
                ),
            ));
        }
        reserve(
            mesh,
            e,
            role,
            capacity(e.count, body.len(), 2),
            At::Line(e.line),
        )?;
        let mut values: Vec<f64> = Vec::new();
        let mut tokens: Vec<&str> = Vec::new();
        let mut list: Vec<i64> = Vec::new();
        for i in 0..e.count {
            let Some((line, l)) = lines.next() else {
                return Err(parse_err(
                    path,
                    last_line,
                    format!("the file ends after {i} of {} {} lines", e.count, e.what()),
                ));
            };
            last_line = line;
            let err = |m: String| parse_err(path, line, format!("{} {i}: {m}", e.what()));
            let mut words = l.split_whitespace();
            values.clear();
            tokens.clear();
            list.clear();
            let mut next = |ty: Ty, what: &str| -> Result<(f64, &str), SceneError> {
                let tok = words.next().ok_or_else(|| {
                    err(format!(
                        "expected a {} for {what}, got the end of the line",
                        ty.name()
                    ))
                })?;
                let v = ascii_value(tok, ty)
                    .map_err(|m| err(format!("{m} for {what}, got '{}'", clip(tok))))?;
                Ok((v, tok))
            };
            for (k, p) in e.props.iter().enumerate() {
                match p.list {
                    None => {
                        let (v, tok) = next(p.ty, &p.name)?;
                        values.push(v);
                        tokens.push(tok);
                    }
                    Some(count_ty) => {
                        let (n, tok) = next(count_ty, &format!("the count of {}", p.name))?;
                        if n < 0.0 {
                            return Err(err(format!("list {} has a negative count {n}", p.name)));
                        }
                        // The items must be on this line, so a hostile count runs out of words.
                        let keep = matches!(role, Role::Face { indices } if indices == k);
                        // A count the line cannot hold fails on its missing items below,
                        // before anything is stored for it.
                        if keep && n as usize <= l.len() {
                            mesh.face_room(n as usize, &mut list, At::Line(line), i)?;
                        }
                        for _ in 0..n as u64 {
                            let (v, _) = next(p.ty, &format!("an item of {}", p.name))?;
                            if keep {
                                list.push(v as i64);
                            }
                        }
                        values.push(n);
                        tokens.push(tok);
                    }
                }
            }
            if let Some(tok) = words.next() {
                return Err(err(format!(
                    "expected {} value(s) on the line, got more: '{}'",
                    e.props.len(),
                    clip(tok)
                )));
            }
            let at = At::Line(line);
            match role {
                Role::Vertex { x, y, z } => mesh.vertex(
                    [values[x], values[y], values[z]],
                    Some([tokens[x], tokens[y], tokens[z]]),
                    at,
                    i,
                    path,
                    opts,
                )?,
                Role::Face { .. } => mesh.face(&list, at, i, path)?,
                Role::Other => {}
            }
        }
    }
    if let Some((line, l)) = lines.next() {
        return Err(parse_err(
            path,
            line,
            format!("text after the last element: '{}'", clip(l.trim())),
        ));
    }
    Ok(())
}

/// An ASCII value of type `ty` (integers whole and within the type's range).
fn ascii_value(tok: &str, ty: Ty) -> Result<f64, String> {
    if ty.is_integer() {
        let (lo, hi) = ty.range();
        return tok
            .parse::<i64>()
            .ok()
            .filter(|v| (lo..=hi).contains(v))
            .map(|v| v as f64)
            .ok_or_else(|| format!("expected a {} ({lo} to {hi})", ty.name()));
    }
    tok.parse::<f64>()
        .map_err(|_| format!("expected a number ({})", ty.name()))
}

/// Room for `n` instances of `e` (as vertices or faces), charged to the mesh's budget.
fn reserve(mesh: &mut Mesh, e: &Element, role: Role, n: usize, at: At) -> Result<(), SceneError> {
    let item = || place(at, format!("element {}", e.name));
    match role {
        Role::Vertex { .. } => {
            mesh.vertex_count = e.count;
            mesh.budget.grow(&mut mesh.verts, n, item)
        }
        Role::Face { .. } => {
            mesh.budget.grow(&mut mesh.faces, n, item)?;
            mesh.budget
                .grow(&mut mesh.corners, n.saturating_mul(3), item)
        }
        Role::Other => Ok(()),
    }
}

/// `what` and where it is, for [`SceneError::OverBudget`]'s item: `face 3 (line 14)`.
fn place(at: At, what: String) -> String {
    match at {
        At::Line(l) => format!("{what} (line {l})"),
        At::Byte(b) => format!("{what} (byte {b})"),
    }
}

/// A binary body's bytes with the offset of its first byte in the file.
struct Cursor<'a> {
    data: &'a [u8],
    at: usize,
    base: u64,
    big: bool,
}

impl Cursor<'_> {
    fn offset(&self) -> u64 {
        self.base + self.at as u64
    }

    fn left(&self) -> usize {
        self.data.len() - self.at
    }

    /// One value of type `ty` as f64 (exact for every integer type), or how many bytes were
    /// missing.
    fn value(&mut self, ty: Ty) -> Result<f64, usize> {
        let n = ty.size();
        if self.left() < n {
            return Err(n - self.left());
        }
        let mut b = [0u8; 8];
        b[..n].copy_from_slice(&self.data[self.at..self.at + n]);
        self.at += n;
        if self.big {
            b[..n].reverse();
        }
        Ok(match ty {
            Ty::I8 => b[0] as i8 as f64,
            Ty::U8 => b[0] as f64,
            Ty::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
            Ty::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
            Ty::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Ty::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Ty::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Ty::F64 => f64::from_le_bytes(b),
        })
    }
}

fn read_binary(
    body: &[u8],
    base: u64,
    format: Format,
    header: &Header,
    path: &Path,
    opts: &LoadOptions,
    mesh: &mut Mesh,
) -> Result<(), SceneError> {
    let roles = roles(header, path)?;
    let mut cur = Cursor {
        data: body,
        at: 0,
        base,
        big: format == Format::Big,
    };
    let mut values: Vec<f64> = Vec::new();
    let mut list: Vec<i64> = Vec::new();
    for (e, role) in header.elements.iter().zip(roles) {
        let min = e.min_size();
        let need = e.count.checked_mul(min);
        if need.is_none_or(|n| n > cur.left() as u64) {
            return Err(item_err(
                path,
                format!("element {} (byte {})", e.name, cur.offset()),
                format!(
                    "{} instances of at least {min} bytes each do not fit in the {} bytes \
                     left in the file",
                    e.count,
                    cur.left()
                ),
            ));
        }
        reserve(
            mesh,
            e,
            role,
            capacity(e.count, cur.left(), min),
            At::Byte(cur.offset()),
        )?;
        if e.props.is_empty() {
            // Instances of no bytes: nothing to read, and nothing to loop over.
            continue;
        }
        for i in 0..e.count {
            values.clear();
            list.clear();
            let start = cur.offset();
            for (k, p) in e.props.iter().enumerate() {
                let here = cur.offset();
                let short = |missing: usize| {
                    item_err(
                        path,
                        format!("{} {i}, property {} (byte {here})", e.what(), p.name),
                        format!("the file ends, expected {missing} more bytes"),
                    )
                };
                match p.list {
                    None => values.push(cur.value(p.ty).map_err(short)?),
                    Some(count_ty) => {
                        let n = cur.value(count_ty).map_err(short)?;
                        let room = cur.left() / p.ty.size();
                        if n < 0.0 || n > room as f64 {
                            return Err(item_err(
                                path,
                                format!("{} {i}, property {} (byte {here})", e.what(), p.name),
                                if n < 0.0 {
                                    format!("the list has a negative count {n}")
                                } else {
                                    format!(
                                        "the list claims {n} items of {} bytes, and {} bytes \
                                         are left in the file",
                                        p.ty.size(),
                                        cur.left()
                                    )
                                },
                            ));
                        }
                        let keep = matches!(role, Role::Face { indices } if indices == k);
                        if keep {
                            mesh.face_room(n as usize, &mut list, At::Byte(start), i)?;
                        }
                        for _ in 0..n as u64 {
                            let v = cur.value(p.ty).map_err(short)?;
                            if keep {
                                list.push(v as i64);
                            }
                        }
                        values.push(n);
                    }
                }
            }
            let at = At::Byte(start);
            match role {
                Role::Vertex { x, y, z } => {
                    mesh.vertex([values[x], values[y], values[z]], None, at, i, path, opts)?
                }
                Role::Face { .. } => mesh.face(&list, at, i, path)?,
                Role::Other => {}
            }
        }
    }
    if cur.left() > 0 {
        return Err(item_err(
            path,
            format!("byte {}", cur.offset()),
            format!("{} bytes after the last element", cur.left()),
        ));
    }
    Ok(())
}

impl<'p> Mesh<'p> {
    fn new(budget: Budget<'p>) -> Mesh<'p> {
        Mesh {
            budget,
            vertex_count: 0,
            verts: Vec::new(),
            bad_verts: Vec::new(),
            corners: Vec::new(),
            faces: Vec::new(),
        }
    }

    /// Charges face `i` of `n` corners before they are read: its triangles against the
    /// load's limits, and room for its corners in `list`.
    fn face_room(
        &mut self,
        n: usize,
        list: &mut Vec<i64>,
        at: At,
        i: u64,
    ) -> Result<(), SceneError> {
        let item = || place(at, format!("face {i}"));
        let triangles = (n as u64).saturating_sub(2);
        self.budget.prims(triangles, item)?;
        // `finish` stores the triangles in a list of exactly their number.
        let size = std::mem::size_of::<Triangle>() as u64;
        self.budget.bytes(triangles.saturating_mul(size), item)?;
        self.budget.grow(list, n, item)
    }

    /// A vertex; `tokens` are its ASCII numbers, for messages.
    fn vertex(
        &mut self,
        xyz: [f64; 3],
        tokens: Option<[&str; 3]>,
        at: At,
        i: u64,
        path: &Path,
        opts: &LoadOptions,
    ) -> Result<(), SceneError> {
        let p = xyz.map(|v| v as f32);
        if let Some(axis) = p.iter().position(|v| !v.is_finite()) {
            match opts.non_finite {
                NonFinite::Error => {
                    let name = ["x", "y", "z"][axis];
                    let kind = if p[axis].is_nan() { "NaN" } else { "infinite" };
                    return Err(match at {
                        At::Line(line) => parse_err(
                            path,
                            line,
                            format!(
                                "vertex {i}: {name} is {kind} ('{}')",
                                tokens.map_or("", |t| t[axis])
                            ),
                        ),
                        At::Byte(b) => item_err(
                            path,
                            format!("vertex {i} (byte {b})"),
                            format!("{name} is {kind} in f32 ({})", xyz[axis]),
                        ),
                    });
                }
                NonFinite::Drop => {
                    self.budget
                        .grow(&mut self.bad_verts, 1, || place(at, format!("vertex {i}")))?;
                    self.bad_verts.push((i as u32, at))
                }
            }
        }
        self.budget
            .grow(&mut self.verts, 1, || place(at, format!("vertex {i}")))?;
        self.verts.push(Vec3A::from(p));
        Ok(())
    }

    fn face(&mut self, corners: &[i64], at: At, i: u64, path: &Path) -> Result<(), SceneError> {
        let item = || place(at, format!("face {i}"));
        self.budget.grow(&mut self.corners, corners.len(), item)?;
        self.budget.grow(&mut self.faces, 1, item)?;
        let start = self.corners.len();
        for &c in corners {
            // Checked against the vertex count once every element is read: the vertex element
            // may come after the faces. Out-of-range values are kept as u32::MAX to fail then.
            self.corners.push(u32::try_from(c).unwrap_or(u32::MAX));
        }
        let n = self.corners.len() - start;
        if n < 3 {
            return Err(place_err(
                path,
                at,
                format!("face {i}"),
                format!("a face needs at least 3 vertices, got {n}"),
            ));
        }
        self.faces.push((self.corners.len(), at));
        Ok(())
    }

    fn finish(self, path: &Path) -> Result<(Scene, LoadReport), SceneError> {
        let mut report = LoadReport::default();
        let mut tris = Vec::with_capacity(self.corners.len().saturating_sub(2 * self.faces.len()));
        let mut start = 0;
        for (f, &(end, at)) in self.faces.iter().enumerate() {
            let face = &self.corners[start..end];
            start = end;
            if let Some(&bad) = face.iter().find(|&&c| c as u64 >= self.vertex_count) {
                // u32::MAX also stands for a negative index or one past u32; say which.
                return Err(place_err(
                    path,
                    at,
                    format!("face {f}"),
                    if bad == u32::MAX {
                        format!(
                            "a vertex index is negative or too large: the file has {} vertices",
                            self.vertex_count
                        )
                    } else {
                        format!(
                            "vertex index {bad} is out of range: the file has {} vertices",
                            self.vertex_count
                        )
                    },
                ));
            }
            if !self.bad_verts.is_empty() {
                let bad = face
                    .iter()
                    .find_map(|&c| self.bad_verts.binary_search_by_key(&c, |b| b.0).ok());
                if let Some(b) = bad {
                    let (v, vat) = self.bad_verts[b];
                    let (place, vplace) = match (at, vat) {
                        (At::Line(l), At::Line(vl)) => {
                            (format!("{}:{l}", path.display()), format!("line {vl}"))
                        }
                        (At::Byte(o), At::Byte(vo)) => (
                            format!("{}: face {f} (byte {o})", path.display()),
                            format!("byte {vo}"),
                        ),
                        // One file has one format.
                        _ => unreachable!("a PLY body is ASCII or binary throughout"),
                    };
                    let reason = match at {
                        At::Line(_) => {
                            format!("{place}: face {f} dropped: its vertex {v} ({vplace}) is not finite")
                        }
                        At::Byte(_) => {
                            format!("{place} dropped: its vertex {v} ({vplace}) is not finite")
                        }
                    };
                    // Counted as the load counts primitives: a face of n corners is n - 2.
                    report.drop_primitives(face.len() - 2, reason);
                    continue;
                }
            }
            let v = |k: usize| self.verts[face[k] as usize];
            for k in 1..face.len() - 1 {
                tris.push(Triangle::new(v(0), v(k), v(k + 1)));
            }
        }
        let mut groups = Groups::default();
        let name = path.file_name().map_or_else(
            || path.display().to_string(),
            |n| n.to_string_lossy().into(),
        );
        groups.start(name, 0);
        let groups = groups.finish(tris.len());
        Ok((super::mesh_scene(path, tris, groups)?, report))
    }
}

/// A fault at a face or vertex: a line in an ASCII body, a byte offset in a binary one.
fn place_err(path: &Path, at: At, what: String, message: String) -> SceneError {
    match at {
        At::Line(line) => parse_err(path, line, format!("{what}: {message}")),
        At::Byte(b) => item_err(path, format!("{what} (byte {b})"), message),
    }
}
