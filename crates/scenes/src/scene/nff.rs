//! Neutral File Format (Haines, NFF.TXT in the SPD): reading and writing.
//!
//! Entities: `v` (followed by `from`, `at`, `up`, `angle`, `hither`, `resolution` lines), `b`
//! background, `l` light (optional colour), `f` fill material (`r g b Kd Ks Shine T ior`), `c`
//! cone (base point and radius, apex point and radius), `s` sphere, `p` polygon and `pp`
//! polygonal patch (vertex count, then one vertex, or vertex and normal, per line), `#`
//! comments. The reader takes whitespace-separated tokens, so line breaks inside an entity
//! are not significant; errors name the line of the offending token.
//!
//! ```
//! use quiver_scenes::scene::{nff, Scene};
//! let s = Scene::load("tetra2").unwrap();
//! let mut text = Vec::new();
//! nff::write(&s, &mut text).unwrap();
//! let back = nff::parse(std::str::from_utf8(&text).unwrap(), "tetra2.nff").unwrap();
//! assert_eq!(back.objects, s.objects);
//! assert!(nff::parse("s 0 0 zero 1", "bad.nff").unwrap_err().to_string().contains("line 1"));
//! ```

use super::{Camera, Light, Material, Object, Scene, SceneError, Shape};
use crate::primitive::{Cone, Sphere};
use glam::Vec3A;
use quiver::Triangle;
use std::io::{self, Write};
use std::path::Path;

/// Token stream with line numbers.
struct Tokens<'a> {
    path: &'a Path,
    items: Vec<(usize, &'a str)>,
    at: usize,
}

impl<'a> Tokens<'a> {
    fn new(text: &'a str, path: &'a Path) -> Self {
        let mut items = Vec::new();
        for (n, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("");
            items.extend(line.split_whitespace().map(|t| (n + 1, t)));
        }
        Tokens { path, items, at: 0 }
    }

    fn err(&self, line: usize, message: String) -> SceneError {
        SceneError::File {
            path: self.path.into(),
            message: format!("line {line}: {message}"),
        }
    }

    /// The line of the current (or, at the end, the last) token.
    fn line(&self) -> usize {
        self.items
            .get(self.at)
            .or(self.items.last())
            .map_or(1, |t| t.0)
    }

