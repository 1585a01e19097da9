//! The contract's time base for C: `CLOCK_MONOTONIC` in nanoseconds, the clock of every
//! timestamp and of the waits of `ar_plant_take`.

/// The current `CLOCK_MONOTONIC` time in nanoseconds (the time base of `t_sample_ns` and
/// of `AR_WAIT_AT` / `AR_WAIT_UNTIL`). Does not allocate, lock or fail.
#[unsafe(no_mangle)]
pub extern "C" fn ar_monotonic_ns() -> u64 {
    ipc_types::clock::monotonic_ns()
}

/// Sleeps until the absolute `CLOCK_MONOTONIC` time `t_ns` (`clock_nanosleep` with
/// `TIMER_ABSTIME`, resumed after a signal); returns at once when `t_ns` is past. Not
/// interrupted by `ar_request_stop`: sleep to a time at most a period away.
#[unsafe(no_mangle)]
pub extern "C" fn ar_sleep_until_ns(t_ns: u64) {
    ipc_types::clock::sleep_until_ns(t_ns);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_clock_advances_and_the_sleep_reaches_its_time() {
        let t0 = ar_monotonic_ns();
        ar_sleep_until_ns(t0 + 2_000_000);
        assert!(ar_monotonic_ns() >= t0 + 2_000_000);
        // A time in the past returns at once (a test that hangs here fails by its harness).
        ar_sleep_until_ns(0);
    }
}
