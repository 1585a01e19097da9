//! Reading the arguments C passes: pointers that may be null, strings that may not be
//! UTF-8, counts past the contract's capacity. Each refusal is an
//! [`AR_ERR_INVALID_ARGUMENT`](crate::status::AR_ERR_INVALID_ARGUMENT) whose message names
//! the function and the argument.

use crate::status::Failure;
use ipc_types::ChannelCounts;
use std::ffi::{CStr, c_char};
use std::time::Duration;

/// `function: argument: null pointer`.
pub fn null(function: &str, argument: &str) -> Failure {
    Failure::invalid(format!("{function}: {argument}: null pointer"))
}

/// The object `p` points to.
///
/// # Safety
/// `p` is null or points to a valid `T` that lives, unchanged by others, for `'a`.
pub unsafe fn read<'a, T>(p: *const T, function: &str, argument: &str) -> Result<&'a T, Failure> {
    // SAFETY: the caller's contract: null or a valid T for 'a.
    unsafe { p.as_ref() }.ok_or_else(|| null(function, argument))
}

/// The object `p` points to, for writing.
///
/// # Safety
/// `p` is null or points to a valid `T` that nothing else accesses during `'a`.
pub unsafe fn write<'a, T>(
    p: *mut T,
    function: &str,
    argument: &str,
) -> Result<&'a mut T, Failure> {
    // SAFETY: the caller's contract: null or a valid, exclusive T for 'a.
    unsafe { p.as_mut() }.ok_or_else(|| null(function, argument))
}

/// The UTF-8 string `p` points to.
///
/// # Safety
/// `p` is null or points to a NUL-terminated string that lives for `'a`.
pub unsafe fn text<'a>(
    p: *const c_char,
    function: &str,
    argument: &str,
) -> Result<&'a str, Failure> {
    if p.is_null() {
        return Err(null(function, argument));
    }
    // SAFETY: not null, and NUL-terminated by the caller's contract.
    let c = unsafe { CStr::from_ptr(p) };
    c.to_str().map_err(|e| {
        Failure::invalid(format!(
            "{function}: {argument}: not valid UTF-8 ({e}): {}",
            c.to_string_lossy()
        ))
    })
}

/// `n` values at `p`; `p` may be null when `n` is 0.
///
/// # Safety
/// `p` is null or points to `n` initialized `f64`s that live, unchanged, for `'a`.
pub unsafe fn values<'a>(
    p: *const f64,
    n: usize,
    function: &str,
    argument: &str,
) -> Result<&'a [f64], Failure> {
    if n == 0 {
        return Ok(&[]);
    }
    if p.is_null() {
        return Err(Failure::invalid(format!(
            "{function}: {argument}: null pointer for {n} value(s)"
        )));
    }
    // SAFETY: not null, and n values by the caller's contract.
    Ok(unsafe { std::slice::from_raw_parts(p, n) })
}

/// Room for `n` values at `p`; `p` may be null when `n` is 0.
///
/// # Safety
/// `p` is null or points to `n` writable `f64`s that nothing else accesses during `'a`.
pub unsafe fn values_out<'a>(
    p: *mut f64,
    n: usize,
    function: &str,
    argument: &str,
) -> Result<&'a mut [f64], Failure> {
    if n == 0 {
        return Ok(&mut []);
    }
    if p.is_null() {
        return Err(Failure::invalid(format!(
            "{function}: {argument}: null pointer for {n} value(s)"
        )));
    }
    // SAFETY: not null, and room for n exclusive values by the caller's contract.
    Ok(unsafe { std::slice::from_raw_parts_mut(p, n) })
}

/// Counts within the contract's capacities.
pub fn counts(c: ChannelCounts, function: &str, argument: &str) -> Result<ChannelCounts, Failure> {
    ChannelCounts::new(
        c.n_y as usize,
        c.n_z as usize,
        c.n_r as usize,
        c.n_u as usize,
    )
    .map_err(|m| Failure::invalid(format!("{function}: {argument}: {m}")))
}

/// A time-out in seconds: finite and not negative.
pub fn seconds(s: f64, function: &str, argument: &str) -> Result<Duration, Failure> {
    Duration::try_from_secs_f64(s).map_err(|_| {
        Failure::invalid(format!(
            "{function}: {argument}: {s} is not a time-out in seconds (finite, not negative)"
        ))
    })
}

/// Room for `n` bytes at `p`, as `u8`s.
///
/// # Safety
/// `p` is null or points to `n` writable bytes that nothing else accesses during `'a`.
pub unsafe fn values_out_bytes<'a>(
    p: *mut c_char,
    n: usize,
    function: &str,
    argument: &str,
) -> Result<&'a mut [u8], Failure> {
    if p.is_null() {
        return Err(null(function, argument));
    }
    // SAFETY: not null, and n exclusive writable bytes by the caller's contract; c_char and
    // u8 have the same size and alignment.
    Ok(unsafe { std::slice::from_raw_parts_mut(p.cast::<u8>(), n) })
}
