//! The PCAC phase: [`crate::pcac_cost::measure`] for each workload on the pinned RT core,
//! turned into table rows, detail lines and the `pcac` block of `summary.json`. It ends
//! the full run and is all of `latency-bench pcac`.

use crate::hist::{self, Summary, ratio};
use crate::pcac_cost::{self, AnchorCost, Anchors, PcacCost, Workload};
use crate::pcac_replan::{self, ReplanCost};
use crate::report::Measured;
use crate::table::fmt_ratio;
use crate::timed_on_rt_core;
use hdrhistogram::Histogram;
use serde_json::{Value, json};
use std::path::Path;
use std::time::{Duration, SystemTime};

/// The PCAC step at each of `workloads` on the pinned RT core, beside the `anchors`
/// (clarabel, OSQP) on the same QPs (see [`crate::pcac_cost`]), and, when the truss is
/// among them, its cost per period re-planning every `N` of `replan` beside a solve at
/// every sample ([`crate::pcac_replan`]): the table rows, the detail lines and the JSON
/// block of `summary.json`.
pub fn pcac_phase(
    rt_core: usize,
    dir: &Path,
    workloads: &[Workload],
    warmup: Option<u64>,
    steps: u64,
    anchors: Anchors,
    replan: pcac_replan::Runs<'_>,
) -> (Vec<Measured>, Vec<String>, Value) {
    let pcac_replan::Runs {
        every: replan,
        qp_share,
    } = replan;
    let list = workloads.to_vec();
    // (N, QP share): every sample first, then each N, and each N ≥ 4 again in shares.
    let periods: Vec<(usize, usize)> = if workloads.contains(&Workload::Truss) && !replan.is_empty()
    {
        std::iter::once((1, 0))
            .chain(replan.iter().flat_map(|&n| {
                let shared = (n >= 4 && qp_share > 0).then_some((n, qp_share));
                std::iter::once((n, 0)).chain(shared)
            }))
            .collect()
    } else {
        Vec::new()
    };
    let run = match timed_on_rt_core(
        rt_core,
        dir,
        "bench-pcac",
        ("pcac", "pcac step"),
        move || {
            let costs = list
                .iter()
                .map(|&w| {
                    let warm = warmup.unwrap_or(w.default_warmup());
                    (w, pcac_cost::measure(w, warm, steps, anchors))
                })
                .collect::<Vec<_>>();
            let warm = warmup.unwrap_or(Workload::Truss.default_warmup());
            let replans = periods
                .iter()
                .map(|&(n, share)| pcac_replan::measure(n, share, warm, steps))
                .collect::<Vec<_>>();
            (costs, replans)
        },
    ) {
        Ok(run) => run,
        Err(failed) => return (vec![*failed], Vec::new(), Value::Null),
    };
    let (setup, (results, replans)) = (run.setup, run.value);
    let (start, elapsed) = (run.start, run.elapsed);
    let mut rows = Vec::new();
    let mut lines = Vec::new();
    let mut json_out = serde_json::Map::new();
    for (w, r) in results {
        match r {
            Ok(c) => {
                let (mut m, l, v) = pcac_rows(&c, dir, start, elapsed, anchors);
                rows.append(&mut m);
                lines.extend(l);
                json_out.insert(w.slug().into(), v);
            }
            Err(e) => rows.push(Measured::failed(w.slug(), w.label(), e)),
        }
    }
    if !replans.is_empty() {
        let (mut m, l, v) = replan_rows(&replans, dir, start, elapsed);
        rows.append(&mut m);
        lines.extend(l);
        json_out.insert("truss-replan".into(), v);
    }
    lines.push(format!(
        "pcac: timing thread: {}; each workload's copies run in blocks of {} samples, the first {} timed steps of a block recorded apart (cold cache)",
        setup.describe(),
        pcac_cost::BLOCK,
        pcac_cost::REWARM
    ));
    (rows, lines, Value::Object(json_out))
}

