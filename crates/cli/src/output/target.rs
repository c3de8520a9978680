//! Where an output may be written: the checks made on every output path before any work
//! ([`check_outputs`]) and again at write time ([`resolve`]).

use super::file::{sweep_stale, TempFile};
use crate::commands::Result;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

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
pub(super) struct FileId {
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
pub(super) static INPUTS: Mutex<Vec<(String, FileId)>> = Mutex::new(Vec::new());

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
pub(super) fn refuse_inputs(
    target: &Target,
    inputs: &[(String, FileId)],
) -> std::result::Result<(), String> {
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
pub(super) enum Target {
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
pub(super) fn resolve(given: &Path) -> std::result::Result<Target, String> {
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
pub(super) fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::file::tests::names;

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
