//! Standalone RLS update benchmark: `cargo bench -p latency-bench --bench rls`.
//!
//! The same measurement as the RLS rows of `cargo run --release -p latency-bench`
//! (see `latency_bench::rls_cost`), printed as its own table: fast kernel against the
//! textbook one, p50/p99/max, at the sizes of issue 3.

use latency_bench::rls_cost::{RLS_SIZES, measure, updates_for};

fn main() {
    // `cargo bench` passes `--bench`; nothing else to parse.
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
        match measure(n, p, steps / 10, steps) {
            Ok((f, t, diff)) => {
                let us =
                    |h: &hdrhistogram::Histogram<u64>, q: f64| h.value_at_quantile(q) as f64 / 1e3;
                println!(
                    "{:<12} {:>10.2} {:>10.2} {:>10.2} {:>12.2} {:>12.2} {:>12.2} {:>9.2} {:>9.2}   (µs; {} updates; θ agree to {:.1e})",
                    format!("({n}, {p})"),
                    us(&f, 0.5),
                    us(&f, 0.99),
                    f.max() as f64 / 1e3,
                    us(&t, 0.5),
                    us(&t, 0.99),
                    t.max() as f64 / 1e3,
                    us(&t, 0.5) / us(&f, 0.5),
                    us(&t, 0.99) / us(&f, 0.99),
                    steps,
                    diff
                );
            }
            Err(e) => println!("({n}, {p}): {e}"),
        }
    }
}
