//! Files named by C strings: the paths `qv_*_save` write and `qv_*_load` read.

use crate::error::{non_null, Failure, QvStatus};
use quiver_rt::LoadError;
use std::ffi::{c_char, CStr};
use std::io;
use std::path::PathBuf;

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

/// Writes the file `path` (created or truncated) by `write`, then flushes it to the disk.
pub(crate) fn save(
    path: &PathBuf,
    write: impl FnOnce(&mut std::fs::File) -> io::Result<()>,
) -> Result<(), Failure> {
    let io = |e: io::Error| Failure::new(QvStatus::Io, format!("{}: {e}", path.display()));
    let mut file = std::fs::File::create(path).map_err(io)?;
    write(&mut file).map_err(io)?;
    file.sync_all().map_err(io)
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
