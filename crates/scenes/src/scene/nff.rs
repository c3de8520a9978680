//! Neutral File Format (Haines, NFF.TXT in the SPD): reading and writing.
//!
//! Entities: `v` (followed by `from`, `at`, `up`, `angle`, `hither`, `resolution` lines), `b`
//! background, `l` light (optional colour), `f` fill material (`r g b Kd Ks Shine T ior`), `c`
//! cone (base point and radius, apex point and radius), `s` sphere, `p` polygon and `pp`
//! polygonal patch (vertex count, then one vertex, or vertex and normal, per line), `#`
//! comments. The reader takes whitespace-separated tokens, so line breaks inside an entity
//! are not significant; errors name the line of the offending token, as
//! `file:line: message` ([`SceneError::Parse`]), the same form the OBJ reader uses.
//!
//! ```
//! use quiver_scenes::scene::{nff, Scene};
//! let s = Scene::load("tetra2").unwrap();
//! let mut text = Vec::new();
//! nff::write(&s, &mut text).unwrap();
//! let back = nff::parse(std::str::from_utf8(&text).unwrap(), "tetra2.nff").unwrap();
//! assert_eq!(back.objects, s.objects);
//! assert_eq!(
//!     nff::parse("s 0 0 zero 1", "bad.nff").unwrap_err().to_string(),
//!     "bad.nff:1: expected a number for sphere centre z, got 'zero'"
//! );
//! ```

use super::{
    Budget, Camera, Light, LoadOptions, LoadReport, Material, NonFinite, Object, Scene, SceneError,
    Shape,
};
use crate::primitive::{Cone, Sphere};
use glam::Vec3A;
use quiver_rt::Triangle;
use std::io::{self, Write};
use std::path::Path;

const ENTITIES: &str = "v, b, l, f, c, s, p or pp";

/// Token stream with line numbers, read as it is consumed: one token of lookahead, never a
/// list of every token (24 bytes each, 12 times the text for a file of one-digit numbers).
struct Tokens<'a> {
    path: &'a Path,
    /// The lines after the current one, numbered from 1.
    lines: std::iter::Enumerate<std::str::Lines<'a>>,
    /// The rest of the current line's tokens, and its number.
    words: std::str::SplitWhitespace<'a>,
    line: usize,
    /// The next token and its line, or `None` at the end of the file.
    ahead: Option<(usize, &'a str)>,
    /// The line of the last token taken (where an unexpected end is reported).
    last_line: usize,
    non_finite: NonFinite,
    /// The first non-finite number of the current entity under [`NonFinite::Drop`]: its line
    /// and message.
    dropped: Option<(usize, String)>,
    /// Context for a missing or malformed number (a polygon's promised vertex count).
    hint: Option<String>,
}

impl<'a> Tokens<'a> {
    fn new(text: &'a str, path: &'a Path, non_finite: NonFinite) -> Self {
        let mut tk = Tokens {
            path,
            lines: text.lines().enumerate(),
            words: "".split_whitespace(),
            line: 0,
            ahead: None,
            last_line: 1,
            non_finite,
            dropped: None,
            hint: None,
        };
        tk.ahead = tk.scan();
        tk
    }

    /// The token after the current lookahead.
    fn scan(&mut self) -> Option<(usize, &'a str)> {
        loop {
            if let Some(w) = self.words.next() {
                return Some((self.line, w));
            }
            let (n, line) = self.lines.next()?;
            self.line = n + 1;
            self.words = line.split('#').next().unwrap_or("").split_whitespace();
        }
    }

    /// Takes the lookahead token.
    fn advance(&mut self) -> Option<(usize, &'a str)> {
        let t = self.ahead.take()?;
        self.last_line = t.0;
        self.ahead = self.scan();
        Some(t)
    }

    fn err(&self, line: usize, message: String) -> SceneError {
        SceneError::Parse {
            path: self.path.into(),
            line,
            message,
        }
    }

    /// [`Tokens::err`] for a missing or malformed token, with the hint if there is one.
    fn syntax(&self, line: usize, message: String) -> SceneError {
        match &self.hint {
            Some(h) => self.err(line, format!("{message} ({h})")),
            None => self.err(line, message),
        }
    }

    /// The line of the current (or, at the end, the last) token.
    fn line(&self) -> usize {
        self.ahead.map_or(self.last_line, |t| t.0)
    }

