//! The `quiver` command line: thin over the library. Every command prints a table on stdout
//! and, with `--json FILE`, writes the same facts under stable keys. One module per command
//! in `commands/`; everything written to stdout or files goes through `output`.
//!
//! Exit codes: 0 on success (also when the reader of stdout closes the pipe early, as
//! `quiver ... | head` does: the output just stops), 2 on any error, with one line
//! `error: ...` on stderr naming the flag, file or value at fault. Arguments and output paths
//! are checked before any work starts.

use clap::{Parser, Subcommand};
use commands::{accuracy, bench, build, builders, costs, gen, layouts, packets, predict, render};
use std::process::ExitCode;

mod budget;
mod commands;
mod interrupt;
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
    /// Scene files: drop primitives and lights with a NaN or infinite number (and say how many
    /// on stderr) instead of refusing the file.
    #[arg(long, global = true)]
    drop_non_finite: bool,
    /// Scene files: let a file name files outside its own folder (a glTF buffer URI with
    /// `..`, an absolute path or a symbolic link leading out). Off by default, so a scene
    /// from elsewhere cannot make quiver read the machine's other files.
    #[arg(long, global = true)]
    outside_files: bool,
    /// The most memory the run may use, e.g. 8G or 512M (default: the memory available when
    /// it starts). Work estimated to need more is refused before it starts, with the estimate.
    #[arg(long, global = true, value_parser = budget::parse_size, allow_hyphen_values = true)]
    max_memory: Option<u64>,
}

#[derive(Subcommand)]
enum Command {
    /// Build a BVH over a scene and report its size, SAH cost and build time.
    Build(build::BuildArgs),
    /// Every tree builder side by side: SAH cost, build and ray times, work per ray, areas.
    Builders(builders::BuildersArgs),
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
    /// Packet traversal against single rays of the same BVH: eye, shadow, mirror and incoherent
    /// Mrays/s.
    Packets(packets::PacketsArgs),
    /// Traversal work predicted from surface areas beside measurement; with --time, against
    /// time per ray.
    Predict(predict::PredictArgs),
    /// Build cost models (SAH, RTSAH, SRDH) side by side: SAH cost, work and time per eye,
    /// shadow and mirror ray.
    Costs(costs::CostsArgs),
}

fn main() -> ExitCode {
    output::guard_std_fds();
    interrupt::install();
    if let Err(e) = utf8_arguments() {
        return fail(&e);
    }
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => return clap_exit(&e),
    };
    commands::load_options(cli.drop_non_finite, cli.outside_files);
    // A misspelt QUIVER_ISA would otherwise be ignored and the run measured on other kernels
    // than the user asked for.
    if let Err(e) = quiver_rt::Isa::from_env() {
        return fail(&e.to_string());
    }
    budget::set_limit(cli.max_memory);
    let result = match cli.command {
        Command::Build(args) => build::run(args),
        Command::Builders(args) => builders::run(args),
        Command::Layouts(args) => layouts::run(args),
        Command::Gen(args) => gen::run(args),
        Command::Render(args) => render::run(args),
        Command::Accuracy(args) => accuracy::run(args),
        Command::Bench(args) => bench::run(args),
        Command::Packets(args) => packets::run(args),
        Command::Predict(args) => predict::run(args),
        Command::Costs(args) => costs::run(args),
    };
    // A failed stdout is reported even when the command failed too: both went wrong.
    let stdout = output::finish_stdout();
    match result.and(stdout) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => fail(&e.to_string()),
    }
}

/// Refuses an argument that is not UTF-8 (clap's own message names no argument), naming it
/// and the flag before it: scene names, paths and values are read as UTF-8.
fn utf8_arguments() -> Result<(), String> {
    let args: Vec<std::ffi::OsString> = std::env::args_os().collect();
    for (i, a) in args.iter().enumerate().skip(1) {
        if a.to_str().is_none() {
            let after = args[..i]
                .iter()
                .rev()
                .find_map(|p| p.to_str().filter(|p| p.starts_with('-')))
                .map_or(String::new(), |flag| format!(" (after {flag})"));
            return Err(format!(
                "argument {i}{after}, '{}', is not valid UTF-8: quiver reads scene names, \
                 paths and values as UTF-8 (rename the file)",
                a.to_string_lossy()
            ));
        }
    }
    Ok(())
}

/// Prints `error: message` and returns exit code 2. `eprintln!` would panic on a failed
/// stderr; there is nowhere left to report that, so it is ignored.
fn fail(message: &str) -> ExitCode {
    use std::io::Write as _;
    let _ = writeln!(std::io::stderr(), "error: {message}");
    ExitCode::from(2)
}

/// Prints clap's message (usage errors to stderr, `--help` and `--version` to stdout) and
/// exits as clap would, except that a failed stdout is an error (a closed pipe is not, as for
/// the commands' own output).
fn clap_exit(e: &clap::Error) -> ExitCode {
    match e.print() {
        // stderr itself failed: there is nowhere to report that.
        Err(_) if e.use_stderr() => ExitCode::from(2),
        Err(io) if io.kind() != std::io::ErrorKind::BrokenPipe => {
            fail(&format!("cannot write to stdout: {io}"))
        }
        _ => ExitCode::from(e.exit_code().clamp(0, 255) as u8),
    }
}