/// The rows, detail lines and JSON of one PCAC workload, with rows for the `anchors` that
/// ran.
pub fn pcac_rows(
    c: &PcacCost,
    dir: &Path,
    start: SystemTime,
    elapsed: Duration,
    anchors: Anchors,
) -> (Vec<Measured>, Vec<String>, Value) {
    let w = c.workload;
    let slug = w.slug();
    let mut rows = Vec::new();
    let files = |name: &str, h: &Histogram<u64>| {
        hist::write_files(dir, name, h, start, elapsed).unwrap_or_default()
    };
    let step = Summary::of(&c.step);
    let timed = c.step.len() + c.cold.len();
    let pct = |n: u64| 100.0 * n as f64 / timed.max(1) as f64;
    let mut m = Measured::from_summary(
        slug,
        &format!("{} step", w.label()),
        step,
        files(slug, &c.step),
    );
    let target = w.target_ns();
    let verdict = |ns: u64, t: u64| if ns < t { "PASS" } else { "FAIL" };
    let mut note = format!(
        "p99 {} target {} µs",
        verdict(step.p99_ns, target),
        target / 1_000
    );
    if let Some(st) = w.stretch_ns() {
        note.push_str(&format!(
            ", {} stretch {} µs",
            if step.p99_ns < st { "meets" } else { "misses" },
            st / 1_000
        ));
    }
    note.push_str(&format!(
        "; fallbacks {}; u at bound {:.1} %",
        c.fallback_steps,
        pct(c.saturated)
    ));
    if c.move_bounds {
        note.push_str(&format!(", Δu at bound {:.1} %", pct(c.at_move_bound)));
    }
    m.note = note;
    rows.push(m);
    let cl = Summary::of(&c.clarabel.time);
    let os = Summary::of(&c.osqp.time);
    let anchor_row = |id: &str, label: &str, a: &AnchorCost, sm: Summary, extra: String| {
        let mut m = Measured::from_summary(id, label, sm, files(id, &a.time));
        m.note = format!(
            "÷ pcac step: p50 {}×, p99 {}×; first move agrees to {:.1e} ({} of {} compared{}{})",
            fmt_ratio(ratio(sm.p50_ns, step.p50_ns)),
            fmt_ratio(ratio(sm.p99_ns, step.p99_ns)),
            a.max_first_move_diff,
            a.compared,
            timed,
            if a.unsolved > 0 {
                format!(", not solved {}", a.unsolved)
            } else {
                String::new()
            },
            extra,
        );
        m
    };
    if anchors.clarabel {
        rows.push(anchor_row(
            &format!("{slug}-clarabel"),
            "  clarabel, same QPs (set-up + solve)",
            &c.clarabel,
            cl,
            String::new(),
        ));
    }
    if anchors.osqp {
        rows.push(anchor_row(
            &format!("{slug}-osqp"),
            "  OSQP, same QPs (update + warm solve)",
            &c.osqp,
            os,
            if c.osqp_setups == 1 {
                String::new()
            } else {
                format!(", {} set-ups", c.osqp_setups)
            },
        ));
    }
    for (i, what) in ["no active constraint", "≥ 1 active constraint"]
        .iter()
        .enumerate()
    {
        let id = format!("{slug}-step-active-{i}");
        let h = &c.step_by_active[i];
        let mut m = Measured::from_summary(
            &id,
            &format!("  steps with {what}"),
            Summary::of(h),
            files(&id, h),
        );
        m.note = format!(
            "{:.0} % of the warm steps",
            100.0 * h.len() as f64 / c.step.len().max(1) as f64
        );
        rows.push(m);
    }
    // Each piece at the steps that ran it (module docs of `pcac_cost`); none for a piece
    // the workload never runs (the fast path on the truss).
    let timed_pieces = c.pieces[0].len();
    for (i, name) in pcac_cost::PIECES.iter().enumerate() {
        if c.pieces[i].is_empty() {
            continue;
        }
        let id = format!("{slug}-piece-{i}");
        let mut m = Measured::from_summary(
            &id,
            &format!("  {name}"),
            Summary::of(&c.pieces[i]),
            files(&id, &c.pieces[i]),
        );
        let share = ratio(Summary::of(&c.pieces[i]).p50_ns, step.p50_ns).unwrap_or(0.0);
        m.note = format!("{:.0} % of the step's p50", 100.0 * share);
        if c.pieces[i].len() != timed_pieces {
            m.note += &format!("; at {} of {} steps", c.pieces[i].len(), timed_pieces);
        }
        rows.push(m);
    }
    let mut m = Measured::from_summary(
        &format!("{slug}-cold"),
        "  step at a block start (cold cache)",
        Summary::of(&c.cold),
        files(&format!("{slug}-cold"), &c.cold),
    );
    m.note = "not in the step row".into();
    rows.push(m);
    let ct = &c.counters;
    let active_any = timed.saturating_sub(c.active.count_between(0, 0));
    let mut lines = vec![format!(
        "{slug}: active constraints per step p50 {} / p90 {} / p99 {} / max {}, {:.0} % of steps with ≥ 1; QP iterations p50 {} / p99 {} / max {}",
        hist::quantile(&c.active, 0.5),
        hist::quantile(&c.active, 0.9),
        hist::quantile(&c.active, 0.99),
        c.active.max(),
        pct(active_any),
        hist::quantile(&c.iterations, 0.5),
        hist::quantile(&c.iterations, 0.99),
        c.iterations.max(),
    )];
    if anchors.clarabel {
        let a = &c.clarabel;
        lines.push(format!(
            "{slug}: first move |u − u_clarabel| (tol {:.0e}) p50 {:.1e} / p90 {:.1e} / p99 {:.1e} / max {:.1e}; beyond {:.0e} at {} of {} compared steps; there: clarabel re-solved at tol {:.0e} agrees to {:.1e} ({} re-solves not solved); ρ = (J(U_cl) − J(U))/(½eᵀHe) ≥ {:.3} (≥ 1: clarabel's point is higher than ours by at least ½eᵀHe); clarabel's constraint violation ≤ {:.1e}",
            pcac_cost::CLARABEL_TOL,
            a.first_move_diff_quantile(0.5),
            a.first_move_diff_quantile(0.9),
            a.first_move_diff_quantile(0.99),
            a.max_first_move_diff,
            pcac_cost::AGREE_TOL,
            a.over_tol,
            a.compared,
            pcac_cost::CLARABEL_TIGHT_TOL,
            c.tight_diff,
            c.tight_unsolved,
            a.optimality_ratio,
            a.violation,
        ));
    }
    if anchors.osqp {
        let a = &c.osqp;
        lines.push(format!(
            "{slug}: first move |u − u_osqp| (eps_abs = eps_rel = {:.0e}, polished) p50 {:.1e} / p90 {:.1e} / p99 {:.1e} / max {:.1e}; beyond {:.0e} at {} of {} compared steps; there: ρ = (J(U_osqp) − J(U))/(½eᵀHe) ≥ {:.3}; OSQP's constraint violation ≤ {:.1e}; OSQP set up {} time(s), then updated and warm-started; ADMM iterations p50 {} / p99 {} / max {}; solved but not polished {}; not solved {} (SolvedInaccurate {}, iteration cap {})",
            pcac_cost::OSQP_TOL,
            a.first_move_diff_quantile(0.5),
            a.first_move_diff_quantile(0.9),
            a.first_move_diff_quantile(0.99),
            a.max_first_move_diff,
            pcac_cost::AGREE_TOL,
            a.over_tol,
            a.compared,
            a.optimality_ratio,
            a.violation,
            c.osqp_setups,
            hist::quantile(&c.osqp_iterations, 0.5),
            hist::quantile(&c.osqp_iterations, 0.99),
            c.osqp_iterations.max(),
            c.osqp_unpolished,
            a.unsolved,
            c.osqp_inaccurate_or_capped[0],
            c.osqp_inaccurate_or_capped[1],
        ));
    }
    lines.push(
        format!(
            "{slug}: {} timed steps; max |u| {:.3}; counters over the whole run: {} MPC steps, {} solved ({} by the fast path), {} fallbacks ({} infeasible, {} iteration cap, {} numerical, {} refused), {} identification resets; reference copy mismatches {}; pieces' first move vs the step's {:.1e}",
            timed,
            c.max_abs_u,
            ct.steps,
            ct.solved,
            ct.fast_path,
            ct.fallbacks,
            ct.infeasible,
            ct.max_iterations,
            ct.numerical_error,
            ct.refused,
            ct.id_resets,
            c.replica_mismatches,
            c.pieces_diff,
        ),
    );
    let active_hist: Vec<(u64, u64)> = c
        .active
        .iter_recorded()
        .map(|v| (v.value_iterated_to(), v.count_at_value()))
        .collect();
    let v = json!({
        "step": step,
        "cold": Summary::of(&c.cold),
        "clarabel": if anchors.clarabel { Some(cl) } else { None },
        "osqp": if anchors.osqp { Some(json!({
            "summary": os,
            "tol": pcac_cost::OSQP_TOL,
            "compared": c.osqp.compared,
            "unsolved": c.osqp.unsolved,
            "max_first_move_diff": c.osqp.max_first_move_diff,
            "first_move_diff_p50": c.osqp.first_move_diff_quantile(0.5),
            "first_move_diff_p90": c.osqp.first_move_diff_quantile(0.9),
            "first_move_diff_p99": c.osqp.first_move_diff_quantile(0.99),
            "over_agree_tol": c.osqp.over_tol,
            "optimality_ratio": c.osqp.optimality_ratio.is_finite().then_some(c.osqp.optimality_ratio),
            "violation": c.osqp.violation,
            "setups": c.osqp_setups,
            "unpolished": c.osqp_unpolished,
            "solved_inaccurate": c.osqp_inaccurate_or_capped[0],
            "iteration_cap": c.osqp_inaccurate_or_capped[1],
            "iterations": Summary::of(&c.osqp_iterations),
        })) } else { None },
        "pieces": pcac_cost::PIECES.iter().zip(&c.pieces).map(|(n, h)| json!({"name": n, "summary": Summary::of(h)})).collect::<Vec<_>>(),
        "max_first_move_diff": c.clarabel.max_first_move_diff,
        "compared": c.clarabel.compared,
        "clarabel_unsolved": c.clarabel.unsolved,
        "pieces_diff": c.pieces_diff,
        "first_move_diff_p50": c.clarabel.first_move_diff_quantile(0.5),
        "first_move_diff_p90": c.clarabel.first_move_diff_quantile(0.9),
        "first_move_diff_p99": c.clarabel.first_move_diff_quantile(0.99),
        "tight_unsolved": c.tight_unsolved,
        "over_agree_tol": c.clarabel.over_tol,
        "tight_tol_diff": c.tight_diff,
        "optimality_ratio": if c.clarabel.optimality_ratio.is_finite() { Some(c.clarabel.optimality_ratio) } else { None },
        "clarabel_violation": c.clarabel.violation,
        "replica_mismatches": c.replica_mismatches,
        "saturated_steps": c.saturated,
        "move_bound_steps": c.at_move_bound,
        "fallback_steps": c.fallback_steps,
        "max_abs_u": c.max_abs_u,
        "active_constraints": active_hist,
        "iterations": Summary::of(&c.iterations),
        "counters": {
            "steps": ct.steps, "solved": ct.solved, "fast_path": ct.fast_path, "fallbacks": ct.fallbacks,
            "infeasible": ct.infeasible, "max_iterations": ct.max_iterations,
            "numerical_error": ct.numerical_error, "refused": ct.refused,
            "id_resets": ct.id_resets,
        },
        "target_p99_ns": w.target_ns(),
        "stretch_p99_ns": w.stretch_ns(),
    });
    (rows, lines, v)
}

