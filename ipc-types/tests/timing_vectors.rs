//! Every rule vector of `tests/vectors/timing.json` against `ipc_types::timing_rules`; the
//! Python package runs the same file (`ipc-types/python/tests/test_timing_vectors.py`).

#[path = "vectors/support.rs"]
mod support;

use ipc_types::ports::Applies;
use ipc_types::timing_rules::{self as rules, *};
use serde_json::{Value, json};
use support::*;

fn policy(name: &Value, fallback: &Value) -> MissPolicy {
    let fallback = match fallback.as_str() {
        Some("safe") => PlanFallback::Safe,
        _ => PlanFallback::Hold,
    };
    match name.as_str() {
        Some("hold") => MissPolicy::Hold,
        Some("safe") => MissPolicy::Safe,
        _ => MissPolicy::Plan(fallback),
    }
}

fn miss_input(v: &Value) -> Option<MissInput> {
    match v {
        Value::Null => None,
        Value::String(s) if s == "hold" => Some(MissInput::Hold),
        Value::String(s) if s == "safe" => Some(MissInput::Safe),
        _ => Some(MissInput::PlanRow(int(&v["plan-row"]) as usize)),
    }
}

fn applied_name(a: Applied) -> &'static str {
    match a {
        Applied::Answered => "answered",
        Applied::Plan => "plan",
        Applied::Held => "held",
        Applied::Safe => "safe",
        Applied::WatchdogSafe => "watchdog-safe",
    }
}

fn applied_of(v: &Value) -> Applied {
    [
        Applied::Answered,
        Applied::Plan,
        Applied::Held,
        Applied::Safe,
        Applied::WatchdogSafe,
    ]
    .into_iter()
    .find(|a| Some(applied_name(*a)) == v.as_str())
    .unwrap_or_else(|| panic!("no such application: {v}"))
}

fn flag_names(flags: u32) -> Value {
    let names = [
        (
            "PREVIOUS_ACTUATION_MISSED",
            ipc_types::measurement_flags::PREVIOUS_ACTUATION_MISSED,
        ),
        ("PLAN_APPLIED", ipc_types::measurement_flags::PLAN_APPLIED),
        (
            "PLANT_SAFE_OUTPUT",
            ipc_types::measurement_flags::PLANT_SAFE_OUTPUT,
        ),
    ];
    let set: Vec<&str> = names
        .iter()
        .filter(|(_, b)| flags & b != 0)
        .map(|(n, _)| *n)
        .collect();
    assert_eq!(
        flags & !names.iter().fold(0, |a, (_, b)| a | b),
        0,
        "unnamed bits"
    );
    json!(set)
}

fn row(j: Option<usize>) -> Value {
    j.map_or(Value::Null, |j| json!(j))
}