    fn next(&mut self, what: &str) -> Result<&'a str, SceneError> {
        let t = self.items.get(self.at).ok_or_else(|| {
            self.err(
                self.line(),
                format!("unexpected end of file, expected {what}"),
            )
        })?;
        self.at += 1;
        Ok(t.1)
    }

    fn peek(&self) -> Option<&'a str> {
        self.items.get(self.at).map(|t| t.1)
    }

    fn number(&mut self, what: &str) -> Result<f32, SceneError> {
        let line = self.line();
        let tok = self.next(what)?;
        match tok.parse::<f32>() {
            Ok(x) if x.is_finite() => Ok(x),
            _ => Err(self.err(
                line,
                format!("expected {what} (a finite number), found '{tok}'"),
            )),
        }
    }

    fn count(&mut self, what: &str, min: u32) -> Result<usize, SceneError> {
        let line = self.line();
        let tok = self.next(what)?;
        match tok.parse::<u32>() {
            Ok(n) if n >= min => Ok(n as usize),
            _ => Err(self.err(
                line,
                format!("expected {what} (an integer >= {min}), found '{tok}'"),
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

    fn keyword(&mut self, want: &str) -> Result<(), SceneError> {
        let line = self.line();
        let tok = self.next(want)?;
        if tok == want {
            Ok(())
        } else {
            Err(self.err(line, format!("expected '{want}', found '{tok}'")))
        }
    }
}

/// Parses NFF text. `path` names the source in error messages.
pub fn parse(text: &str, path: impl AsRef<Path>) -> Result<Scene, SceneError> {
    let path = path.as_ref();
    let mut tk = Tokens::new(text, path);
    let mut scene = Scene {
        name: path.display().to_string(),
        objects: Vec::new(),
        materials: Vec::new(),
        camera: Camera::new(Vec3A::new(0.0, 0.0, -10.0), Vec3A::ZERO, Vec3A::Y, 45.0),
        lights: Vec::new(),
        background: Vec3A::ZERO,
        hither: 1.0,
        resolution: [512, 512],
    };
    let mut have_view = false;
    let mut material: Option<u32> = None;
    while let Some(tok) = tk.peek() {
        let line = tk.line();
        tk.at += 1;
        let shape = |s: Shape, tk: &Tokens, objects: &mut Vec<Object>| {
            let m =
                material.ok_or_else(|| tk.err(line, format!("'{tok}' before any 'f' material")))?;
            objects.push(Object {
                shape: s,
                material: m,
            });
            Ok::<(), SceneError>(())
        };
        match tok {
            "v" => {
                tk.keyword("from")?;
                let from = tk.vec3("from")?;
                tk.keyword("at")?;
                let at = tk.vec3("at")?;
                tk.keyword("up")?;
                let up = tk.vec3("up")?;
                tk.keyword("angle")?;
                let angle = tk.number("angle")?;
                tk.keyword("hither")?;
                scene.hither = tk.number("hither")?;
                tk.keyword("resolution")?;
                scene.resolution = [
                    tk.count("resolution x", 1)? as u32,
                    tk.count("resolution y", 1)? as u32,
                ];
                if !(angle > 0.0 && angle < 180.0) {
                    return Err(tk.err(
                        line,
                        format!("view angle {angle} must lie strictly between 0 and 180"),
                    ));
                }
                if (at - from).length_squared() == 0.0 || up.length_squared() == 0.0 {
                    return Err(tk.err(line, "view needs from != at and a non-zero up".into()));
                }
                scene.camera = Camera::new(from, at, up, angle);
                have_view = true;
            }
            "b" => scene.background = tk.vec3("background colour")?,
            "l" => {
                let pos = tk.vec3("light position")?;
                // An optional colour follows when the next token is a number.
                let color = if tk.peek().is_some_and(|t| t.parse::<f32>().is_ok()) {
                    tk.vec3("light colour")?
                } else {
                    Vec3A::ONE
                };
                scene.lights.push(Light { pos, color });
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
                let center = tk.vec3("sphere centre")?;
                let radius = tk.number("sphere radius")?;
                if radius <= 0.0 {
                    return Err(tk.err(line, format!("sphere radius {radius} must be positive")));
                }
                shape(
                    Shape::Sphere(Sphere { center, radius }),
                    &tk,
                    &mut scene.objects,
                )?;
            }
            "c" => {
                let base = tk.vec3("cone base")?;
                let base_radius = tk.number("cone base radius")?;
                let apex = tk.vec3("cone apex")?;
                let apex_radius = tk.number("cone apex radius")?;
                if base_radius < 0.0 || apex_radius < 0.0 {
                    return Err(tk.err(line, "cone radii must not be negative".into()));
                }
                let c = Cone {
                    base,
                    base_radius,
                    apex,
                    apex_radius,
                };
                shape(Shape::Cone(c), &tk, &mut scene.objects)?;
            }
            "p" | "pp" => {
                let n = tk.count("vertex count", 3)?;
                // A count larger than the rest of the file is an error found below; do not let
                // it reserve memory first.
                let mut verts = Vec::with_capacity(n.min(tk.items.len() - tk.at));
                let mut normals = Vec::new();
                for _ in 0..n {
                    verts.push(tk.vec3("vertex")?);
                    if tok == "pp" {
                        normals.push(tk.vec3("vertex normal")?);
                    }
                }
                let s = match (tok, n) {
                    ("pp", _) => Shape::Patch { verts, normals },
                    (_, 3) => Shape::Triangle(Triangle::new(verts[0], verts[1], verts[2])),
                    _ => Shape::Polygon(verts),
                };
                shape(s, &tk, &mut scene.objects)?;
            }
            other => {
                return Err(tk.err(
                    line,
                    format!("unknown entity '{other}' (expected v, b, l, f, c, s, p or pp)"),
                ))
            }
        }
    }
    if !have_view {
        scene.camera = Camera::framing(&scene.bounds());
    }
    Ok(scene)
}

/// Writes the scene as NFF. Numbers are printed in Rust's shortest round-trip form, so
/// reading the file back gives exactly the same scene.
pub fn write(scene: &Scene, w: &mut impl Write) -> io::Result<()> {
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
    for o in &scene.objects {
        if current != Some(o.material) {
            let m = &scene.materials[o.material as usize];
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
            current = Some(o.material);
        }
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
            "t.nff: line 2: unexpected end of file, expected sphere radius"
        );
        assert_eq!(
            err("f 1 1 1 0.5 0.5 3 0 1\n\ns 0 0 0 -1"),
            "t.nff: line 3: sphere radius -1 must be positive"
        );
        assert_eq!(
            err("s 0 0 0 1"),
            "t.nff: line 1: 's' before any 'f' material"
        );
        assert_eq!(
            err("f 1 1 1 1 1 1 1 1\np 2\n0 0 0\n1 1 1"),
            "t.nff: line 2: expected vertex count (an integer >= 3), found '2'"
        );
        assert_eq!(
            err("x 1"),
            "t.nff: line 1: unknown entity 'x' (expected v, b, l, f, c, s, p or pp)"
        );
        assert_eq!(
            err("v\nfrom 0 0 0\nat 0 0 1\nup 0 1 0\nangle 45\nhither 1\nresolution 512 nan"),
            "t.nff: line 7: expected resolution y (an integer >= 1), found 'nan'"
        );
        assert_eq!(
            err("f 1 1 1 1 1 1 1 1\ns 0 inf 0 1"),
            "t.nff: line 2: expected sphere centre y (a finite number), found 'inf'"
        );
        assert_eq!(
            err("v\nfrom 0 0 0\nlookat 0 0 1"),
            "t.nff: line 3: expected 'at', found 'lookat'"
        );
    }

    #[test]
    fn lights_with_and_without_colour() {
        let s = parse("l 1 2 3\nl 4 5 6 0.5 0.5 0.5\nl 7 8 9", "t.nff").unwrap();
        let colors: Vec<Vec3A> = s.lights.iter().map(|l| l.color).collect();
        assert_eq!(colors, vec![Vec3A::ONE, Vec3A::splat(0.5), Vec3A::ONE]);
    }
}
