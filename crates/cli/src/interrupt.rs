//! Interrupted runs leave no temporary file behind. [`crate::output::write_file`] registers
//! each temporary here before creating it; a SIGINT, SIGTERM or SIGHUP removes every
//! registered temporary and then ends the process by the same signal, so the shell still sees
//! "killed by SIGINT". A SIGKILL cannot be caught: the temporaries it leaves carry the dead
//! process's id in their name, and the next run writing the same file sweeps them
//! (`output::file::sweep_stale`).
//!
//! SIGXFSZ (a write past `ulimit -f`) is ignored instead, so such a write fails with an error
//! (`File too large`) that the normal error path reports and cleans up after.
//!
//! The handler may run at any instruction of any thread, so it touches only what is safe there:
//! a fixed table of atomic pointers to C strings, `unlink` and `raise` (both async-signal-safe
//! in POSIX). Registered strings are never freed, since a handler that loaded a pointer just
//! before it was deregistered may still be passing it to `unlink`: a run leaks one path per
//! file it writes, a few hundred bytes.

use std::ffi::{c_char, CString};
use std::path::Path;
use std::sync::atomic::{AtomicPtr, Ordering};

/// Most temporaries registered at once (the CLI writes one file at a time; its checks probe
/// one directory at a time).
const SLOTS: usize = 64;

/// Registered temporary paths; null for a free slot.
static TEMPS: [AtomicPtr<c_char>; SLOTS] = [const { AtomicPtr::new(std::ptr::null_mut()) }; SLOTS];

/// A temporary path the signal handler removes; dropping it deregisters the path (call that
/// once the file is renamed into place or removed).
pub(crate) struct Registered(Option<usize>);

/// Registers `path` for removal on SIGINT, SIGTERM and SIGHUP. Register before creating the
/// file: a signal between the two then finds nothing to remove, never a file it missed.
///
/// A path with an interior NUL byte cannot exist on Unix, and a full table (more than
/// [`SLOTS`] temporaries at once, which the CLI never has) leaves the path unregistered; both
/// return a registration that does nothing.
pub(crate) fn register(path: &Path) -> Registered {
    use std::os::unix::ffi::OsStrExt as _;
    let Ok(c) = CString::new(path.as_os_str().as_bytes()) else {
        return Registered(None);
    };
    let ptr = c.into_raw();
    for (i, slot) in TEMPS.iter().enumerate() {
        if slot
            .compare_exchange(
                std::ptr::null_mut(),
                ptr,
                Ordering::AcqRel,
                Ordering::Acquire,
            )
            .is_ok()
        {
            return Registered(Some(i));
        }
    }
    // SAFETY: `ptr` came from `CString::into_raw` above and was never published to the
    // table (every compare-exchange failed), so nothing else can hold it.
    drop(unsafe { CString::from_raw(ptr) });
    Registered(None)
}

impl Drop for Registered {
    fn drop(&mut self) {
        if let Some(i) = self.0 {
            // The string is leaked on purpose (see the module doc).
            TEMPS[i].store(std::ptr::null_mut(), Ordering::Release);
        }
    }
}

extern "C" fn on_signal(signal: libc::c_int) {
    for slot in &TEMPS {
        let p = slot.load(Ordering::Acquire);
        if !p.is_null() {
            // SAFETY: every non-null pointer in the table came from `CString::into_raw` and is
            // never freed (see `Registered::drop`), so it stays a valid NUL-terminated string
            // for the life of the process; `unlink` is async-signal-safe and its failure
            // (the file already renamed or removed) is harmless.
            unsafe {
                libc::unlink(p);
            }
        }
    }
    // SAFETY: `raise` is async-signal-safe. The handler was installed with SA_RESETHAND, so
    // the signal's action is the default again, and the signal stays blocked until this
    // handler returns: it is then delivered and ends the process as it would have without us.
    unsafe {
        libc::raise(signal);
    }
}

/// Installs the cleanup handler for SIGINT, SIGTERM and SIGHUP (each left alone if it was
/// ignored when the process started, as `nohup` and background jobs expect), and ignores
/// SIGXFSZ. Called once, first thing in `main`.
pub(crate) fn install() {
    for signal in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
        // SAFETY: `sigaction` is given valid pointers to zero-initialised `sigaction` structs
        // (all-zero is a valid value of the C struct: no handler, empty mask, no flags) that
        // live across the calls; the handler it installs is the `extern "C"` function above,
        // which only does async-signal-safe work.
        unsafe {
            let mut old: libc::sigaction = std::mem::zeroed();
            if libc::sigaction(signal, std::ptr::null(), &mut old) != 0
                || old.sa_sigaction == libc::SIG_IGN
            {
                continue;
            }
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
            action.sa_flags = libc::SA_RESETHAND;
            libc::sigemptyset(&mut action.sa_mask);
            libc::sigaction(signal, &action, std::ptr::null_mut());
        }
    }
    // SAFETY: setting a signal's disposition to SIG_IGN involves no handler code at all.
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
}