/// The result of the vector's rule on its arguments, in the file's encoding.
fn run(rule: &str, a: &Value) -> Value {
    match rule {
        "applies" => {
            json!(rules::applies(boolean(&a["lockstep"]), value(&a["deadline_fraction"])).name())
        }
        "deadline_offset_ns" => json!(deadline_offset_ns(
            boolean(&a["lockstep"]),
            value(&a["deadline_fraction"]),
            int(&a["period_ns"])
        )),
        "application_instant" => json!(application_instant(
            int(&a["t_sample_ns"]),
            int(&a["deadline_offset_ns"])
        )),
        "timings_meet" => {
            let plant = Applies::from_name(a["applies"].as_str().unwrap_or_default())
                .expect("an application");
            json!(timings_meet(plant, timing(&a["timing"])))
        }
        "answer_seq" => json!(answer_seq(int(&a["k"]), timing(&a["timing"]))),
        "answers_sample_itself" => json!(answers_sample_itself(
            timing(&a["timing"]),
            boolean(&a["sent_ahead_for_k"])
        )),
        "answer_deadline_ns" => json!(answer_deadline_ns(
            boolean(&a["lockstep"]),
            int(&a["deadline_ns"]),
            int(&a["period_ns"]),
            timing(&a["timing"])
        )),
        "answer_late" => json!(answer_late(
            boolean(&a["timestamp_ok"]),
            int(&a["deadline_ns"]),
            int(&a["response_ns"])
        )),
        "plan_row" => row(plan_row(
            int(&a["seq"]),
            int(&a["plan_len"]) as u32,
            int(&a["k"]),
        )),
        "carried" => match carried(int(&a["seq"]), int(&a["plan_len"]) as u32, int(&a["k"])) {
            Some(Carried::Input) => json!("input"),
            Some(Carried::PlanRow(j)) => variant("plan-row", Some(json!(j))),
            None => Value::Null,
        },
        "answered_measurement" => json!(answered_measurement(
            int(&a["seq"]),
            int(&a["reply_to"]),
            timing_wire(&a["timing"])
        )),
        "actuation_valid" => json!(actuation_valid(
            &actuation(&a["actuation"]),
            int(&a["n_u"]) as usize
        )),
        "arrival" => json!(match arrival(
            &actuation(&a["actuation"]),
            int(&a["n_u"]) as usize,
            int(&a["k"])
        ) {
            Arrival::StallAck => "stall-ack",
            Arrival::Invalid => "invalid",
            Arrival::Late => "late",
            Arrival::InTime => "in-time",
        }),
        "plan_supersedes" => json!(plan_supersedes(opt_int(&a["held"]), int(&a["candidate"]))),
        "on_miss" => {
            let j = opt_int(&a["newest_plan_row"]).map(|j| j as usize);
            match on_miss(policy(&a["policy"], &a["fallback"]), j) {
                MissInput::PlanRow(j) => variant("plan-row", Some(json!(j))),
                MissInput::Hold => json!("hold"),
                MissInput::Safe => json!("safe"),
            }
        }
        "watchdog_trips" => json!(watchdog_trips(
            boolean(&a["tripped"]),
            int(&a["consecutive_misses"]),
            int(&a["watchdog_periods"])
        )),
        "applied" => json!(applied_name(applied(
            miss_input(&a["miss"]),
            boolean(&a["tripped"])
        ))),
        "report_flags" => flag_names(report_flags(applied_of(&a["applied"]))),
        "reported" => json!(match reported(bits(&a["flags"])) {
            Reported::OnTime => "on-time",
            Reported::PlanRow => "plan-row",
            Reported::HeldOrSafe => "held-or-safe",
        }),
        "expected_input" => {
            let newest = a["newest"]
                .as_array()
                .map(|n| (int(&n[0]), int(&n[1]) as u32));
            match expected_input(boolean(&a["sent_for_k"]), newest, int(&a["k"])) {
                Expected::Sent => json!("sent"),
                Expected::PlanRow(j) => variant("plan-row", Some(json!(j))),
                Expected::Held => json!("held"),
                Expected::Safe => json!("safe"),
            }
        }
        "resolve_timing" => {
            let choice = match a["choice"].as_str() {
                Some("auto") => TimingChoice::Auto,
                _ => TimingChoice::Fixed(timing(&a["choice"])),
            };
            match resolve_timing(choice, boolean(&a["answers_ahead"])) {
                Ok(t) => json!({ "ok": t.name() }),
                Err(t) => json!({ "needs-ahead": t.name() }),
            }
        }
        "plan_length" => match plan_length(int(&a["requested"]), timing(&a["timing"])) {
            Ok(n) => json!({ "ok": n }),
            Err(PlanLengthRefusal::PastCapacity) => json!({ "refused": "past-capacity" }),
            Err(PlanLengthRefusal::ComputeFirst) => json!({ "refused": "compute-first" }),
        },
        "effective_timing" => {
            json!(effective_timing(timing(&a["configured"]), boolean(&a["has_ahead"])).name())
        }
        "effective_plan_length" => json!(effective_plan_length(
            timing(&a["timing"]),
            int(&a["configured"]) as usize
        )),
        other => panic!("a vector of an unknown rule: {other}"),
    }
}

#[test]
fn every_rule_vector_holds_for_the_rust_rules() {
    let v = vectors();
    let cases = v["rules"].as_array().expect("a list of rule vectors");
    let mut failures = Vec::new();
    for c in cases {
        let rule = c["rule"].as_str().expect("a rule name");
        let got = run(rule, &c["args"]);
        if got != c["expect"] {
            failures.push(format!(
                "{rule} ({}): expected {}, got {got}",
                c["description"], c["expect"]
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn every_rule_has_vectors() {
    let v = vectors();
    let named: std::collections::BTreeSet<&str> = v["rules"]
        .as_array()
        .expect("rules")
        .iter()
        .filter_map(|c| c["rule"].as_str())
        .collect();
    for rule in [
        "applies",
        "deadline_offset_ns",
        "application_instant",
        "timings_meet",
        "answer_seq",
        "answers_sample_itself",
        "answer_deadline_ns",
        "answer_late",
        "plan_row",
        "carried",
        "answered_measurement",
        "actuation_valid",
        "arrival",
        "plan_supersedes",
        "on_miss",
        "watchdog_trips",
        "applied",
        "report_flags",
        "reported",
        "expected_input",
        "resolve_timing",
        "plan_length",
        "effective_timing",
        "effective_plan_length",
    ] {
        assert!(named.contains(rule), "no vector for {rule}");
    }
}
