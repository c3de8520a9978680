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

use crate::commands::Result;
use serde_json::Value;
use std::fs::File;
use std::io::{self, BufWriter, Write};
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

/// Checks, before any work, that each output file given as `(flag, path)` can be written by
/// the rule [`write_file`] follows, and records the scene files of `scenes` (generator names
/// are skipped) so that no output, now or at write time, replaces one of them. Fails, naming
/// the flag, the path and the reason, on a path that ends in `/`, a directory, a FIFO, a
/// socket, a block device, a loop of symbolic links, a file that is not writable, a missing
/// directory or one that takes no new files, the scene file itself (through any symbolic or
/// hard link), and two flags naming the same file (the second write would silently replace
/// the first). Stale temporaries of earlier runs that died writing the same file are removed.
pub(crate) fn check_outputs<S: AsRef<str>>(
    outputs: &[(&str, Option<&Path>)],
    scenes: &[S],
) -> Result<()> {
    let inputs = record_inputs(scenes);
    let mut seen: Vec<(&str, PathBuf)> = Vec::new();
    for &(flag, path) in outputs {
        let Some(path) = path else { continue };
        let shown = path.display();
        let fail = |why: String| format!("{flag} {shown}: {why}");
        let target = resolve(path).map_err(fail)?;
        refuse_inputs(&target, &inputs).map_err(fail)?;
        let Target::Replace { path: file, .. } = &target else {
            // A device or an open descriptor: written in place, so two flags may share it.
            continue;
        };
        let Some(name) = file.file_name() else {
            return Err(fail("not a file name".into()).into());
        };
        let dir = parent_dir(file);
        // Through a symbolic link, say where it led.
        let via = if file != path {
            format!("is a symbolic link to {}; ", file.display())
        } else {
            String::new()
        };
        match std::fs::metadata(dir) {
            Ok(m) if m.is_dir() => {}
            Ok(_) => return Err(fail(format!("{via}{} is not a directory", dir.display())).into()),
            Err(e) if e.kind() == io::ErrorKind::NotFound => {
                let dir = dir.display();
                return Err(fail(format!("{via}directory {dir} does not exist")).into());
            }
            Err(e) => return Err(fail(format!("{via}directory {}: {e}", dir.display())).into()),
        }
        sweep_stale(dir, name);
        // Creating (and removing) a temporary file is the one reliable test that the
        // directory takes new files: permission bits do not tell about read-only mounts,
        // ACLs or root.
        let probe = TempFile::create(dir, name)
            .map_err(|e| fail(format!("cannot create files in {}: {e}", dir.display())))?;
        drop(probe);
        let key = std::fs::canonicalize(dir).map_or_else(|_| file.clone(), |d| d.join(name));
        if let Some((other, _)) = seen.iter().find(|(_, k)| *k == key) {
            return Err(format!("{other} and {flag} both name {shown}").into());
        }
        seen.push((flag, key));
    }
    Ok(())
}

/// A file's identity: two paths name the same file exactly when these agree (symbolic links
/// followed, hard links alike).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
struct FileId {
    dev: u64,
    ino: u64,
}

impl FileId {
    fn of(m: &std::fs::Metadata) -> FileId {
        use std::os::unix::fs::MetadataExt as _;
        FileId {
            dev: m.dev(),
            ino: m.ino(),
        }
    }
}

/// The scene files this run reads, as `(argument, identity)`, recorded by [`check_outputs`]
/// for [`write_file`]'s second look.
static INPUTS: Mutex<Vec<(String, FileId)>> = Mutex::new(Vec::new());

