//! Everything the commands write: tables and lines on stdout, JSON reports, PNG images,
//! the node-count heatmap, and SVG scatter plots.
//!
//! Files are written all or nothing ([`write_file`]): into a temporary file beside the target,
//! renamed over it once complete, so a failed run never leaves a truncated file and never
//! spoils the previous one; an interrupted one (SIGINT, SIGTERM, SIGHUP) removes its temporary
//! before it dies ([`crate::interrupt`]), and the temporary a SIGKILL leaves is swept by the
//! next run that writes the same file. Output paths are checked before any work starts
//! ([`check_outputs`]), so a typo in a path costs no render time, and an output never replaces
//! the scene file it was made from, a directory, a FIFO or a device: `/dev/null`, terminals and
//! `/dev/stdout` are written in place.
//!
//! Stdout: the first failed write is remembered and later ones are skipped; `main` reports it
//! through [`finish_stdout`] with a non-zero exit. A closed pipe (`quiver ... | head`) is the
//! reader's choice to stop, not a failure: it ends the output quietly with exit code 0.
//!
//! One file per idea: `target` (which paths an output may take, checked before any work),
//! `file` (all-or-nothing writes through a temporary), `image` (PNG images and the node-count
//! heatmap), `plot` (SVG scatter plots); stdout, tables and JSON here.

mod file;
mod image;
mod plot;
mod target;

pub(crate) use file::write_file;
pub(crate) use image::{write_heatmap, write_png};
pub(crate) use plot::{scatter_svg, Axes, Point};
pub(crate) use target::check_outputs;

use crate::commands::Result;
use serde_json::Value;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// The first error writing to stdout. Later writes are skipped: a full disk would fail them
/// too, and a closed pipe has no reader left.
static STDOUT_ERROR: Mutex<Option<io::Error>> = Mutex::new(None);

/// Set when the run started with stdout closed (`quiver ... >&-`).
static STDOUT_CLOSED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Whether stdout was closed when the process started, looked at before Rust's runtime
/// puts `/dev/null` in a closed standard descriptor's place (it does so before `main`, which
/// then cannot tell `>&-` from `>/dev/null`): the loader runs `.init_array` entries first.
#[cfg(target_os = "linux")]
#[used]
#[link_section = ".init_array"]
static STDOUT_AT_START: extern "C" fn() = {
    extern "C" fn look() {
        // SAFETY: F_GETFD only asks whether descriptor 1 is open; it reads and changes
        // nothing, and needs nothing of Rust's runtime.
        if unsafe { libc::fcntl(1, libc::F_GETFD) } == -1 {
            STDOUT_CLOSED.store(true, std::sync::atomic::Ordering::Relaxed);
        }
    }
    look
};

/// Called first by `main`: a closed stdout or stderr (`>&-`) gets `/dev/null` in its place,
/// so that no file the run opens later takes descriptor 1 or 2 and receives the table or the
/// messages; a closed stdout is remembered, and the first write to it fails the run (Rust's
/// stdout would otherwise swallow the error, and the table would be lost with exit code 0).
pub(crate) fn guard_std_fds() {
    for fd in [1, 2] {
        // SAFETY: F_GETFD only asks whether `fd` is open; it reads and changes nothing.
        if unsafe { libc::fcntl(fd, libc::F_GETFD) } != -1 {
            continue;
        }
        if fd == 1 {
            STDOUT_CLOSED.store(true, std::sync::atomic::Ordering::Relaxed);
        }
        // SAFETY: the path is a NUL-terminated literal; open returns the lowest free
        // descriptor, which is `fd` (every lower one is open: checked in order).
        let null = unsafe { libc::open(c"/dev/null".as_ptr(), libc::O_RDWR) };
        if null != -1 && null != fd {
            // SAFETY: both descriptors are ours; dup2 makes `fd` a copy and `null` is closed.
            unsafe {
                libc::dup2(null, fd);
                libc::close(null);
            }
        }
    }
}

/// Writes formatted text to stdout, remembering the first failure for [`finish_stdout`].
pub(crate) fn emit(args: std::fmt::Arguments) {
    // A poisoned lock only means another thread panicked while printing; the slot is intact.
    let mut error = STDOUT_ERROR.lock().unwrap_or_else(|e| e.into_inner());
    if error.is_none() && STDOUT_CLOSED.load(std::sync::atomic::Ordering::Relaxed) {
        *error = Some(io::Error::other(
            "it was closed when the run started (file descriptor 1)",
        ));
    }
    if error.is_none() {
        if let Err(e) = io::stdout().write_fmt(args) {
            *error = Some(e);
        }
    }
}

/// Flushes stdout and turns the first write error into the command's error, except a closed
/// pipe, which ends the output quietly (see the module doc).
pub(crate) fn finish_stdout() -> Result<()> {
    let mut error = STDOUT_ERROR.lock().unwrap_or_else(|e| e.into_inner());
    if error.is_none() {
        if let Err(e) = io::stdout().flush() {
            *error = Some(e);
        }
    }
    match error.take() {
        Some(e) if e.kind() != io::ErrorKind::BrokenPipe => {
            Err(format!("cannot write to stdout: {e}").into())
        }
        _ => Ok(()),
    }
}

/// `println!` through [`emit`]: never panics when stdout is gone.
macro_rules! outln {
    () => {
        $crate::output::emit(format_args!("\n"))
    };
    ($($t:tt)*) => {
        $crate::output::emit(format_args!("{}\n", format_args!($($t)*)))
    };
}
pub(crate) use outln;

/// `print!` with the same rule as [`outln!`].
macro_rules! out {
    ($($t:tt)*) => {
        $crate::output::emit(format_args!($($t)*))
    };
}
pub(crate) use out;

/// A report as a two-column table: key, value (floats to three decimals).
pub(crate) fn print_table(report: &Value) {
    let Value::Object(map) = report else { return };
    let width = map.keys().map(|k| k.len()).max().unwrap_or(0);
    for (k, v) in map {
        let shown = match v {
            Value::String(s) => s.clone(),
            Value::Number(n) if n.is_f64() => format!("{:.3}", n.as_f64().unwrap_or(f64::NAN)),
            other => other.to_string(),
        };
        outln!("{k:<width$}  {shown}");
    }
}

/// Writes `report` as pretty JSON to `path`, if given.
pub(crate) fn write_json(path: Option<&PathBuf>, report: &Value) -> Result<()> {
    let Some(path) = path else { return Ok(()) };
    let text = serde_json::to_string_pretty(report)?;
    write_file(path, |w| Ok(w.write_all((text + "\n").as_bytes())?))
}

/// Writes text (an SVG plot, an NFF scene) to `path`.
pub(crate) fn write_text(path: &Path, text: &str) -> Result<()> {
    write_file(path, |w| Ok(w.write_all(text.as_bytes())?))
}