    fn next(&mut self, what: &str) -> Result<&'a str, SceneError> {
        match self.advance() {
            Some(t) => Ok(t.1),
            None => Err(self.syntax(
                self.line(),
                format!("unexpected end of file, expected {what}"),
            )),
        }
    }

    fn peek(&self) -> Option<&'a str> {
        self.ahead.map(|t| t.1)
    }

    /// A number of what no primitive or light owns (view, background, material): NaN and
    /// infinity are errors whatever the options.
    fn number(&mut self, what: &str) -> Result<f32, SceneError> {
        let line = self.line();
        let tok = self.next(&format!("a number for {what}"))?;
        match super::number(tok, what) {
            Ok(x) if x.is_finite() => Ok(x),
            Ok(x) => Err(self.err(line, super::non_finite(what, tok, x))),
            Err(m) => Err(self.syntax(line, m)),
        }
    }

    /// A number of a primitive or light: under [`NonFinite::Drop`] a NaN or infinity is kept
    /// and marks the entity for dropping.
    fn coord(&mut self, what: &str) -> Result<f32, SceneError> {
        let line = self.line();
        let tok = self.next(&format!("a number for {what}"))?;
        match super::number(tok, what) {
            Ok(x) if x.is_finite() => Ok(x),
            Ok(x) => {
                let m = super::non_finite(what, tok, x);
                match self.non_finite {
                    NonFinite::Error => Err(self.err(line, m)),
                    NonFinite::Drop => {
                        self.dropped.get_or_insert((line, m));
                        Ok(x)
                    }
                }
            }
            Err(m) => Err(self.syntax(line, m)),
        }
    }

    /// A whole number of at least `min`; `small` says what is wrong with a smaller one.
    fn count(
        &mut self,
        what: &str,
        min: u32,
        small: impl Fn(u32) -> String,
    ) -> Result<usize, SceneError> {
        let line = self.line();
        let tok = self.next(&format!("{what} (a whole number)"))?;
        match tok.parse::<u32>() {
            Ok(n) if n >= min => Ok(n as usize),
            Ok(n) => Err(self.err(line, small(n))),
            Err(_) => Err(self.syntax(
                line,
                format!("expected {what} (a whole number), got '{tok}'"),
            )),
        }
    }

    fn vec3(&mut self, what: &str) -> Result<Vec3A, SceneError> {
        Ok(Vec3A::new(
            self.number(&format!("{what} x"))?,
            self.number(&format!("{what} y"))?,
            self.number(&format!("{what} z"))?,
        ))
    }

    /// A point or direction of a primitive or light (see [`Tokens::coord`]).
    fn point(&mut self, what: &str) -> Result<Vec3A, SceneError> {
        Ok(Vec3A::new(
            self.coord(&format!("{what} x"))?,
            self.coord(&format!("{what} y"))?,
            self.coord(&format!("{what} z"))?,
        ))
    }

    /// Reads the keyword `want` and returns its line.
    fn keyword(&mut self, want: &str) -> Result<usize, SceneError> {
        let line = self.line();
        let tok = self.next(&format!("'{want}'"))?;
        if tok == want {
            Ok(line)
        } else {
            Err(self.err(line, format!("expected '{want}', got '{tok}'")))
        }
    }
}

/// Parses NFF text strictly (see [`parse_with`]). `path` names the source in error messages.
pub fn parse(text: &str, path: impl AsRef<Path>) -> Result<Scene, SceneError> {
    parse_with(text, path, &LoadOptions::default()).map(|(scene, _)| scene)
}

