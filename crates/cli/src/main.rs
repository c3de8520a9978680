//! The `quiver` command line: thin over the library. Every command prints a table on stdout
//! and, with `--json FILE`, writes the same facts under stable keys. One module per command
//! in `commands/`; everything written to stdout or files goes through `output`.

use clap::{Parser, Subcommand};
use commands::{accuracy, bench, build, gen, layouts, packets, render};
use std::process::ExitCode;

mod commands;
mod output;

#[derive(Parser)]
#[command(
    name = "quiver",
    version,
    about = "Parallel SAH BVHs and ray shooting on CPUs"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Build a BVH over a scene and report its size, SAH cost and build time.
    Build(build::BuildArgs),
    /// Measure traversal throughput of every memory layout on several scenes.
    Layouts(layouts::LayoutsArgs),
    /// Write a scene as NFF (to stdout, or to a file with -o).
    Gen(gen::GenArgs),
    /// Render a scene by the SPD testing procedure to a PNG and report the rays it traced.
    Render(render::RenderArgs),
    /// Measure what accuracy costs: intersector x box test x offset, in time and errors.
    Accuracy(accuracy::AccuracyArgs),
    /// quiver and obvhs side by side: builds, SAH cost, eye/shadow/incoherent Mrays/s.
    Bench(bench::BenchArgs),
    /// Packet traversal against BVH4 single rays: eye, shadow and incoherent Mrays/s.
    Packets(packets::PacketsArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Build(args) => build::run(args),
        Command::Layouts(args) => layouts::run(args),
        Command::Gen(args) => gen::run(args),
        Command::Render(args) => render::run(args),
        Command::Accuracy(args) => accuracy::run(args),
        Command::Bench(args) => bench::run(args),
        Command::Packets(args) => packets::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}
