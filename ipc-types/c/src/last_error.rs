//! The message of the calling thread's last failure, for [`ar_last_error`].
//!
//! Each thread has its own: a failure on one thread never overwrites the message another
//! thread is reading. A successful call leaves the message of the last failure in place.

use std::cell::RefCell;
use std::ffi::{CString, c_char};

thread_local! {
    static LAST: RefCell<CString> = RefCell::new(CString::default());
}

/// Records `message` as this thread's last failure (an interior NUL, which C cannot show,
/// becomes a space).
pub fn set(message: &str) {
    let text = CString::new(message.replace('\0', " ")).unwrap_or_default();
    LAST.with(|l| *l.borrow_mut() = text);
}

/// This thread's last failure message, as a Rust string (for the tests).
pub fn get() -> String {
    LAST.with(|l| l.borrow().to_string_lossy().into_owned())
}

/// The message of the calling thread's last failed call (`""` when none failed yet): the
/// text the Rust processes print for the same failure, e.g. a contract mismatch with one
/// line per difference. Never null. The pointer stays valid until the next `ar_` call on
/// the same thread; copy the text to keep it.
#[unsafe(no_mangle)]
pub extern "C" fn ar_last_error() -> *const c_char {
    // The CString lives in this thread's slot until the next failure replaces it; the
    // pointer is to its heap buffer, which does not move while the slot holds it.
    LAST.with(|l| l.borrow().as_ptr())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::ffi::CStr;

    #[test]
    fn the_message_is_per_thread_and_survives_interior_nuls() {
        set("main thread failure");
        std::thread::spawn(|| {
            assert_eq!(get(), "", "a new thread starts with no message");
            set("other\0thread");
            assert_eq!(get(), "other thread");
        })
        .join()
        .unwrap();
        // SAFETY: ar_last_error returns a valid NUL-terminated string owned by this thread.
        let text = unsafe { CStr::from_ptr(ar_last_error()) };
        assert_eq!(text.to_str().unwrap(), "main thread failure");
    }
}
