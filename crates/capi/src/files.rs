//! Files named by C strings: the paths `qv_*_save` write and `qv_*_load` read.

use crate::error::{non_null, Failure, QvStatus};
use quiver_rt::LoadError;
use std::ffi::{c_char, CStr};
use std::fs::File;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// The file path `path` names.
///
/// # Safety
/// `path` is NULL or a NUL-terminated string.
pub(crate) unsafe fn path_of(path: *const c_char) -> Result<PathBuf, Failure> {
    non_null(path, "path")?;
    // SAFETY: not NULL (checked), and NUL-terminated (the caller's contract).
    let bytes = unsafe { CStr::from_ptr(path) }.to_bytes();
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        Ok(PathBuf::from(std::ffi::OsStr::from_bytes(bytes)))
    }
    #[cfg(not(unix))]
    {
        std::str::from_utf8(bytes)
            .map(PathBuf::from)
            .map_err(|_| Failure::new(QvStatus::InvalidArgument, "path: not UTF-8"))
    }
}

/// Writes the file `path` by `write`, all or nothing: into a new temporary file beside it,
/// flushed to the disk, then renamed over `path` (atomic). A write that fails leaves `path` as
/// it was and no temporary file behind.
pub(crate) fn save(
    path: &Path,
    write: impl FnOnce(&mut File) -> io::Result<()>,
) -> Result<(), Failure> {
    let io = |e: io::Error| Failure::new(QvStatus::Io, format!("{}: {e}", path.display()));
    let name = path.file_name().ok_or_else(|| {
        Failure::new(
            QvStatus::InvalidArgument,
            format!("path: {} names no file", path.display()),
        )
    })?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    // A name no other writer shares: this process, a counter, and `create_new` refusing one
    // that exists.
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let mut tries = 0;
    let (temp, mut file) = loop {
        let mut temp_name = std::ffi::OsString::from(".");
        temp_name.push(name);
        temp_name.push(format!(
            ".{}.{}.partial",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        ));
        let temp = dir.join(temp_name);
        match File::options().write(true).create_new(true).open(&temp) {
            Ok(file) => break (temp, file),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists && tries < 1000 => tries += 1,
            Err(e) => return Err(io(e)),
        }
    };
    let written = write(&mut file)
        .and_then(|()| file.sync_all())
        .and_then(|()| std::fs::rename(&temp, path));
    if let Err(e) = written {
        drop(file);
        let _ = std::fs::remove_file(&temp);
        return Err(io(e));
    }
    Ok(())
}

/// The object `parse` reads from the whole file `path`: `QV_IO` when it cannot be read,
/// `QV_BAD_FILE` when its bytes are not what `parse` takes (the message says why).
pub(crate) fn load<T>(
    path: &PathBuf,
    parse: fn(&[u8]) -> Result<T, LoadError>,
) -> Result<T, Failure> {
    let shown = path.display();
    let bytes =
        std::fs::read(path).map_err(|e| Failure::new(QvStatus::Io, format!("{shown}: {e}")))?;
    parse(&bytes).map_err(|e| match e {
        LoadError::Io(e) => Failure::new(QvStatus::Io, format!("{shown}: {e}")),
        e => Failure::new(QvStatus::BadFile, format!("{shown}: {e}")),
    })
}