/// Records the files among `scenes` (a generator name such as `tetra6` is no file, even if a
/// file of that name exists: the loader never reads it) and returns them.
fn record_inputs<S: AsRef<str>>(scenes: &[S]) -> Vec<(String, FileId)> {
    let found: Vec<(String, FileId)> = scenes
        .iter()
        .map(|s| s.as_ref())
        .filter(|s| !is_generator(s))
        .filter_map(|s| Some((s.to_string(), FileId::of(&std::fs::metadata(s).ok()?))))
        .collect();
    let mut inputs = INPUTS.lock().unwrap_or_else(|e| e.into_inner());
    inputs.extend(found.iter().cloned());
    inputs.clone()
}

/// Whether `spec` is a generator name with an optional size, as `Scene::load` reads it (then
/// it names no file).
fn is_generator(spec: &str) -> bool {
    let split = spec
        .find(|c: char| c.is_ascii_digit())
        .unwrap_or(spec.len());
    let (name, size) = spec.split_at(split);
    size.bytes().all(|b| b.is_ascii_digit())
        && quiver_scenes::scene::GENERATORS
            .iter()
            .any(|g| g.name == name)
}

/// Fails when `target` is one of `inputs` (see [`FileId`]).
fn refuse_inputs(target: &Target, inputs: &[(String, FileId)]) -> std::result::Result<(), String> {
    let id = match target {
        Target::Replace {
            existing: Some(m), ..
        } => FileId::of(m),
        Target::Direct { id, .. } => *id,
        Target::Replace { existing: None, .. } => return Ok(()),
    };
    match inputs.iter().find(|(_, i)| *i == id) {
        Some((spec, _)) => Err(format!(
            "is the scene file {spec} this command reads (the same file); an output never \
             replaces its input"
        )),
        None => Ok(()),
    }
}

/// Most symbolic links followed from an output path to its file (Linux's own limit).
const MAX_LINKS: usize = 40;

/// Where and how an output path is written; see [`resolve`].
enum Target {
    /// A regular file, or no file yet, at `path` (symbolic links followed): written to a
    /// temporary beside it and renamed over it.
    Replace {
        path: PathBuf,
        /// The file being replaced, if there is one.
        existing: Option<std::fs::Metadata>,
    },
    /// A character device (`/dev/null`, a terminal) or an open descriptor (`/dev/stdout`,
    /// `/dev/fd/N`, `/proc/self/fd/N`): written in place.
    Direct { path: PathBuf, id: FileId },
}

/// Follows `given`'s symbolic links to what a write would reach and decides how to write it
/// ([`Target`]), or says why it must not be written (the reason, to follow the path).
fn resolve(given: &Path) -> std::result::Result<Target, String> {
    use std::os::unix::fs::FileTypeExt as _;
    if names_directory(given) {
        return Err("names a directory (it ends in '/', '.' or '..'), not a file".into());
    }
    let mut path = given.to_path_buf();
    for _ in 0..=MAX_LINKS {
        let meta = match std::fs::symlink_metadata(&path) {
            Ok(m) => m,
            // Nothing there yet: a new file (its directory is checked by the caller, which
            // also names a file where a directory should be).
            Err(e)
                if e.kind() == io::ErrorKind::NotFound
                    || e.raw_os_error() == Some(libc::ENOTDIR) =>
            {
                return Ok(Target::Replace {
                    path,
                    existing: None,
                })
            }
            Err(e) => return Err(e.to_string()),
        };
        let kind = meta.file_type();
        if kind.is_symlink() {
            if is_descriptor_link(&path) {
                let m = std::fs::metadata(&path).map_err(|e| e.to_string())?;
                return Ok(Target::Direct {
                    id: FileId::of(&m),
                    path,
                });
            }
            let to = std::fs::read_link(&path).map_err(|e| e.to_string())?;
            // A relative link is relative to the directory holding it; `join` keeps an
            // absolute one as it is.
            path = match path.parent() {
                Some(dir) if !dir.as_os_str().is_empty() => dir.join(to),
                _ => to,
            };
            continue;
        }
        let what = if kind.is_file() {
            // A file the user may not write to is not one to replace behind their back.
            if !writable(&path) {
                "a file that is not writable"
            } else {
                return Ok(Target::Replace {
                    path,
                    existing: Some(meta),
                });
            }
        } else if kind.is_char_device() {
            return Ok(Target::Direct {
                id: FileId::of(&meta),
                path,
            });
        } else if kind.is_dir() {
            "a directory, not a file"
        } else if kind.is_fifo() {
            "a FIFO (named pipe), which quiver does not write to (a pipe works as stdout)"
        } else if kind.is_block_device() {
            "a block device"
        } else if kind.is_socket() {
            "a socket"
        } else {
            "not a regular file"
        };
        return Err(if path == given {
            format!("is {what}")
        } else {
            format!("is a symbolic link to {}, {what}", path.display())
        });
    }
    Err(format!(
        "has more than {MAX_LINKS} levels of symbolic links (a loop?)"
    ))
}