/// Parses NFF text; `path` names the source in error messages. Under [`NonFinite::Drop`] a
/// sphere, cone, polygon, patch or light with a NaN or infinite number is left out and
/// counted; a non-finite view, background or material is an error either way.
///
/// Besides syntax, the reader rejects what would trace as something other than the file
/// says: a degenerate view (see [`crate::scene::CameraError`]), a negative `hither`, a sphere
/// without a positive radius, a cone with a negative radius, both radii zero or its two ends
/// at one point.
///
/// ```
/// use quiver_scenes::scene::{nff, LoadOptions, NonFinite};
/// let view = "v\nfrom 0 0 5\nat 0 0 0\nup 0 0 1\nangle 45\nhither 1\nresolution 64 64\n";
/// assert_eq!(
///     nff::parse(view, "v.nff").unwrap_err().to_string(),
///     "v.nff:4: camera 'up' is zero or parallel to the view direction from 'from' to 'at'"
/// );
/// let lax = LoadOptions::default().non_finite(NonFinite::Drop);
/// let (s, report) = nff::parse_with("l 0 0 1\nl inf 0 1\n", "l.nff", &lax).unwrap();
/// assert_eq!((s.lights.len(), report.dropped_lights), (1, 1));
/// assert_eq!(report.reasons, ["l.nff:2: light dropped: light position x is infinite ('inf')"]);
/// ```
pub fn parse_with(
    text: &str,
    path: impl AsRef<Path>,
    opts: &LoadOptions,
) -> Result<(Scene, LoadReport), SceneError> {
    let path = path.as_ref();
    let text = super::strip_bom(text);
    let mut tk = Tokens::new(text, path, opts.non_finite);
    let mut report = LoadReport::default();
    let mut scene = Scene {
        name: path.display().to_string(),
        objects: Vec::new(),
        materials: Vec::new(),
        camera: Camera::new(Vec3A::new(0.0, 0.0, -10.0), Vec3A::ZERO, Vec3A::Y, 45.0),
        lights: Vec::new(),
        background: Vec3A::ZERO,
        hither: 1.0,
        resolution: [512, 512],
        groups: Vec::new(),
    };
    let mut have_view = false;
    let mut material: Option<u32> = None;
    // Primitives so far, for `LoadOptions::max_primitives`, and the memory held.
    let mut held = (0u64, Budget::new(path, opts));
    held.1
        .bytes(text.len() as u64, || "the file's text".into())?;
    // The entity before the current one, to explain a stray number by a wrong count.
    let mut last: Option<(usize, &str, Option<usize>)> = None;
    while let Some(tok) = tk.peek() {
        let line = tk.line();
        tk.advance();
        tk.dropped = None;
        let mut count = None;
        // Stores a shape unless one of its numbers was not finite under `NonFinite::Drop`.
        let shape = |s: Shape,
                     tk: &mut Tokens,
                     objects: &mut Vec<Object>,
                     report: &mut LoadReport,
                     held: &mut (u64, Budget)| {
            let m =
                material.ok_or_else(|| tk.err(line, format!("'{tok}' before any 'f' material")))?;
            // What it traces as: a polygon or patch of n vertices is n - 2 triangles.
            let traced = match &s {
                Shape::Polygon(v) | Shape::Patch { verts: v, .. } => v.len() as u64 - 2,
                _ => 1,
            };
            match tk.dropped.take() {
                Some((l, why)) => report.drop_primitives(
                    traced as usize,
                    format!("{}:{l}: {} dropped: {why}", path.display(), shape_name(tok)),
                ),
                None => {
                    let prims = &mut held.0;
                    *prims += traced;
                    held.1.grow(objects, 1, || format!("line {line}"))?;
                    if *prims > opts.max_primitives {
                        return Err(SceneError::TooLarge {
                            path: path.into(),
                            line,
                            limit: opts.max_primitives,
                        });
                    }
                    objects.push(Object {
                        shape: s,
                        material: m,
                    })
                }
            }
            Ok::<(), SceneError>(())
        };
        match tok {
            "v" => {
                let l_from = tk.keyword("from")?;
                let from = tk.vec3("from")?;
                let l_at = tk.keyword("at")?;
                let at = tk.vec3("at")?;
                let l_up = tk.keyword("up")?;
                let up = tk.vec3("up")?;
                let l_angle = tk.keyword("angle")?;
                let angle = tk.number("angle")?;
                let l_hither = tk.keyword("hither")?;
                let hither = tk.number("hither")?;
                if hither < 0.0 {
                    return Err(tk.err(l_hither, format!("hither {hither} must not be negative")));
                }
                tk.keyword("resolution")?;
                scene.resolution = [
                    tk.count("resolution x", 1, |_| {
                        "resolution x must be at least 1".into()
                    })? as u32,
                    tk.count("resolution y", 1, |_| {
                        "resolution y must be at least 1".into()
                    })? as u32,
                ];
                scene.hither = hither;
                scene.camera = Camera::try_new(from, at, up, angle).map_err(|e| {
                    let l = match e.field() {
                        "from" => l_from,
                        "at" => l_at,
                        "up" => l_up,
                        _ => l_angle,
                    };
                    tk.err(l, e.to_string())
                })?;
                have_view = true;
            }
            "b" => scene.background = tk.vec3("background colour")?,
            "l" => {
                let pos = tk.point("light position")?;
                // An optional colour follows when the next token is a number.
                let color = if tk.peek().is_some_and(|t| t.parse::<f32>().is_ok()) {
                    tk.point("light colour")?
                } else {
                    Vec3A::ONE
                };
                match tk.dropped.take() {
                    Some((l, why)) => {
                        report.drop_light(format!("{}:{l}: light dropped: {why}", path.display()))
                    }
                    None => scene.lights.push(Light { pos, color }),
                }
            }
            "f" => {
                let m = Material {
                    color: tk.vec3("fill colour")?,
                    kd: tk.number("Kd")?,
                    ks: tk.number("Ks")?,
                    shine: tk.number("Shine")?,
                    t: tk.number("T")?,
                    // The SPD writes 0 for opaque surfaces; below 1 means vacuum (as the SPD
                    // library reads it).
                    ior: tk.number("index of refraction")?.max(1.0),
                };
                material = Some(match scene.materials.iter().position(|x| *x == m) {
                    Some(i) => i as u32,
                    None => {
                        scene.materials.push(m);
                        scene.materials.len() as u32 - 1
                    }
                });
            }
            "s" => {
                let center = tk.point("sphere centre")?;
                let l_radius = tk.line();
                let radius = tk.coord("sphere radius")?;
                if tk.dropped.is_none() && radius <= 0.0 {
                    return Err(
                        tk.err(l_radius, format!("sphere radius {radius} must be positive"))
                    );
                }
                shape(
                    Shape::Sphere(Sphere { center, radius }),
                    &mut tk,
                    &mut scene.objects,
                    &mut report,
                    &mut held,
                )?;
            }
            "c" => {
                let base = tk.point("cone base")?;
                let base_radius = tk.coord("cone base radius")?;
                let l_apex = tk.line();
                let apex = tk.point("cone apex")?;
                let l_apex_radius = tk.line();
                let apex_radius = tk.coord("cone apex radius")?;
                if tk.dropped.is_none() {
                    let fault = if base_radius < 0.0 || apex_radius < 0.0 {
                        Some((l_apex_radius, "cone radii must not be negative".to_string()))
                    } else if base_radius == 0.0 && apex_radius == 0.0 {
                        Some((
                            l_apex_radius,
                            "cone radii must not both be zero".to_string(),
                        ))
                    } else if base == apex {
                        Some((l_apex, "cone apex must differ from its base".to_string()))
                    } else {
                        None
                    };
                    if let Some((l, m)) = fault {
                        return Err(tk.err(l, m));
                    }
                }
                let c = Cone {
                    base,
                    base_radius,
                    apex,
                    apex_radius,
                };
                shape(
                    Shape::Cone(c),
                    &mut tk,
                    &mut scene.objects,
                    &mut report,
                    &mut held,
                )?;
            }
            "p" | "pp" => {
                let n = tk.count("vertex count", 3, |n| {
                    format!("{} needs at least 3 vertices, got {n}", shape_name(tok))
                })?;
                count = Some(n);
                // A count larger than the rest of the file is an error found below; do not let
                // it reserve memory first (a vertex takes at least six bytes of text).
                let room = n.min(text.len() / 6 + 1);
                let lists = if tok == "pp" { 2 } else { 1 };
                held.1
                    .bytes(room as u64 * 16 * lists, || format!("line {line}"))?;
                let mut verts = Vec::with_capacity(room);
                let mut normals = Vec::with_capacity(if tok == "pp" { room } else { 0 });
                // A word or the end of the file where a vertex should be: say what the count
                // promised.
                tk.hint = Some(format!("the '{tok}' on line {line} says {n} vertices"));
                for i in 1..=n {
                    verts.push(tk.point(&format!("vertex {i}"))?);
                    if tok == "pp" {
                        normals.push(tk.point(&format!("normal {i}"))?);
                    }
                }
                tk.hint = None;
                let s = match (tok, n) {
                    ("pp", _) => Shape::Patch { verts, normals },
                    (_, 3) => Shape::Triangle(Triangle::new(verts[0], verts[1], verts[2])),
                    _ => Shape::Polygon(verts),
                };
                shape(s, &mut tk, &mut scene.objects, &mut report, &mut held)?;
            }
            other if other.parse::<f32>().is_ok() => {
                let hint = match last {
                    Some((l, e @ ("p" | "pp"), Some(n))) => {
                        format!("; the '{e}' on line {l} says {n} vertices, are there more?")
                    }
                    Some((l, e, _)) => format!("; too many numbers for the '{e}' on line {l}?"),
                    None => String::new(),
                };
                return Err(tk.err(
                    line,
                    format!("expected an entity ({ENTITIES}), got the number '{other}'{hint}"),
                ));
            }
            other => {
                return Err(tk.err(
                    line,
                    format!("unknown entity '{other}' (expected {ENTITIES})"),
                ))
            }
        }
        last = Some((line, tok, count));
    }
    if !have_view {
        scene.camera = Camera::framing(&scene.bounds()).map_err(|e| SceneError::File {
            path: path.into(),
            message: format!("the file has no view ('v'), and {e}"),
        })?;
    }
    Ok((scene, report))
}

