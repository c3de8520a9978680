//! `quiver gen`: a scene written as NFF.

use super::{scene_help, Result};
use crate::output::{check_outputs, write_file};
use quiver_scenes::scene::{nff, tessellate, Census, Scene};
use std::io::Write;
use std::path::PathBuf;

#[derive(clap::Args)]
pub(crate) struct GenArgs {
    /// A generator name with optional size, or an .nff/.obj/.ply/.ply.gz/.gltf/.glb file.
    #[arg(long_help = scene_help())]
    scene: String,
    /// Tessellate spheres and cones into polygonal patches (the SPD's patch mode).
    #[arg(long)]
    patches: bool,
    /// Tessellation resolution for --patches (the SPD's OUTPUT_RESOLUTION).
    #[arg(allow_negative_numbers = true, long, default_value_t = tessellate::DEFAULT_RESOLUTION, value_parser = clap::value_parser!(u32).range(1..=1000))]
    resolution: u32,
    /// Output file (default: stdout).
    #[arg(short, long)]
    output: Option<PathBuf>,
}

/// Runs `quiver gen`.
pub(crate) fn run(args: GenArgs) -> Result<()> {
    check_outputs(&[("--output", args.output.as_deref())], &[&args.scene])?;
    // The scene in curve mode is all gen holds: patches are written as they are made.
    let what = format!("gen {}", args.scene);
    let scene = super::load_within(std::slice::from_ref(&args.scene), |censuses, _| {
        let mut e = crate::budget::Estimate::new(&what);
        e.add("scene", super::scenes_bytes(censuses, false));
        e
    })?
    .pop()
    .ok_or("internal error: no scene loaded")?;
    check_writable(&scene)?;
    let resolution = args.patches.then_some(args.resolution);
    if let Some(path) = &args.output {
        check_disk(&scene, resolution, path)?;
    }
    let write = |mut w: &mut dyn Write| match resolution {
        Some(r) => nff::write_patches(&scene, r, &mut w),
        None => nff::write(&scene, &mut w),
    };
    match &args.output {
        Some(p) => write_file(p, |w| Ok(write(w)?)),
        None => {
            let stdout = std::io::stdout();
            let mut w = std::io::BufWriter::new(stdout.lock());
            // A closed pipe (`quiver gen ... | head`) is the reader's choice, not an error
            // (the rule for all stdout output, see `output`).
            match write(&mut w).and_then(|_| w.flush()) {
                Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => {
                    Err(format!("cannot write to stdout: {e}").into())
                }
                _ => Ok(()),
            }
        }
    }
}

/// Refuses, before writing, an NFF that cannot fit on the output's file system: its smallest
/// possible size (every number one character) against the space free there. A patch-mode
/// scene at a high resolution is small in memory, since it is written as it is tessellated,
/// but not on disk (`balls2 --patches --resolution 1000`: 1.09 billion triangles, over 40 GB).
fn check_disk(scene: &Scene, resolution: Option<u32>, path: &std::path::Path) -> Result<()> {
    let c = Census::of(scene);
    let c = resolution.map_or(c, |r| c.in_patch_mode(r));
    // "s 0 0 0 1", a cone on two lines, "p 3" and three "0 0 0" lines, "pp 3" and three
    // "0 0 0 0 0 0" lines, polygons' vertices "0 0 0": each with its newlines.
    let least = c.spheres * 10
        + c.cones * 20
        + c.triangles * 22
        + c.polygons * 4
        + c.polygon_vertices * 6
        + c.patches * 5
        + c.patch_vertices * 12;
    // A device or descriptor (`/dev/null`, `/dev/stdout`) is written in place, not stored.
    if std::fs::metadata(path).is_ok_and(|m| !m.is_file()) {
        return Ok(());
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => std::path::Path::new("."),
    };
    let Some(free) = free_bytes(dir) else {
        return Ok(());
    };
    if least > free {
        return Err(format!(
            "--output {}: the NFF takes at least {} [{least} bytes] ({} objects), more than the {} \
             free on its file system",
            path.display(),
            crate::budget::human(least),
            crate::budget::count(c.objects()),
            crate::budget::human(free)
        )
        .into());
    }
    Ok(())
}

/// Bytes an unprivileged process may still write on `dir`'s file system (`statvfs`), if known.
fn free_bytes(dir: &std::path::Path) -> Option<u64> {
    use std::os::unix::ffi::OsStrExt as _;
    let c = std::ffi::CString::new(dir.as_os_str().as_bytes()).ok()?;
    // SAFETY: all-zero is a valid `statvfs`; the call reads the NUL-terminated `c`, which
    // outlives it, and writes only to `s`.
    let mut s: libc::statvfs = unsafe { std::mem::zeroed() };
    if unsafe { libc::statvfs(c.as_ptr(), &mut s) } != 0 {
        return None;
    }
    Some(s.f_bavail as u64 * s.f_frsize as u64)
}

/// NFF numbers must be finite (quiver's reader refuses anything else), but a loader can
/// place a camera or light at infinity: an OBJ file without faces has empty bounds, and its
/// light lands at -inf. Writing that would make a file `quiver` itself cannot read back.
fn check_writable(scene: &Scene) -> Result<()> {
    let c = &scene.camera;
    let mut points = vec![
        ("camera position", c.from),
        ("camera target", c.at),
        ("camera up", c.up),
    ];
    points.extend(scene.lights.iter().map(|l| ("light position", l.pos)));
    for (what, p) in points {
        if !p.is_finite() {
            let why = if scene.objects.is_empty() {
                " (it has no primitives to place it by)"
            } else {
                ""
            };
            return Err(format!(
                "scene {} cannot be written as NFF: its {what} is not finite ({p}){why}",
                scene.name
            )
            .into());
        }
    }
    Ok(())
}