/// Whether `path` ends in a way that can only name a directory (`out/`, `x/.`, `..`). The
/// standard library's `Path` drops a trailing `/`, and a later rename onto it would fail.
fn names_directory(path: &Path) -> bool {
    use std::os::unix::ffi::OsStrExt as _;
    let b = path.as_os_str().as_bytes();
    b == b"." || b == b".." || b.ends_with(b"/") || b.ends_with(b"/.") || b.ends_with(b"/..")
}

/// Whether `path` is an entry of a process's descriptor table (`/proc/PID/fd/N`,
/// `/proc/PID/task/TID/fd/N`, and `/dev/fd/N`, a link to the former): a link to an open file,
/// pipe or terminal that is written as it is, never replaced.
fn is_descriptor_link(path: &Path) -> bool {
    let Ok(dir) = std::fs::canonicalize(parent_dir(path)) else {
        return false;
    };
    let parts: Vec<&std::ffi::OsStr> = dir.iter().collect();
    let number = |s: &std::ffi::OsStr| s.to_str().is_some_and(|s| s.parse::<u32>().is_ok());
    match parts.as_slice() {
        [root, proc, pid, fd] => *root == "/" && *proc == "proc" && number(pid) && *fd == "fd",
        [root, proc, pid, task, tid, fd] => {
            *root == "/"
                && *proc == "proc"
                && number(pid)
                && *task == "task"
                && number(tid)
                && *fd == "fd"
        }
        _ => false,
    }
}

/// Whether this process may write to the existing file `path` (`access(2)`, which accounts for
/// the effective user, ACLs and read-only mounts).
fn writable(path: &Path) -> bool {
    use std::os::unix::ffi::OsStrExt as _;
    let Ok(c) = std::ffi::CString::new(path.as_os_str().as_bytes()) else {
        return false;
    };
    // SAFETY: `c` is a valid NUL-terminated string that outlives the call; `access` only
    // reads it.
    unsafe { libc::access(c.as_ptr(), libc::W_OK) == 0 }
}

/// The directory a file path lives in (`.` for a bare file name).
fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// The most bytes a file name may have (Linux's `NAME_MAX`, most file systems' limit).
const NAME_MAX: usize = 255;

/// The longest `.quiver-PID-K.tmp` tail a temporary takes (both numbers at 10 digits).
const TEMP_TAIL: usize = ".quiver-4294967295-4294967295.tmp".len();

/// What a temporary for `name` starts with: `.NAME`, or for a name too long to take the
/// tail within [`NAME_MAX`], `.` and as much of it as fits with `~` and a 16-digit hash of
/// the whole name (FNV-1a, stable from run to run, so a later run sweeps it).
fn temp_stem(name: &std::ffi::OsStr) -> Vec<u8> {
    use std::os::unix::ffi::OsStrExt as _;
    let bytes = name.as_bytes();
    let mut stem = b".".to_vec();
    if 1 + bytes.len() + TEMP_TAIL <= NAME_MAX {
        stem.extend_from_slice(bytes);
        return stem;
    }
    let hash = bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
        (h ^ b as u64).wrapping_mul(0x100_0000_01b3)
    });
    let tail = format!("~{hash:016x}");
    stem.extend_from_slice(&bytes[..NAME_MAX - TEMP_TAIL - 1 - tail.len()]);
    stem.extend_from_slice(tail.as_bytes());
    stem
}

