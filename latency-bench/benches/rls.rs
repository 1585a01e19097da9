//! Standalone RLS update benchmark: `cargo bench -p latency-bench --bench rls`.
//!
//! The same measurement as the RLS rows of `cargo run --release -p latency-bench`
//! (see `latency_bench::rls_cost`), printed as its own table: fast kernel against the
//! textbook one, p50/p99/max, at the sizes of issue 3, plus the fast updates left out by
//! the cold-cache rule (count and largest).
//!
//! The measuring thread is pinned to core 1 (the RT core of the full bench), runs at
//! `SCHED_FIFO` priority [`latency_bench::RT_PRIORITY`] (as the full bench's RT phases do)
//! and locks its memory, so that the numbers reflect a dedicated RT core even while other
//! work runs on the machine. A thread that computes for a minute at real-time priority is
//! throttled by the kernel (`sched_rt_runtime_us`: 50 ms of every second left to others),
//! which shows up as isolated ≈ 50 ms values in the max columns, never in the p99 (one
//! sample per second). The outcome of each request is printed first. Options (after
//! `--`): `--core <c>` pins to another core, `--no-pin` leaves the affinity alone,
//! `--fifo <prio>` changes the priority, `--no-fifo` stays `SCHED_OTHER`.

use ipc_types::rt::{RtRequest, setup_current_thread};
use latency_bench::rls_cost::{RLS_SIZES, measure_detailed, updates_for};

fn main() {
    let mut core = Some(1usize);
    let mut fifo = Some(latency_bench::RT_PRIORITY);
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--core" => core = args.next().and_then(|v| v.parse().ok()),
            "--no-pin" => core = None,
            "--fifo" => fifo = args.next().and_then(|v| v.parse().ok()),
            "--no-fifo" => fifo = None,
            // `cargo bench` passes `--bench`; anything else is ignored.
            _ => {}
        }
    }
    let setup = setup_current_thread(&RtRequest {
        core,
        fifo_priority: fifo,
        mlockall: true,
        prefault_stack_bytes: 256 * 1024,
        cpu_latency_us: Some(0),
    });
    println!("{}", setup.describe());
    println!(
        "{:<12} {:>10} {:>10} {:>10} {:>12} {:>12} {:>12} {:>9} {:>9}",
        "(n, p)",
        "fast p50",
        "fast p99",
        "fast max",
        "text p50",
        "text p99",
        "text max",
        "×p50",
        "×p99"
    );
    for (n, p) in RLS_SIZES {
        let steps = updates_for(n, p, 20_000);
        match measure_detailed(n, p, steps / 10, steps) {
            Ok(r) => {
                let (f, t) = (&r.fast, &r.text);
                let us =
                    |h: &hdrhistogram::Histogram<u64>, q: f64| h.value_at_quantile(q) as f64 / 1e3;
                println!(
                    "{:<12} {:>10.2} {:>10.2} {:>10.2} {:>12.2} {:>12.2} {:>12.2} {:>9.2} {:>9.2}   (µs; {}/{} updates; {} cold left out, max {:.2}; θ agree to {:.1e})",
                    format!("({n}, {p})"),
                    us(f, 0.5),
                    us(f, 0.99),
                    f.max() as f64 / 1e3,
                    us(t, 0.5),
                    us(t, 0.99),
                    t.max() as f64 / 1e3,
                    us(t, 0.5) / us(f, 0.5),
                    us(t, 0.99) / us(f, 0.99),
                    f.len(),
                    t.len(),
                    r.cold.len(),
                    r.cold.max() as f64 / 1e3,
                    r.diff
                );
            }
            Err(e) => println!("({n}, {p}): {e}"),
        }
    }
}
