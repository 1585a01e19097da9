//! A campaign as Markdown: the header (command, machine, campaign), the summary table, the
//! loaded-over-idle table and the per-run table. The formatting is fixed (numbers with a
//! fixed count of decimals, rows in the campaign's combination order, runs in the order
//! they ran), so two campaigns' files differ only where their figures do.

use super::Campaign;
use super::row::RunRow;
use super::summary::{CellSummary, LoadRatio};

fn or_dash(v: Option<String>) -> String {
    v.unwrap_or_else(|| "—".into())
}

fn db(v: Option<f64>) -> String {
    or_dash(v.map(|d| format!("{d:.1}")))
}

fn pct(v: Option<f64>) -> String {
    or_dash(v.map(|s| format!("{:.3} %", 100.0 * s)))
}

fn us(v: Option<f64>) -> String {
    or_dash(v.map(|ns| format!("{:.1}", ns / 1e3)))
}

fn ms(v: Option<f64>) -> String {
    or_dash(v.map(|ns| format!("{:.1}", ns / 1e6)))
}

fn times(v: Option<f64>) -> String {
    or_dash(v.map(|r| format!("×{r:.2}")))
}

/// A table cell's text: `|` escaped, line breaks folded.
fn cell(s: &str) -> String {
    s.replace('|', "\\|").replace('\n', " ")
}

/// The first cells of a row of the summary and the ratio tables, `| controller | wait |
/// condition |`.
fn row_head(
    controller: &str,
    wait: &impl std::fmt::Display,
    condition: &impl std::fmt::Display,
) -> String {
    format!("| {} | {wait} | {condition} |", cell(controller))
}

/// The summary table: one row per combination.
pub fn summary_table(cells: &[CellSummary]) -> String {
    let mut out = String::from(
        "| controller | wait | condition | runs | met criterion | min suppression dB, median / min \
         | lost share, median / max | held share, max | verdicts OK | every run below its \
         criterion failed its verdict with the cause named |\n\
         | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n",
    );
    for c in cells {
        let runs = if c.unreadable > 0 {
            format!("{} ({} unreadable)", c.runs, c.unreadable)
        } else {
            c.runs.to_string()
        };
        let met = match (c.met, c.criterion_db) {
            (Some(m), Some(k)) => format!("{m}/{} (≥ {k} dB)", c.runs),
            _ => "no criterion".into(),
        };
        let mut supp = format!(
            "{} / {}",
            db(c.min_suppression_median_db),
            db(c.min_suppression_min_db)
        );
        if c.unmeasured > 0 {
            supp += &format!(" ({} not measured)", c.unmeasured);
        }
        out += &format!(
            "{} {runs} | {met} | {supp} | {} / {} | {} | {}/{} | {} |\n",
            row_head(&c.controller, &c.wait, &c.condition),
            pct(c.lost_share_median),
            pct(c.lost_share_max),
            pct(c.held_share_max),
            c.verdicts_ok,
            c.runs,
            c.cause_named.label()
        );
    }
    out
}

/// The loaded-over-idle table: one row per controller, wait mode and loaded condition.
pub fn ratio_table(ratios: &[LoadRatio]) -> String {
    let mut out = String::from(
        "| controller | wait | condition | response p99 µs, idle → loaded | ratio | wake-up p99 \
         µs, idle → loaded | ratio | lost share, idle → loaded | RT run-queue wait ms, idle → \
         loaded | min suppression dB, idle → loaded |\n\
         | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n",
    );
    for r in ratios {
        let (i, l) = (&r.idle, &r.loaded);
        out += &format!(
            "{} {} → {} | {} | {} → {} | {} | {} → {} | {} → {} | {} → {} |\n",
            row_head(&r.controller, &r.wait, &r.condition),
            us(i.response_p99_ns),
            us(l.response_p99_ns),
            times(r.response_ratio()),
            us(i.wakeup_p99_ns),
            us(l.wakeup_p99_ns),
            times(r.wakeup_ratio()),
            pct(i.lost_share),
            pct(l.lost_share),
            ms(i.run_queue_wait_ns),
            ms(l.run_queue_wait_ns),
            db(i.min_suppression_db),
            db(l.min_suppression_db),
        );
    }
    out
}

/// The per-run table, in the order the runs ran.
pub fn run_table(rows: &[RunRow]) -> String {
    let mut out = String::from(
        "| # | folder | min suppression dB | criterion dB | lost share | held share | caught up \
         | response p99 µs | wake-up p99 µs | RT run-queue wait ms | RT involuntary switches \
         | steal ms, all CPUs | plant clock slips | verdict |\n\
         | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n",
    );
    for r in rows {
        let crit = db(r.criterion_db);
        match &r.outcome {
            Ok(f) => {
                let verdict = match f.first_failure() {
                    None if f.verdict_ok => "OK".to_string(),
                    None => "FAILED".to_string(),
                    Some(line) => format!("FAILED: {}", cell(line)),
                };
                out += &format!(
                    "| {} | `{}` | {} | {crit} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {verdict} |\n",
                    r.seq,
                    r.folder,
                    f.min_suppression_db
                        .map_or("not measured".to_string(), |d| format!("{d:.1}")),
                    pct(Some(f.lost_share)),
                    pct(Some(f.held_share)),
                    f.caught_up,
                    us(Some(f.response_p99_ns as f64)),
                    us(Some(f.wakeup_p99_ns as f64)),
                    ms(f.run_queue_wait_ns.map(|n| n as f64)),
                    or_dash(f.involuntary_switches.map(|n| n.to_string())),
                    ms(f.steal_s.map(|s| s * 1e9)),
                    or_dash(f.plant_clock_slips.map(|n| n.to_string())),
                );
            }
            Err(e) => {
                let why = match &r.launch_error {
                    Some(l) => format!("{e} (launch: {l})"),
                    None => e.to_string(),
                };
                out += &format!(
                    "| {} | `{}` | — | {crit} | — | — | — | — | — | — | — | — | — | RUN FAILED, NO \
                     REPORT: {} |\n",
                    r.seq,
                    r.folder,
                    cell(&why)
                );
            }
        }
    }
    out
}

/// The whole results file.
pub fn render(c: &Campaign, cells: &[CellSummary], ratios: &[LoadRatio]) -> String {
    let mut out = crate::results_page::head(
        "Real time under load",
        "rig soak",
        "service/tools/src/soak.rs",
        "docs/deployment.md (\"Measuring real time under load: rig soak\")",
    );
    out += &format!("Command: `{}`\n\n{}\n\n", c.command, c.machine.line());
    out += &format!("{}\n\n", c.description());
    if let Some(why) = &c.interrupted {
        out += &format!("**INTERRUPTED**: {why}.\n\n");
    }
    out += "## Summary\n\n";
    out += &summary_table(cells);
    out += "\n## Loaded over idle (medians over the runs of each combination)\n\n";
    if ratios.is_empty() {
        out += "No idle runs to compare with, or no loaded condition.\n";
    } else {
        out += &ratio_table(ratios);
    }
    out += "\n## Runs\n\n";
    out += &run_table(&c.rows);
    out
}
