//! The CPU wake-up latency a real-time process asks of the kernel: a PM QoS request on
//! `/dev/cpu_dma_latency`.
//!
//! Between two samples an idle core enters an idle state, and leaving it costs its exit
//! latency on the next wake-up: tens to hundreds of µs for a deep C-state on bare metal,
//! and, for a virtual CPU that halts, a trip through the hypervisor, which may run
//! something else meanwhile. The kernel's idle governor picks only states whose exit
//! latency is at most the smallest value any process asks for: a process writes that value
//! (µs, a native-endian `i32`) to `/dev/cpu_dma_latency` and the request holds for as long
//! as it keeps the file open. With 0 the cores poll in idle instead of halting (the
//! `POLL` state); `cyclictest` asks the same unless told `--laptop`.
//!
//! The request is global (every CPU) and costs power: an idle core keeps running. It is
//! held for the life of the process ([`hold`]) or until [`release`].

use crate::rt::StepOutcome;
use std::fs::File;
use std::io::{Read, Write};
use std::sync::Mutex;

/// The PM QoS device of the CPU wake-up latency.
pub const DEVICE: &str = "/dev/cpu_dma_latency";

/// The open request, if any, and its value in µs.
static HELD: Mutex<Option<(File, u32)>> = Mutex::new(None);

/// Asks that no core take longer than `us` µs to wake up, for the life of the process
/// (a request held before is replaced). Refused, with the reason, when the device cannot
/// be opened or written (it needs root, or write access to [`DEVICE`]).
pub fn hold(us: u32) -> StepOutcome {
    let Ok(value) = i32::try_from(us) else {
        return StepOutcome::Refused(format!("{us} µs does not fit the PM QoS request"));
    };
    let opened = File::options().write(true).open(DEVICE);
    let mut file = match opened {
        Ok(f) => f,
        Err(e) => {
            return StepOutcome::Refused(format!(
                "{DEVICE}: {e} (needs root or write access to it)"
            ));
        }
    };
    if let Err(e) = file.write_all(&value.to_ne_bytes()) {
        return StepOutcome::Refused(format!("{DEVICE}: writing {us} µs: {e}"));
    }
    // The lock is taken at set-up only, never on a real-time path.
    let mut held = HELD.lock().unwrap_or_else(|p| p.into_inner());
    *held = Some((file, us));
    StepOutcome::Done
}

/// Drops the request held by [`hold`], if any (closing the file ends it).
pub fn release() {
    let mut held = HELD.lock().unwrap_or_else(|p| p.into_inner());
    *held = None;
}

/// The value this process holds, µs, if any.
pub fn held() -> Option<u32> {
    HELD.lock()
        .unwrap_or_else(|p| p.into_inner())
        .as_ref()
        .map(|(_, us)| *us)
}

/// The latency the kernel enforces now (the smallest request of all processes), µs;
/// `None` when [`DEVICE`] cannot be read.
pub fn in_force() -> Option<u32> {
    let mut bytes = [0u8; 4];
    File::open(DEVICE).ok()?.read_exact(&mut bytes).ok()?;
    u32::try_from(i32::from_ne_bytes(bytes)).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_held_request_is_in_force_until_released() {
        match hold(0) {
            StepOutcome::Done => {
                assert_eq!(held(), Some(0));
                assert_eq!(
                    in_force(),
                    Some(0),
                    "the kernel enforces the smallest request"
                );
                release();
                assert_eq!(held(), None);
            }
            StepOutcome::Refused(why) => {
                // Not root: the reason names the device.
                assert!(why.contains(DEVICE), "{why}");
                assert_eq!(held(), None);
            }
            StepOutcome::Skipped => panic!("hold never skips"),
        }
    }
}
