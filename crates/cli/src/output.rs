//! Everything the commands write: tables and lines on stdout, JSON reports, PNG images,
//! the node-count heatmap, and SVG scatter plots.
//!
//! Files are written all or nothing ([`write_file`]): into a temporary file beside the target,
//! renamed over it once complete, so an interrupted or failed run never leaves a truncated
//! file and never spoils the previous one. Output paths are checked before any work starts
//! ([`check_outputs`]), so a typo in a path costs no render time.
//!
//! Stdout: the first failed write is remembered and later ones are skipped; `main` reports it
//! through [`finish_stdout`] with a non-zero exit. A closed pipe (`quiver ... | head`) is the
//! reader's choice to stop, not a failure: it ends the output quietly with exit code 0.

use crate::commands::Result;
use serde_json::Value;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// The first error writing to stdout. Later writes are skipped: a full disk would fail them
/// too, and a closed pipe has no reader left.
static STDOUT_ERROR: Mutex<Option<io::Error>> = Mutex::new(None);

/// Writes formatted text to stdout, remembering the first failure for [`finish_stdout`].
pub(crate) fn emit(args: std::fmt::Arguments) {
    // A poisoned lock only means another thread panicked while printing; the slot is intact.
    let mut error = STDOUT_ERROR.lock().unwrap_or_else(|e| e.into_inner());
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

/// Checks, before any work, that each output file given as `(flag, path)` can be written:
/// the path names a file (not a directory), its directory exists and takes new files, and no
/// two flags name the same file (the second write would silently replace the first).
pub(crate) fn check_outputs(outputs: &[(&str, Option<&Path>)]) -> Result<()> {
    let mut seen: Vec<(&str, PathBuf)> = Vec::new();
    for &(flag, path) in outputs {
        let Some(path) = path else { continue };
        let shown = path.display();
        let Some(name) = path.file_name() else {
            return Err(format!("{flag} {shown}: not a file name").into());
        };
        if path.is_dir() {
            return Err(format!("{flag} {shown}: is a directory, not a file").into());
        }
        let dir = parent_dir(path);
        match std::fs::metadata(dir) {
            Ok(m) if m.is_dir() => {}
            Ok(_) => {
                return Err(format!("{flag} {shown}: {} is not a directory", dir.display()).into())
            }
            Err(e) if e.kind() == io::ErrorKind::NotFound => {
                let dir = dir.display();
                return Err(format!("{flag} {shown}: directory {dir} does not exist").into());
            }
            Err(e) => {
                return Err(format!("{flag} {shown}: directory {}: {e}", dir.display()).into())
            }
        }
        // Creating (and removing) a temporary file is the one reliable test that the
        // directory takes new files: permission bits do not tell about read-only mounts,
        // ACLs or root.
        let probe = TempFile::create(dir, name).map_err(|e| {
            format!(
                "{flag} {shown}: cannot create files in {}: {e}",
                dir.display()
            )
        })?;
        drop(probe);
        let key = std::fs::canonicalize(dir).map_or_else(|_| path.to_path_buf(), |d| d.join(name));
        if let Some((other, _)) = seen.iter().find(|(_, k)| *k == key) {
            return Err(format!("{other} and {flag} both name {shown}").into());
        }
        seen.push((flag, key));
    }
    Ok(())
}

/// The directory a file path lives in (`.` for a bare file name).
fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// A temporary file beside its target, removed when dropped unless [`TempFile::persist`]
/// renamed it into place (so an error or a panic between the two leaves nothing behind).
struct TempFile {
    path: PathBuf,
    file: Option<File>,
}

impl TempFile {
    /// Creates `.NAME.PID-K.tmp` in `dir`, a name no other file, run or writer in this run
    /// shares (`create_new` refuses an existing one, and `K` counts up past it).
    fn create(dir: &Path, name: &std::ffi::OsStr) -> io::Result<TempFile> {
        let mut k = 0u32;
        loop {
            let mut temp = std::ffi::OsString::from(".");
            temp.push(name);
            temp.push(format!(".{}-{k}.tmp", std::process::id()));
            let path = dir.join(temp);
            match File::options().write(true).create_new(true).open(&path) {
                Ok(file) => {
                    return Ok(TempFile {
                        path,
                        file: Some(file),
                    })
                }
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists && k < 1000 => k += 1,
                Err(e) => return Err(e),
            }
        }
    }

    /// Syncs the data to disk and renames the file to `target`: the rename is atomic, and
    /// the sync keeps a crash right after it from exposing an empty file under `target`.
    fn persist(mut self, target: &Path) -> io::Result<()> {
        if let Some(file) = self.file.take() {
            file.sync_all()?;
        }
        std::fs::rename(&self.path, target)?;
        self.path = PathBuf::new();
        Ok(())
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        self.file = None;
        if !self.path.as_os_str().is_empty() {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

/// Writes `path` all or nothing: `write` fills a temporary file in the same directory, which
/// replaces `path` only when complete. On any error `path` keeps its previous content (or stays
/// absent) and no temporary file remains; the error names `path`. Every file the CLI writes
/// goes through here.
///
/// A replaced file gets a new inode: a symbolic link at `path` is replaced by a plain file,
/// and the old file's permissions are not carried over.
pub(crate) fn write_file(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<()>,
) -> Result<()> {
    let fail = |e: &dyn std::fmt::Display| format!("cannot write {}: {e}", path.display());
    let name = path.file_name().ok_or_else(|| fail(&"not a file name"))?;
    let mut temp = TempFile::create(parent_dir(path), name).map_err(|e| fail(&e))?;
    let file = temp
        .file
        .take()
        .ok_or_else(|| fail(&"temporary file closed"))?;
    let mut w = BufWriter::new(file);
    write(&mut w).map_err(|e| fail(&e))?;
    let file = w.into_inner().map_err(|e| fail(&e.into_error()))?;
    temp.file = Some(file);
    temp.persist(path).map_err(|e| fail(&e))?;
    Ok(())
}

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

/// Writes an 8-bit RGB image.
pub(crate) fn write_png(path: &Path, w: u32, h: u32, rgb: &[[u8; 3]]) -> Result<()> {
    write_file(path, |out| {
        let mut enc = png::Encoder::new(out, w, h);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut writer = enc.write_header()?;
        writer.write_image_data(rgb.as_flattened())?;
        writer.finish()?;
        Ok(())
    })
}

/// Writes text (an SVG plot, an NFF scene) to `path`.
pub(crate) fn write_text(path: &Path, text: &str) -> Result<()> {
    write_file(path, |w| Ok(w.write_all(text.as_bytes())?))
}

/// A false-colour picture of per-ray node counts: dark blue (few) through green and yellow to
/// red (the most, at the 99th percentile so a few outliers do not wash out the image).
pub(crate) fn heatmap(counts: &[u32], width: usize) -> (usize, Vec<[u8; 3]>) {
    let mut sorted = counts.to_vec();
    sorted.sort_unstable();
    let top = sorted
        .get(sorted.len() * 99 / 100)
        .copied()
        .unwrap_or(1)
        .max(1) as f32;
    let px = counts
        .iter()
        .map(|&c| {
            let x = (c as f32 / top).min(1.0);
            let ramp = [
                (0.0, [0.0, 0.0, 0.3]),
                (0.33, [0.0, 0.6, 1.0]),
                (0.66, [1.0, 1.0, 0.0]),
                (1.0, [1.0, 0.0, 0.0]),
            ];
            let k = ramp.windows(2).position(|w| x <= w[1].0).unwrap_or(2);
            let (a, b) = (ramp[k], ramp[k + 1]);
            let f = (x - a.0) / (b.0 - a.0);
            let ch = |i: usize| ((a.1[i] + (b.1[i] - a.1[i]) * f) * 255.0 + 0.5) as u8;
            [ch(0), ch(1), ch(2)]
        })
        .collect();
    (width, px)
}

/// One point of a [`scatter_svg`] plot.
pub(crate) struct Point {
    pub x: f64,
    /// Plotted on a log scale as `log10(1 + y)`, so zero is at the bottom.
    pub y: f64,
    pub label: String,
    /// An SVG colour.
    pub color: &'static str,
}

/// How a [`scatter_svg`] plot scales its x axis.
#[derive(Clone, Copy)]
pub(crate) struct Axes<'a> {
    /// Logarithmic x over the decades the points span (positive x only) instead of linear
    /// from 0: for quantities spanning several orders of magnitude, such as build times.
    pub x_log: bool,
    /// Colour key drawn at the top right: (name, SVG colour); empty for none.
    pub legend: &'a [(&'a str, &'a str)],
}

/// A scatter plot as SVG: linear x from 0 (or logarithmic, see [`Axes`]), logarithmic y
/// (`1 + y`), labelled points.
pub(crate) fn scatter_svg(
    title: &str,
    x_label: &str,
    y_label: &str,
    points: &[Point],
    axes: Axes<'_>,
) -> String {
    let (w, h, m) = (760.0, 480.0, 70.0);
    let xmax = points.iter().map(|p| p.x).fold(0.0f64, f64::max).max(1e-12) * 1.1;
    let ymax = points
        .iter()
        .map(|p| p.y)
        .fold(10.0f64, f64::max)
        .log10()
        .ceil();
    // Decades for a log x axis: from the smallest positive x's to the largest's.
    let lo = points
        .iter()
        .map(|p| p.x)
        .filter(|&x| x > 0.0)
        .fold(f64::INFINITY, f64::min)
        .min(xmax)
        .log10()
        .floor();
    let hi = xmax.log10().ceil().max(lo + 1.0);
    let x = |v: f64| {
        let f = if axes.x_log {
            (v.max(1e-300).log10() - lo) / (hi - lo)
        } else {
            v / xmax
        };
        m + f * (w - 2.0 * m)
    };
    let y = |v: f64| h - m - (1.0 + v).log10() / ymax * (h - 2.0 * m);
    let mut s = format!(
        "<svg xmlns='http://www.w3.org/2000/svg' width='{w}' height='{h}' font-family='sans-serif' font-size='11'>\n\
         <rect width='100%' height='100%' fill='white'/>\n\
         <text x='{}' y='20' text-anchor='middle' font-size='14'>{title}</text>\n\
         <line x1='{m}' y1='{}' x2='{}' y2='{}' stroke='black'/><line x1='{m}' y1='{m}' x2='{m}' y2='{}' stroke='black'/>\n\
         <text x='{}' y='{}' text-anchor='middle'>{x_label}</text>\n\
         <text x='16' y='{}' transform='rotate(-90 16 {})' text-anchor='middle'>{y_label}</text>\n",
        w / 2.0, h - m, w - m, h - m, h - m, w / 2.0, h - 20.0, h / 2.0, h / 2.0
    );
    for k in 0..=ymax as i32 {
        let v = 10f64.powi(k) - 1.0;
        s += &format!(
            "<text x='{}' y='{}' text-anchor='end'>{}</text>\n",
            m - 6.0,
            y(v) + 4.0,
            10f64.powi(k) as u64 - 1
        );
    }
    let ticks: Vec<f64> = if axes.x_log {
        (lo as i32..=hi as i32).map(|k| 10f64.powi(k)).collect()
    } else {
        (0..=4).map(|k| xmax * k as f64 / 4.0).collect()
    };
    for v in ticks {
        // Log ticks are powers of ten (0.01 … 1000); linear ones whole numbers.
        let text = if axes.x_log {
            format!("{v}")
        } else {
            format!("{v:.0}")
        };
        s += &format!(
            "<text x='{}' y='{}' text-anchor='middle'>{text}</text>\n",
            x(v),
            h - m + 16.0
        );
    }
    for (i, (name, color)) in axes.legend.iter().enumerate() {
        let ly = m + 12.0 * i as f64;
        s += &format!(
            "<circle cx='{}' cy='{ly}' r='4' fill='{color}'/><text x='{}' y='{}'>{name}</text>\n",
            w - m - 90.0,
            w - m - 82.0,
            ly + 4.0
        );
    }
    for (i, p) in points.iter().enumerate() {
        let (px, py) = (x(p.x), y(p.y));
        s += &format!(
            "<circle cx='{px:.1}' cy='{py:.1}' r='5' fill='{}' fill-opacity='0.7'/><text x='{:.1}' y='{:.1}'>{}</text>\n",
            p.color,
            px + 7.0,
            py - 4.0 + (i % 2) as f64 * 12.0,
            p.label
        );
    }
    s + "</svg>\n"
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The names in `dir`, sorted.
    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn write_file_writes_whole_file_and_leaves_no_temp() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.json");
        std::fs::write(&path, "old").unwrap();
        write_file(&path, |w| Ok(w.write_all(b"new content")?)).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "new content");
        assert_eq!(names(dir.path()), ["out.json"]);
    }

    #[test]
    fn failed_write_keeps_previous_file_and_leaves_no_temp() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("image.png");
        std::fs::write(&path, "previous").unwrap();
        let err = write_file(&path, |w| {
            w.write_all(&[7; 100_000])?;
            Err("encoder gave up".into())
        })
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("image.png") && err.contains("encoder gave up"),
            "{err}"
        );
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "previous");
        assert_eq!(names(dir.path()), ["image.png"]);
    }

    #[test]
    fn failed_first_write_creates_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("plot.svg");
        assert!(write_file(&path, |_| Err("no".into())).is_err());
        assert!(names(dir.path()).is_empty());
    }

    #[test]
    fn check_outputs_names_flag_and_problem() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("f");
        std::fs::write(&file, "").unwrap();
        let missing = dir.path().join("missing/x.json");
        let under_file = file.join("x.json");
        let cases: [(&Path, &str); 3] = [
            (&missing, "does not exist"),
            (&under_file, "is not a directory"),
            (dir.path(), "is a directory"),
        ];
        for (path, want) in cases {
            let err = check_outputs(&[("--json", Some(path))])
                .unwrap_err()
                .to_string();
            assert!(err.starts_with("--json ") && err.contains(want), "{err}");
        }
        let same = dir.path().join("a.png");
        let err = check_outputs(&[("--output", Some(&same)), ("--heatmap", Some(&same))])
            .unwrap_err()
            .to_string();
        assert!(err.contains("--output and --heatmap"), "{err}");
        check_outputs(&[("--json", Some(&file)), ("--plot", None)]).unwrap();
        // The probe file is gone again.
        assert_eq!(names(dir.path()), ["f"]);
    }
}
