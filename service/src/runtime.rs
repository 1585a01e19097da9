//! The real-time loop of the service, its policies, and the run report.
//!
//! Two phases, kept apart by types. [`run`] builds everything that allocates — the
//! controller, the histogram boxes, the log and event queues, the iceoryx2 ports — and
//! starts the helper threads (histogram reporter, CSV writer) off the RT core and at normal
//! priority. The RT thread then pins itself, asks for `SCHED_FIFO` and `mlockall`, connects,
//! and runs [`LoopCore`], whose per-sample work is:
//!
//! ```text
//!  wait for measurement k (sleep-poll, busy-poll or blocking on the plant's event: [`pacing`])
//!  session: first sample, next (gaps counted as lost), stall resumed, or new plant session
//!  gate: contract version and counts, finite, in range — else hold u, count
//!  answer, by service.timing (the safe input instead in the safe state and the open-loop
//!  phase, while the controller takes the sample in without adapting):
//!    compute-first  u_k = controller.step(y_k, …); publish Actuation{seq k}
//!    answer-first   publish Actuation{seq k} = the prepared u_k (and plan);
//!                   then advance(k) prepares u_{k+1} and its plan
//!    send-ahead     (publish Actuation{seq k} = the prepared u_k if none went ahead for k);
//!                   advance(k) prepares u_{k+1}; publish Actuation{seq k+1} at once
//!  record wake-up, compute, response time and period jitter
//!  push the signals to the log queue (drop and count when full)
//!  deadline policy: count misses; N consecutive after the grace period ⇒ safe state
//!  (latched, or left after M good answers)
//! ```
//!
//! With answer-first the response time no longer contains the controller's cost; with
//! send-ahead the plant holds `u_{k+1}` before sample `k + 1` is taken, so a stall of the
//! service shorter than a period costs nothing and a plant may latch its inputs on the
//! sample clock (`proxy.deadline = 0`). Its deadline for the answer to sample `k` is then
//! `T + D` after `t_k`. The ahead timings need a controller with an ahead form
//! ([`control::ahead`]); each of their answers may carry the controller's plan for the
//! next `service.plan-length` samples, which a plant applies when an answer is late.
//! Which inputs were sent for which sample is kept in a [`sent::SentLog`].
//!
//! The policies are plain-data types with no I/O and no clock of their own, each with its
//! rules stated in its module:
//!
//! - [`gate`]: which measurements may reach the controller;
//! - [`session`]: sequence numbers, silence, a stall versus a genuinely new plant session;
//! - [`deadline`]: what counts as a miss, when the safe state is entered and left;
//! - [`reset`]: what a fault does to what the controller learned. By default
//!   ([`TimingFaultReset::KeepLearned`]) a timing fault — leaving the safe state, a stalled
//!   plant that resumes its sequence — keeps it; a new plant session keeps it too and
//!   restarts only the controller's data history, unless `service.reset-on-resume` is true;
//! - [`checkpoint`]: what the controller learned, copied every `service.checkpoint-every`
//!   through a [`checkpoint_slot::CheckpointSlot`] (no allocation) and written to
//!   `checkpoint.json` off the RT thread; `--warm-start` starts a later run from it.
//!
//! Nothing in that path allocates, locks, does I/O or panics (a counting-allocator test in
//! `service/tests/no_alloc.rs` runs it). Events (plant silent, resumed, safe state) leave the
//! RT thread through a lock-free queue and are printed by the supervising thread. When no
//! sample has arrived for `silent-periods` periods the plant is declared silent; while it is,
//! and only then, the loop cleans up stale iceoryx2 resources of dead processes every 100 ms
//! so that a restarted plant can connect, and it resumes on the next sample.

pub mod checkpoint;
pub mod checkpoint_slot;
pub mod deadline;
pub mod force_regulation;
pub mod gate;
pub mod live_tap;
mod loop_core;
mod loop_event;
mod loop_stats;
pub mod model_following;
pub mod operator;
pub mod pacing;
mod report;
pub mod reset;
mod rt_thread;
mod run;
pub mod sent;
mod service_error;
pub mod session;
mod tones;
pub mod verdict;

pub use loop_core::{CycleDecision, LoopCore, Outbox};
pub use loop_event::LoopEvent;
pub use loop_stats::LoopStats;
pub use pacing::{Pacer, WaitStep};
pub use report::{AdaptationReport, CheckpointReport, RunReport};
pub use reset::TimingFaultReset;
pub use rt_thread::{PortsOutbox, RT_POOL_BLOCKS, StopReason, rt_loop};
pub use run::{RunOptions, run};
pub use service_error::ServiceError;
pub use tones::{ToneLine, ToneMeter, ToneReport};
