//! Reading scene files: one bounded function every loader calls, so that each format refuses
//! devices, FIFOs and oversized files alike.

use super::SceneError;
use std::path::Path;

/// The largest scene file [`Scene::load`](super::Scene::load) reads by default, 1 GiB
/// ([`LoadOptions::max_file_bytes`](super::LoadOptions::max_file_bytes) changes it): more is a mistake (a device, a wrong path)
/// sooner than a scene, and reading it whole would cost memory before any check could run.
pub const MAX_FILE_BYTES: u64 = 1 << 30;

/// The bytes of the scene file `path`, at most `limit` of them: the one way the loaders read
/// a file, so every format has the same bound. Anything but a regular file (after symbolic
/// links) is refused without reading: a device such as `/dev/zero` never ends, and a FIFO may
/// never open. The size is checked from the file's metadata before reading and again while
/// reading (a file that grows meanwhile is cut off at the limit and refused).
///
/// ```
/// use quiver_scenes::scene::{read_bytes, MAX_FILE_BYTES};
/// let e = read_bytes("/dev/zero".as_ref(), MAX_FILE_BYTES).unwrap_err().to_string();
/// assert_eq!(e, "/dev/zero: is a character device, not a regular file");
/// let dir = std::env::temp_dir().join(format!("read_bytes_doc_{}", std::process::id()));
/// std::fs::write(&dir, "v 0 0 0\n").unwrap();
/// assert_eq!(read_bytes(&dir, 8).unwrap(), b"v 0 0 0\n");
/// let e = read_bytes(&dir, 7).unwrap_err().to_string();
/// assert!(e.ends_with("8 bytes, more than the 7 a scene file may have"), "{e}");
/// # std::fs::remove_file(&dir).unwrap();
/// ```
pub fn read_bytes(path: &Path, limit: u64) -> Result<Vec<u8>, SceneError> {
    use std::io::Read as _;
    let fail = |message: String| SceneError::File {
        path: path.into(),
        message,
    };
    let kind = |m: &std::fs::Metadata| -> Result<(), SceneError> {
        let t = m.file_type();
        if t.is_file() {
            return Ok(());
        }
        #[cfg(unix)]
        let special = {
            use std::os::unix::fs::FileTypeExt as _;
            if t.is_char_device() {
                "a character device"
            } else if t.is_block_device() {
                "a block device"
            } else if t.is_fifo() {
                "a FIFO (named pipe)"
            } else if t.is_socket() {
                "a socket"
            } else if t.is_dir() {
                "a directory"
            } else {
                "not a regular file"
            }
        };
        #[cfg(not(unix))]
        let special = if t.is_dir() {
            "a directory"
        } else {
            "not a regular file"
        };
        Err(fail(if special.starts_with("not") {
            format!("is {special}")
        } else {
            format!("is {special}, not a regular file")
        }))
    };
    let too_big = |n: u64| {
        fail(format!(
            "{n} bytes, more than the {limit} a scene file may have"
        ))
    };
    let meta = std::fs::metadata(path).map_err(|e| fail(format!("cannot read: {e}")))?;
    kind(&meta)?;
    if meta.len() > limit {
        return Err(too_big(meta.len()));
    }
    let file = std::fs::File::open(path).map_err(|e| fail(format!("cannot read: {e}")))?;
    // The file opened may not be the one looked at (replaced in between): look again.
    let meta = file
        .metadata()
        .map_err(|e| fail(format!("cannot read: {e}")))?;
    kind(&meta)?;
    let mut bytes = Vec::with_capacity(meta.len().min(limit) as usize);
    file.take(limit.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| fail(format!("cannot read: {e}")))?;
    if bytes.len() as u64 > limit {
        return Err(too_big(bytes.len() as u64));
    }
    Ok(bytes)
}

/// [`read_bytes`] as text. Invalid UTF-8 becomes U+FFFD, so it fails as a bad token on its own
/// line where it matters and passes in comments.
pub fn read_text(path: &Path, limit: u64) -> Result<String, SceneError> {
    let bytes = read_bytes(path, limit)?;
    Ok(String::from_utf8(bytes)
        .unwrap_or_else(|e| String::from_utf8_lossy(e.as_bytes()).into_owned()))
}