/// The rows, detail lines and JSON of the truss re-planning every `N`: the first run is
/// the reference (`N = 1`, a solve at every sample), each later one a row with its
/// worst periods against it and its periods by position in the cycle.
fn replan_rows(
    runs: &[Result<ReplanCost, String>],
    dir: &Path,
    start: SystemTime,
    elapsed: Duration,
) -> (Vec<Measured>, Vec<String>, Value) {
    let mut rows = Vec::new();
    let mut lines = Vec::new();
    let mut out = Vec::new();
    let files = |name: &str, h: &Histogram<u64>| {
        hist::write_files(dir, name, h, start, elapsed).unwrap_or_default()
    };
    let mut reference: Option<Summary> = None;
    for run in runs {
        let r = match run {
            Ok(r) => r,
            Err(e) => {
                rows.push(Measured::failed(
                    "truss-replan",
                    "pcac truss re-planning",
                    e.clone(),
                ));
                continue;
            }
        };
        let id = if r.share > 0 {
            format!("truss-replan-{}-share-{}", r.every, r.share)
        } else {
            format!("truss-replan-{}", r.every)
        };
        let sm = Summary::of(&r.period);
        let label = if r.every == 1 {
            "pcac truss, a solve every sample (per period)".to_string()
        } else if r.share > 0 {
            format!(
                "pcac truss, re-planning every {}, QP in shares of {} (per period)",
                r.every, r.share
            )
        } else {
            format!("pcac truss, re-planning every {} (per period)", r.every)
        };
        let mut m = Measured::from_summary(&id, &label, sm, files(&id, &r.period));
        let last = if r.share > 0 {
            "QP continued"
        } else {
            "no unit"
        };
        let positions = ["prediction", "condensing", "QP", last];
        let used = r.every.min(4);
        let by_pos: Vec<String> = (0..used)
            .map(|i| {
                let what = if r.every == 1 {
                    "whole solve"
                } else if r.every == 2 && i == 0 {
                    "prediction + condensing"
                } else if r.every == 2 {
                    "QP"
                } else {
                    positions[i]
                };
                format!(
                    "{what} p99 {:.1}",
                    Summary::of(&r.by_position[i]).p99_ns as f64 / 1e3
                )
            })
            .collect();
        m.note = match reference {
            Some(base) if r.every > 1 => format!(
                "÷ every sample: p99 {}×, max {}×; {} µs; {} solves, {} fallbacks",
                fmt_ratio(ratio(sm.p99_ns, base.p99_ns)),
                fmt_ratio(ratio(sm.max_ns, base.max_ns)),
                by_pos.join(", "),
                r.solves,
                r.fallbacks
            ),
            _ => format!(
                "the reference of the rows below; {} solves, {} fallbacks",
                r.solves, r.fallbacks
            ),
        };
        if r.every == 1 {
            reference = Some(sm);
        }
        rows.push(m);
        lines.push(format!(
            "{id}: {} timed periods, {} at block starts apart; u at bound in {:.1} % of the periods",
            r.period.len(),
            r.cold.len(),
            100.0 * r.saturated as f64 / r.period.len().max(1) as f64
        ));
        out.push(json!({
            "every": r.every,
            "qp_share": r.share,
            "period": sm,
            "by_position": r.by_position[..used].iter().map(Summary::of).collect::<Vec<_>>(),
            "cold": Summary::of(&r.cold),
            "solves": r.solves,
            "fallbacks": r.fallbacks,
        }));
    }
    (rows, lines, Value::Array(out))
}
