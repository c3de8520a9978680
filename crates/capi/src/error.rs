//! Status codes, the thread's last error message, and [`guard`]: the one wrapper every
//! exported function's body runs in, so no panic unwinds into C.

use std::cell::{Cell, RefCell};
use std::ffi::c_char;
use std::fmt::Display;
use std::panic::{catch_unwind, AssertUnwindSafe};

/// What a call did: `QV_OK`, or why it did nothing (`qv_last_error` says more).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum QvStatus {
    /// Done.
    Ok = 0,
    /// A pointer argument that must not be NULL was NULL.
    NullPointer = 1,
    /// An argument out of range: a size that overflows, an unknown geometry or instance id,
    /// a transform that is not finite or not invertible, a refit of a loaded BVH.
    InvalidArgument = 2,
    /// A mesh that cannot be built or refit: a stride shorter than its element, an index
    /// past the vertices, a non-finite vertex, too many triangles.
    BadMesh = 3,
    /// Reading or writing a file failed.
    Io = 4,
    /// A file that is not a saved quiver BVH, or one damaged.
    BadFile = 5,
    /// quiver panicked: a bug. The message says where; the objects passed are unchanged or
    /// freed as the function documents.
    Panic = 6,
}

/// Why a call was refused: a status and a message naming what was wrong.
#[derive(Debug)]
pub(crate) struct Failure {
    pub status: QvStatus,
    pub message: String,
}

impl Failure {
    /// A failure with `status`, saying `message`. Cold and out of line, as is [`report`]:
    /// kept out of the exported functions' bodies, the refusals leave the path of a call that
    /// succeeds a few instructions and registers (a single-ray query is tens of nanoseconds).
    #[cold]
    #[inline(never)]
    pub fn new(status: QvStatus, message: impl Display) -> Failure {
        Failure {
            status,
            message: message.to_string(),
        }
    }

    /// A NULL argument `name`.
    #[cold]
    #[inline(never)]
    pub fn null(name: &str) -> Failure {
        Failure::new(QvStatus::NullPointer, format!("{name} is NULL"))
    }
}

/// Refuses a NULL `p`, naming the argument.
pub(crate) fn non_null<T>(p: *const T, name: &str) -> Result<(), Failure> {
    match p.is_null() {
        true => Err(Failure::null(name)),
        false => Ok(()),
    }
}

/// Frees handle `h` (a `Box<T>` turned into a raw pointer) as `name`; NULL is ignored.
///
/// # Safety
/// `h` is NULL or a live handle no other thread uses, not used again.
pub(crate) unsafe fn free_handle<T>(name: &str, h: *mut T) {
    guard(name, || {
        if !h.is_null() {
            // SAFETY: a live handle is a `Box<T>` from `Box::into_raw`, given back once and
            // used by no other thread (the caller's contract).
            drop(unsafe { Box::from_raw(h) });
        }
        Ok(())
    });
}

thread_local! {
    /// The message `qv_last_error` returns, NUL-terminated (empty: no message): replaced by
    /// every exported call on this thread. A byte buffer reused in place, so the calls that
    /// succeed (clearing it) allocate nothing: a single-ray query is a few dozen nanoseconds,
    /// and an allocation per call would be a sizeable part of it.
    static LAST_ERROR: RefCell<Vec<u8>> = const { RefCell::new(Vec::new()) };

    /// Whether `LAST_ERROR` holds a message. Apart from it because it needs no destructor:
    /// the check every successful call makes is one load, where the buffer's own
    /// thread-local would first check that its destructor is registered.
    static HAS_ERROR: Cell<bool> = const { Cell::new(false) };
}

/// Records `message` as the thread's last error (NUL bytes, which C cannot hold inside a
/// string, become spaces).
fn set_last_error(message: &str) {
    LAST_ERROR.with(|e| {
        let mut e = e.borrow_mut();
        e.clear();
        e.extend(message.bytes().map(|b| if b == 0 { b' ' } else { b }));
        e.push(0);
    });
    HAS_ERROR.set(true);
}

/// Clears the thread's last error (one load when it is clear already).
#[inline]
fn clear_last_error() {
    if HAS_ERROR.get() {
        LAST_ERROR.with(|e| {
            let mut e = e.borrow_mut();
            e.clear();
            e.push(0);
        });
        HAS_ERROR.set(false);
    }
}

/// Runs `f`, returning `fallback` if it panics. Every exported function's body runs inside
/// this, directly or through [`guard`]: a panic unwinding into C is undefined behaviour.
#[inline(always)]
pub(crate) fn catch<T>(fallback: T, f: impl FnOnce() -> T) -> T {
    // Unwind safety: after a panic nothing `f` touched is used by this function, and the
    // objects a caller passed are documented as unchanged or freed (their Rust types keep
    // their invariants across a panic: no unsafe code of ours runs half done).
    catch_unwind(AssertUnwindSafe(f)).unwrap_or_else(|payload| {
        set_last_error(&format!("quiver panicked: {}", panic_message(&*payload)));
        fallback
    })
}

/// The message a panic was raised with, where it is a string.
fn panic_message(payload: &(dyn std::any::Any + Send)) -> &str {
    if let Some(s) = payload.downcast_ref::<&str>() {
        s
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s
    } else {
        "(no message)"
    }
}

/// Runs exported function `name`'s body `f`: clears the last error, then maps `f`'s refusal
/// to its status (recording the message, prefixed by `name`) and a panic to
/// [`QvStatus::Panic`].
#[inline(always)]
pub(crate) fn guard(name: &str, f: impl FnOnce() -> Result<(), Failure>) -> QvStatus {
    clear_last_error();
    catch(QvStatus::Panic, || match f() {
        Ok(()) => QvStatus::Ok,
        Err(failure) => report(name, failure),
    })
}

/// Records `failure` of exported function `name` as the thread's last error; its status.
#[cold]
#[inline(never)]
fn report(name: &str, failure: Failure) -> QvStatus {
    set_last_error(&format!("{name}: {}", failure.message));
    failure.status
}

/// The message of the last refused call on this thread (naming the argument, vertex,
/// triangle or instance at fault), or `""` after a call that succeeded. The pointer stays
/// valid until the next `qv_` call on this thread; it is never NULL.
#[no_mangle]
pub extern "C" fn qv_last_error() -> *const c_char {
    // Not through `guard`: reading the message must not clear it.
    catch(c"quiver: qv_last_error panicked".as_ptr(), || {
        // The buffer lives in the thread-local and is only written by the next call, as the
        // contract says; until then its bytes (NUL-terminated) stay where they are. Never
        // written yet: the empty message.
        LAST_ERROR.with(|e| match e.borrow().as_slice() {
            [] => c"".as_ptr(),
            bytes => bytes.as_ptr().cast(),
        })
    })
}

/// The thread's last error message, for this crate's tests.
#[cfg(test)]
pub(crate) fn last_error() -> String {
    LAST_ERROR.with(|e| {
        let e = e.borrow();
        String::from_utf8_lossy(e.strip_suffix(&[0]).unwrap_or(&e)).into_owned()
    })
}