fn shape_name(entity: &str) -> &'static str {
    match entity {
        "s" => "sphere",
        "c" => "cone",
        "pp" => "patch",
        _ => "polygon",
    }
}

/// Writes the scene as NFF. Numbers are printed in Rust's shortest round-trip form, so
/// reading the file back gives exactly the same scene.
pub fn write(scene: &Scene, w: &mut impl Write) -> io::Result<()> {
    write_as(scene, None, w)
}

/// Writes the scene as NFF in patch mode at `resolution`: exactly what [`write()`] writes of
/// [`Scene::into_patches`]`(resolution)`, but each sphere's and cone's patches are written as
/// they are made, never held: memory stays that of the scene in curve mode at any resolution.
///
/// ```
/// use quiver_scenes::scene::{nff, Scene};
/// let s = Scene::load("balls1").unwrap();
/// let (mut streamed, mut whole) = (Vec::new(), Vec::new());
/// nff::write_patches(&s, 3, &mut streamed).unwrap();
/// nff::write(&s.clone().into_patches(3), &mut whole).unwrap();
/// assert_eq!(streamed, whole);
/// ```
pub fn write_patches(scene: &Scene, resolution: u32, w: &mut impl Write) -> io::Result<()> {
    write_as(scene, Some(resolution), w)
}

