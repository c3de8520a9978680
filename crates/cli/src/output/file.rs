//! All-or-nothing writes: a temporary file beside the target, renamed over it once complete
//! ([`write_file`]), and the sweep of temporaries a killed run left ([`sweep_stale`]).

use super::target::{parent_dir, refuse_inputs, resolve, Target, INPUTS};
use crate::commands::Result;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

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
pub(super) fn sweep_stale(dir: &Path, name: &std::ffi::OsStr) {
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
pub(super) struct TempFile {
    path: PathBuf,
    file: Option<File>,
    /// Dropped after `path` is renamed or removed (fields drop after `Drop::drop`).
    _registered: crate::interrupt::Registered,
}

impl TempFile {
    /// Creates [`temp_name`] in `dir`, a name no other file, run or writer in this run shares
    /// (`create_new` refuses an existing one, and `K` counts up past it).
    pub(super) fn create(dir: &Path, name: &std::ffi::OsStr) -> io::Result<TempFile> {
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

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// The names in `dir`, sorted.
    pub(crate) fn names(dir: &Path) -> Vec<String> {
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
}
