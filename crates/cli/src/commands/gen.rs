//! `quiver gen`: a scene written as NFF.

use super::{scene_help, Result};
use crate::output::{check_outputs, write_file};
use quiver_scenes::scene::{nff, tessellate, Scene};
use std::io::Write;
use std::path::PathBuf;

#[derive(clap::Args)]
pub(crate) struct GenArgs {
    /// A generator name with optional size, or an .nff/.obj file.
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
    let mut scene = super::load_scene(&args.scene)?;
    if args.patches {
        scene = scene.into_patches(args.resolution);
    }
    check_writable(&scene)?;
    match &args.output {
        Some(p) => write_file(p, |w| Ok(nff::write(&scene, w)?)),
        None => {
            let stdout = std::io::stdout();
            let mut w = std::io::BufWriter::new(stdout.lock());
            // A closed pipe (`quiver gen ... | head`) is the reader's choice, not an error
            // (the rule for all stdout output, see `output`).
            match nff::write(&scene, &mut w).and_then(|_| w.flush()) {
                Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => {
                    Err(format!("cannot write to stdout: {e}").into())
                }
                _ => Ok(()),
            }
        }
    }
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