/// [`write()`], with spheres and cones as patches at `patches` if given.
fn write_as(scene: &Scene, patches: Option<u32>, w: &mut impl Write) -> io::Result<()> {
    let v = |p: Vec3A| format!("{} {} {}", p.x, p.y, p.z);
    let c = &scene.camera;
    writeln!(w, "# {} (written by quiver)", scene.name)?;
    writeln!(w, "v\nfrom {}\nat {}\nup {}", v(c.from), v(c.at), v(c.up))?;
    writeln!(w, "angle {}\nhither {}", c.angle, scene.hither)?;
    writeln!(
        w,
        "resolution {} {}",
        scene.resolution[0], scene.resolution[1]
    )?;
    writeln!(w, "b {}", v(scene.background))?;
    for l in &scene.lights {
        if l.color == Vec3A::ONE {
            writeln!(w, "l {}", v(l.pos))?;
        } else {
            writeln!(w, "l {} {}", v(l.pos), v(l.color))?;
        }
    }
    let mut current = None;
    // A material line before an object whose material differs from the last one written.
    let material = |w: &mut dyn Write, current: &mut Option<u32>, k: u32| -> io::Result<()> {
        if *current != Some(k) {
            let m = &scene.materials[k as usize];
            writeln!(
                w,
                "f {} {} {} {} {} {}",
                v(m.color),
                m.kd,
                m.ks,
                m.shine,
                m.t,
                m.ior
            )?;
            *current = Some(k);
        }
        Ok(())
    };
    for o in &scene.objects {
        if let (Some(r), Shape::Sphere(_) | Shape::Cone(_)) = (patches, &o.shape) {
            // Patches as into_patches makes them, three vertices with their normals, each
            // written as it is made (none for a cone of no height, as into_patches).
            let mut result = Ok(());
            let mut patch = |verts: [Vec3A; 3], normals: [Vec3A; 3]| {
                if result.is_ok() {
                    result = material(w, &mut current, o.material)
                        .and_then(|_| writeln!(w, "pp 3"))
                        .and_then(|_| {
                            verts
                                .iter()
                                .zip(&normals)
                                .try_for_each(|(&x, &n)| writeln!(w, "{} {}", v(x), v(n)))
                        });
                }
            };
            match &o.shape {
                Shape::Sphere(s) => super::tessellate::for_each_sphere_patch(s, r, &mut patch),
                Shape::Cone(k) => super::tessellate::for_each_cone_patch(k, r, &mut patch),
                _ => {}
            }
            result?;
            continue;
        }
        material(w, &mut current, o.material)?;
        match &o.shape {
            Shape::Sphere(s) => writeln!(w, "s {} {}", v(s.center), s.radius)?,
            Shape::Cone(k) => writeln!(
                w,
                "c\n{} {}\n{} {}",
                v(k.base),
                k.base_radius,
                v(k.apex),
                k.apex_radius
            )?,
            Shape::Triangle(t) => writeln!(w, "p 3\n{}\n{}\n{}", v(t.v[0]), v(t.v[1]), v(t.v[2]))?,
            Shape::Polygon(p) => {
                writeln!(w, "p {}", p.len())?;
                for &x in p {
                    writeln!(w, "{}", v(x))?;
                }
            }
            Shape::Patch { verts, normals } => {
                writeln!(w, "pp {}", verts.len())?;
                for (&x, &n) in verts.iter().zip(normals) {
                    writeln!(w, "{} {}", v(x), v(n))?;
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str) -> String {
        parse(text, "t.nff").unwrap_err().to_string()
    }

    #[test]
    fn malformed_input_names_file_line_and_expectation() {
        assert_eq!(
            err("f 1 1 1 0.5 0.5 3 0 1\ns 0 0 0"),
            "t.nff:2: unexpected end of file, expected a number for sphere radius"
        );
        assert_eq!(
            err("f 1 1 1 0.5 0.5 3 0 1\n\ns 0 0 0 -1"),
            "t.nff:3: sphere radius -1 must be positive"
        );
        assert_eq!(err("s 0 0 0 1"), "t.nff:1: 's' before any 'f' material");
        assert_eq!(
            err("f 1 1 1 1 1 1 1 1\np 2\n0 0 0\n1 1 1"),
            "t.nff:2: polygon needs at least 3 vertices, got 2"
        );
        assert_eq!(
            err("x 1"),
            "t.nff:1: unknown entity 'x' (expected v, b, l, f, c, s, p or pp)"
        );
        assert_eq!(
            err("v\nfrom 0 0 0\nat 0 0 1\nup 0 1 0\nangle 45\nhither 1\nresolution 512 nan"),
            "t.nff:7: expected resolution y (a whole number), got 'nan'"
        );
        assert_eq!(
            err("f 1 1 1 1 1 1 1 1\ns 0 inf 0 1"),
            "t.nff:2: sphere centre y is infinite ('inf')"
        );
        assert_eq!(
            err("v\nfrom 0 0 0\nlookat 0 0 1"),
            "t.nff:3: expected 'at', got 'lookat'"
        );
    }

    /// Streamed patch mode writes exactly the text of the converted scene, cones and
    /// spheres among other objects, at several resolutions.
    #[test]
    fn streamed_patches_equal_the_converted_scene() {
        for (name, res) in [("lattice1", 1), ("tree3", 2), ("jacks1", 3), ("balls1", 4)] {
            let s = Scene::load(name).unwrap();
            let (mut streamed, mut whole) = (Vec::new(), Vec::new());
            write_patches(&s, res, &mut streamed).unwrap();
            write(&s.clone().into_patches(res), &mut whole).unwrap();
            assert!(streamed == whole, "{name} at {res}");
        }
    }

    /// A file past LoadOptions::max_primitives stops at the line where the count passes it:
    /// a polygon counts as its triangles.
    #[test]
    fn max_primitives_stops_at_the_line_that_passes_it() {
        let text =
            "f 1 1 1 1 0 0 0 1\ns 0 0 0 1\ns 1 0 0 1\np 5\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0.5 0\n";
        let at = |n: u64| {
            parse_with(text, "m.nff", &LoadOptions::default().max_primitives(n))
                .map(|(s, _)| s.objects.len())
                .map_err(|e| e.to_string())
        };
        assert_eq!(at(5), Ok(3));
        assert_eq!(
            at(4),
            Err(
                "m.nff:4: more than 4 primitives, the most this load allows \
                 (LoadOptions::max_primitives)"
                    .into()
            )
        );
        assert!(at(1).unwrap_err().starts_with("m.nff:3: "));
    }

    #[test]
    fn lights_with_and_without_colour() {
        let s = parse("l 1 2 3\nl 4 5 6 0.5 0.5 0.5\nl 7 8 9", "t.nff").unwrap();
        let colors: Vec<Vec3A> = s.lights.iter().map(|l| l.color).collect();
        assert_eq!(colors, vec![Vec3A::ONE, Vec3A::splat(0.5), Vec3A::ONE]);
    }
}
