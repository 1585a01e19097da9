//! The boundary of every call: no panic crosses into C, and a failure leaves its message
//! for [`ar_last_error`](crate::last_error::ar_last_error).

use crate::last_error;
use crate::status::{AR_ERR_PANIC, AR_OK, ArStatus, Failure};
use std::panic::{AssertUnwindSafe, catch_unwind};

#[cfg(test)]
thread_local! {
    /// Test hook: the next guarded call on this thread panics inside its body.
    static PANIC_NEXT: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Test hook: makes the next guarded call on this thread panic inside the boundary.
#[cfg(test)]
pub fn panic_in_next_call() {
    PANIC_NEXT.with(|p| p.set(true));
}

/// Runs the body of the function `function` inside `catch_unwind`: `Ok` gives [`AR_OK`], a
/// [`Failure`] its code (its message recorded for this thread), a panic [`AR_ERR_PANIC`]
/// with the panic's message.
///
/// The body is asserted unwind-safe: after a panic the handle it worked on may be
/// inconsistent, which the documentation of [`AR_ERR_PANIC`] tells the caller (only close
/// it).
pub fn call(function: &str, body: impl FnOnce() -> Result<(), Failure>) -> ArStatus {
    let outcome = catch_unwind(AssertUnwindSafe(|| {
        #[cfg(test)]
        if PANIC_NEXT.with(|p| p.replace(false)) {
            panic!("test hook: a panic inside {function}");
        }
        body()
    }));
    match outcome {
        Ok(Ok(())) => AR_OK,
        Ok(Err(f)) => {
            last_error::set(&f.message);
            f.status
        }
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "(no message)".to_string());
            last_error::set(&format!("{function}: internal panic caught: {what}"));
            AR_ERR_PANIC
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::status::AR_ERR_IO;

    #[test]
    fn a_panic_becomes_ar_err_panic_with_its_message() {
        let code = call("ar_test", || panic!("boom {}", 7));
        assert_eq!(code, AR_ERR_PANIC);
        assert_eq!(last_error::get(), "ar_test: internal panic caught: boom 7");
        assert_eq!(call("ar_test", || Ok(())), AR_OK);
        assert_eq!(
            call("ar_test", || Err(Failure::new(AR_ERR_IO, "disk"))),
            AR_ERR_IO
        );
        assert_eq!(last_error::get(), "disk");
    }
}
