//! `quiver gen`: a scene written as NFF.

use super::{scene_help, Result};
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
    #[arg(long, default_value_t = tessellate::DEFAULT_RESOLUTION, value_parser = clap::value_parser!(u32).range(1..=1000))]
    resolution: u32,
    /// Output file (default: stdout).
    #[arg(short, long)]
    output: Option<PathBuf>,
}

/// Runs `quiver gen`.
pub(crate) fn run(args: GenArgs) -> Result<()> {
    let mut scene = Scene::load(&args.scene)?;
    if args.patches {
        scene = scene.into_patches(args.resolution);
    }
    match &args.output {
        Some(p) => {
            let file = std::fs::File::create(p)
                .map_err(|e| format!("cannot create {}: {e}", p.display()))?;
            let mut w = std::io::BufWriter::new(file);
            nff::write(&scene, &mut w).map_err(|e| format!("cannot write {}: {e}", p.display()))?;
            w.flush()
                .map_err(|e| format!("cannot write {}: {e}", p.display()))?;
        }
        None => {
            let stdout = std::io::stdout();
            let mut w = std::io::BufWriter::new(stdout.lock());
            // A closed pipe (`quiver gen ... | head`) is not an error worth a message.
            match nff::write(&scene, &mut w).and_then(|_| w.flush()) {
                Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {}
                other => other?,
            }
        }
    }
    Ok(())
}