/// The temporary name for `name` that [`TempFile::create`] makes: `.NAME.quiver-PID-K.tmp`,
/// within 255 bytes however long `name` is ([`temp_stem`]).
fn temp_name(name: &std::ffi::OsStr, pid: u32, k: u32) -> std::ffi::OsString {
    use std::os::unix::ffi::OsStringExt as _;
    let mut temp = temp_stem(name);
    temp.extend_from_slice(format!(".quiver-{pid}-{k}.tmp").as_bytes());
    std::ffi::OsString::from_vec(temp)
}

/// Removes `dir`'s temporaries for `name` left by quiver runs that died without cleaning up
/// (a SIGKILL, a power cut): regular files named as [`temp_name`] makes them whose process no
/// longer exists. A live process's temporary is left alone (another run may be writing the
/// same file right now), and nothing else is touched. Errors are ignored: a stale temporary
/// costs disk space, not correctness.
fn sweep_stale(dir: &Path, name: &std::ffi::OsStr) {
    use std::os::unix::ffi::OsStrExt as _;
    let mut prefix = temp_stem(name);
    prefix.extend_from_slice(b".quiver-");
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let file = entry.file_name();
        let Some(rest) = file
            .as_bytes()
            .strip_prefix(prefix.as_slice())
            .and_then(|r| r.strip_suffix(b".tmp"))
        else {
            continue;
        };
        let Some((pid, k)) = std::str::from_utf8(rest)
            .ok()
            .and_then(|r| r.split_once('-'))
        else {
            continue;
        };
        let (Ok(pid), Ok(_)) = (pid.parse::<i32>(), k.parse::<u32>()) else {
            continue;
        };
        if pid <= 0 || pid as u32 == std::process::id() || process_exists(pid) {
            continue;
        }
        if entry.file_type().is_ok_and(|t| t.is_file()) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// Whether a process `pid` (> 0) exists: `kill(pid, 0)` sends nothing and fails with ESRCH
/// only when there is none (EPERM means it exists but is not ours).
fn process_exists(pid: i32) -> bool {
    // SAFETY: signal 0 is the null signal: `kill` only checks that `pid` could be signalled.
    // `pid` is positive, so it names one process, never a group or every process.
    let r = unsafe { libc::kill(pid, 0) };
    r == 0 || io::Error::last_os_error().raw_os_error() != Some(libc::ESRCH)
}

/// A temporary file beside its target, removed when dropped unless [`TempFile::persist`]
/// renamed it into place (so an error or a panic between the two leaves nothing behind), and
/// removed by a SIGINT, SIGTERM or SIGHUP too ([`crate::interrupt`]).
struct TempFile {
    path: PathBuf,
    file: Option<File>,
    /// Dropped after `path` is renamed or removed (fields drop after `Drop::drop`).
    _registered: crate::interrupt::Registered,
}

impl TempFile {
    /// Creates [`temp_name`] in `dir`, a name no other file, run or writer in this run shares
    /// (`create_new` refuses an existing one, and `K` counts up past it).
    fn create(dir: &Path, name: &std::ffi::OsStr) -> io::Result<TempFile> {
        let mut k = 0u32;
        loop {
            let path = dir.join(temp_name(name, std::process::id(), k));
            let registered = crate::interrupt::register(&path);
            match File::options().write(true).create_new(true).open(&path) {
                Ok(file) => {
                    return Ok(TempFile {
                        path,
                        file: Some(file),
                        _registered: registered,
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

/// Writes `path` by the output rule ([`check_outputs`] checked it before the work; it is
/// looked at again here, in case it changed meanwhile):
///
/// - a regular file, or none yet, is written all or nothing: `write` fills a temporary file in
///   the same directory, which replaces the file only when complete (keeping its permission
///   bits). On any error the file keeps its previous content (or stays absent) and no
///   temporary remains. A symbolic link is followed: the file it points to is replaced and
///   the link stays a link.
/// - a character device or an open descriptor (`/dev/null`, `/dev/stdout`) is written in place
///   (appending, never truncating).
/// - anything else, and the command's own scene file, is refused.
///
/// The error names `path`. Every file the CLI writes goes through here.
pub(crate) fn write_file(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<()>,
) -> Result<()> {
    let fail = |e: &dyn std::fmt::Display| format!("cannot write {}: {e}", path.display());
    let target = resolve(path).map_err(|why| fail(&why))?;
    let inputs = INPUTS.lock().unwrap_or_else(|e| e.into_inner()).clone();
    refuse_inputs(&target, &inputs).map_err(|why| fail(&why))?;
    match target {
        Target::Direct { path: device, .. } => {
            let file = File::options()
                .append(true)
                .open(&device)
                .map_err(|e| fail(&e))?;
            let mut w = BufWriter::new(file);
            write(&mut w).map_err(|e| fail(&e))?;
            w.flush().map_err(|e| fail(&e))?;
            Ok(())
        }
        Target::Replace {
            path: file,
            existing,
        } => {
            let name = file.file_name().ok_or_else(|| fail(&"not a file name"))?;
            let mut temp = TempFile::create(parent_dir(&file), name).map_err(|e| fail(&e))?;
            let out = temp
                .file
                .take()
                .ok_or_else(|| fail(&"temporary file closed"))?;
            if let Some(old) = &existing {
                out.set_permissions(old.permissions())
                    .map_err(|e| fail(&e))?;
            }
            let mut w = BufWriter::new(out);
            write(&mut w).map_err(|e| fail(&e))?;
            let out = w.into_inner().map_err(|e| fail(&e.into_error()))?;
            temp.file = Some(out);
            temp.persist(&file).map_err(|e| fail(&e))?;
            Ok(())
        }
    }
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
    let width = w as usize;
    write_png_rows(path, w, h, |y, row| {
        row.copy_from_slice(rgb[y * width..(y + 1) * width].as_flattened())
    })
}

/// Writes an 8-bit RGB image whose row `y` `fill(y, row)` writes into `row` (3 bytes a pixel),
/// streamed: the encoder holds a row and a chunk of compressed data, not the image (which
/// `write_image_data` would compress into memory whole).
fn write_png_rows(
    path: &Path,
    w: u32,
    h: u32,
    mut fill: impl FnMut(usize, &mut [u8]),
) -> Result<()> {
    write_file(path, |out| {
        let mut enc = png::Encoder::new(out, w, h);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut writer = enc.write_header()?;
        let mut stream = writer.stream_writer()?;
        let mut row = vec![0u8; 3 * w as usize];
        for y in 0..h as usize {
            fill(y, &mut row);
            stream.write_all(&row)?;
        }
        stream.finish()?;
        Ok(())
    })
}

/// Writes text (an SVG plot, an NFF scene) to `path`.
pub(crate) fn write_text(path: &Path, text: &str) -> Result<()> {
    write_file(path, |w| Ok(w.write_all(text.as_bytes())?))
}

/// Writes a false-colour picture of per-ray node counts, `width` a row: dark blue (few)
/// through green and yellow to red (the most, at the 99th percentile so a few outliers do not
/// wash out the image). Streamed row by row; the percentile comes from a histogram of the
/// counts, so nothing of the picture's size is held but the counts.
pub(crate) fn write_heatmap(path: &Path, counts: &[u32], width: usize) -> Result<()> {
    let top = percentile_99(counts).max(1) as f32;
    let height = counts.len() / width.max(1);
    write_png_rows(path, width as u32, height as u32, |y, row| {
        for (px, &c) in row
            .chunks_exact_mut(3)
            .zip(&counts[y * width..(y + 1) * width])
        {
            px.copy_from_slice(&heat(c as f32 / top));
        }
    })
}

/// The element at index `len * 99 / 100` of `counts` sorted (0 for none).
fn percentile_99(counts: &[u32]) -> u32 {
    let Some(&max) = counts.iter().max() else {
        return 0;
    };
    let rank = counts.len() * 99 / 100;
    if max as usize <= 1 << 22 {
        // A histogram: 4 bytes per distinct value up to the largest, not per count.
        let mut histogram = vec![0u32; max as usize + 1];
        for &c in counts {
            histogram[c as usize] += 1;
        }
        let mut seen = 0usize;
        for (value, &n) in histogram.iter().enumerate() {
            seen += n as usize;
            if seen > rank {
                return value as u32;
            }
        }
        max
    } else {
        let mut copy = counts.to_vec();
        *copy.select_nth_unstable(rank).1
    }
}

/// The heatmap's colour at `x` (0 few, 1 the 99th percentile and above).
fn heat(x: f32) -> [u8; 3] {
    let x = x.min(1.0);
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
/// (`1 + y`), labelled points. A point that cannot be placed (a NaN or infinite coordinate,
/// a negative y, a non-positive x on a log axis) is left out, named in a note under the title
/// and in a warning on stderr: no coordinate in the file is ever NaN or infinite, and an
/// infinite value cannot stretch the axes.
pub(crate) fn scatter_svg(
    title: &str,
    x_label: &str,
    y_label: &str,
    points: &[Point],
    axes: Axes<'_>,
) -> String {
    let placeable =
        |p: &Point| p.x.is_finite() && p.y.is_finite() && p.y >= 0.0 && (!axes.x_log || p.x > 0.0);
    let (points, left_out): (Vec<&Point>, Vec<&Point>) = points.iter().partition(|p| placeable(p));
    let (w, h, m) = (760.0, 480.0, 70.0);
    // Text goes into the SVG escaped: labels are scene names, which may be any file path.
    let (title_text, x_label, y_label) = (xml(title), xml(x_label), xml(y_label));
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
         <text x='{}' y='20' text-anchor='middle' font-size='14'>{title_text}</text>\n\
         <line x1='{m}' y1='{}' x2='{}' y2='{}' stroke='black'/><line x1='{m}' y1='{m}' x2='{m}' y2='{}' stroke='black'/>\n\
         <text x='{}' y='{}' text-anchor='middle'>{x_label}</text>\n\
         <text x='16' y='{}' transform='rotate(-90 16 {})' text-anchor='middle'>{y_label}</text>\n",
        w / 2.0, h - m, w - m, h - m, h - m, w / 2.0, h - 20.0, h / 2.0, h / 2.0
    );
    if !left_out.is_empty() {
        let shown: Vec<String> = left_out
            .iter()
            .map(|p| format!("{} ({}, {})", p.label, p.x, p.y))
            .collect();
        let note = format!(
            "{} point(s) left out, not placeable on these axes: {}",
            left_out.len(),
            shown.join(", ")
        );
        use std::io::Write as _;
        // A failed stderr has nowhere to be reported; the plot is still written.
        let _ = writeln!(io::stderr(), "warning: plot '{title}': {note}");
        s += &format!(
            "<text x='{}' y='36' text-anchor='middle' fill='firebrick'>{}</text>\n",
            w / 2.0,
            xml(&note)
        );
    }
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
            "<circle cx='{}' cy='{ly}' r='4' fill='{color}'/><text x='{}' y='{}'>{}</text>\n",
            w - m - 90.0,
            w - m - 82.0,
            ly + 4.0,
            xml(name)
        );
    }
    for (i, p) in points.iter().enumerate() {
        let (px, py) = (x(p.x), y(p.y));
        s += &format!(
            "<circle cx='{px:.1}' cy='{py:.1}' r='5' fill='{}' fill-opacity='0.7'/><text x='{:.1}' y='{:.1}'>{}</text>\n",
            p.color,
            px + 7.0,
            py - 4.0 + (i % 2) as f64 * 12.0,
            xml(&p.label)
        );
    }
    s + "</svg>\n"
}

/// `text` with XML's five special characters escaped, for SVG text and attributes.
fn xml(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '\'' => out.push_str("&apos;"),
            '"' => out.push_str("&quot;"),
            c => out.push(c),
        }
    }
    out
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

    /// No NaN or infinity reaches the SVG, whatever the points: an infinite y used to make
    /// the y axis loop to i32::MAX, a NaN x printed `NaN` coordinates.
    #[test]
    fn scatter_plot_leaves_out_points_it_cannot_place_and_says_so() {
        let p = |x: f64, y: f64, label: &str| Point {
            x,
            y,
            label: label.into(),
            color: "black",
        };
        let points = [
            p(1.0, 2.0, "fine"),
            p(f64::NAN, 1.0, "nan-x"),
            p(3.0, f64::INFINITY, "inf-y"),
            p(f64::NEG_INFINITY, 1.0, "neg-inf-x"),
            p(2.0, -5.0, "negative-y"),
            p(0.0, 1.0, "zero-x"),
            p(1.5, 1.0, "<a&b's>.obj"),
        ];
        for x_log in [false, true] {
            let axes = Axes { x_log, legend: &[] };
            let svg = scatter_svg("t", "x", "y", &points, axes);
            let numbers = svg
                .split(['\'', '>', '<', ' '])
                .filter(|t| t.parse::<f64>().is_ok());
            for t in numbers {
                assert!(t.parse::<f64>().unwrap().is_finite(), "{t} in {svg}");
            }
            assert!(!svg.contains("NaN") || svg.contains("nan-x (NaN"), "{svg}");
            assert!(svg.contains(">fine</text>"));
            // Labels are escaped: a scene path may hold any character.
            assert!(svg.contains(">&lt;a&amp;b&apos;s&gt;.obj</text>"), "{svg}");
            let left = if x_log { 5 } else { 4 };
            assert!(svg.contains(&format!("{left} point(s) left out")), "{svg}");
            assert!(svg.len() < 10_000, "{} bytes", svg.len());
            // Only the note shows the values that could not be placed.
            let circles = svg.matches("<circle").count();
            assert_eq!(circles, points.len() - left, "{svg}");
        }
    }

    /// The histogram percentile is the sorted array's element.
    #[test]
    fn percentile_is_the_sorted_element() {
        let mut seed = 5u64;
        for len in [0usize, 1, 2, 99, 100, 101, 1000, 4097] {
            for spread in [1u32, 7, 1000, u32::MAX] {
                let counts: Vec<u32> = (0..len)
                    .map(|_| {
                        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
                        ((seed >> 33) as u32) % spread.max(1)
                    })
                    .collect();
                let mut sorted = counts.clone();
                sorted.sort_unstable();
                let want = sorted.get(len * 99 / 100).copied().unwrap_or(0);
                assert_eq!(percentile_99(&counts), want, "{len} {spread}");
            }
        }
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
            let err = check_outputs(&[("--json", Some(path))], &[] as &[&str])
                .unwrap_err()
                .to_string();
            assert!(err.starts_with("--json ") && err.contains(want), "{err}");
        }
        let same = dir.path().join("a.png");
        let err = check_outputs(
            &[("--output", Some(&same)), ("--heatmap", Some(&same))],
            &[] as &[&str],
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("--output and --heatmap"), "{err}");
        check_outputs(&[("--json", Some(&file)), ("--plot", None)], &[] as &[&str]).unwrap();
        // The probe file is gone again.
        assert_eq!(names(dir.path()), ["f"]);
    }
}
