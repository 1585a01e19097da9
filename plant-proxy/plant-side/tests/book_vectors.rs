//! Every book vector of `ipc-types/tests/vectors/timing.json` against [`ActuationBook`]: the
//! offers and decisions of the timing rules, kept with their state. The Python book runs
//! the same file (`ipc-types/python/tests/test_timing_vectors.py`).

#[path = "../../../ipc-types/tests/vectors/support.rs"]
mod support;

use ipc_types::MAX_U;
use plant_side::actuation_book::{ActuationBook, Decision, Offer};
use plant_side::late_policy::{MissPolicy, PlanFallback};
use serde_json::{Value, json};
use support::*;

fn used(u: &[f64; MAX_U], n_u: usize) -> Value {
    json!(u[..n_u])
}

/// Runs one book vector on a book of capacity `N`; returns its failures.
fn run_case<const N: usize>(case: &Value) -> Vec<String> {
    let what = case["description"].as_str().unwrap_or_default();
    let n_u = int(&case["n_u"]) as usize;
    let fallback = match case["fallback"].as_str() {
        Some("safe") => PlanFallback::Safe,
        _ => PlanFallback::Hold,
    };
    let policy = match case["policy"].as_str() {
        Some("hold") => MissPolicy::Hold,
        Some("safe") => MissPolicy::Safe,
        _ => MissPolicy::Plan(fallback),
    };
    let mut book = ActuationBook::<N>::new(n_u, policy);
    let mut failures = Vec::new();
    for (i, step) in case["steps"].as_array().expect("steps").iter().enumerate() {
        let (got, expected) = if let Some(a) = step.get("offer") {
            let got = match book.offer(&actuation(a), int(&step["k"])) {
                Offer::Kept => json!({ "offer": "kept" }),
                Offer::KeptDropping { dropped_seq } => {
                    json!({ "offer": "kept-dropping", "dropped_seq": dropped_seq })
                }
                Offer::Late => json!({ "offer": "late" }),
                Offer::Invalid => json!({ "offer": "invalid" }),
                Offer::StallAck => json!({ "offer": "stall-ack" }),
            };
            let mut expected = json!({ "offer": step["expect"] });
            if let Some(d) = step.get("dropped_seq") {
                expected["dropped_seq"] = d.clone();
            }
            (got, expected)
        } else if let Some(k) = step.get("decide") {
            let got = match book.decide(int(k)) {
                Decision::Answered { u, .. } => json!({ "answered": used(&u, n_u) }),
                Decision::Plan { u, from_seq, .. } => {
                    json!({ "plan": used(&u, n_u), "from_seq": from_seq })
                }
                Decision::Hold => json!("hold"),
                Decision::Safe => json!("safe"),
            };
            (got, step["expect"].clone())
        } else if let Some(k) = step.get("answers") {
            (json!(book.answers(int(k))), step["expect"].clone())
        } else if let Some(seq) = step.get("plan_seq") {
            (json!(book.plan_seq()), seq.clone())
        } else if step.get("clear").is_some() {
            book.clear();
            continue;
        } else {
            panic!("{what}: step {i} is no known step: {step}");
        };
        if got != expected {
            failures.push(format!(
                "{what}, step {i} {step}: expected {expected}, got {got}"
            ));
        }
    }
    failures
}

#[test]
fn every_book_vector_holds_for_the_plant_sides_book() {
    let v = vectors();
    let mut failures = Vec::new();
    for case in v["book"].as_array().expect("a list of book vectors") {
        failures.extend(match int(&case["capacity"]) {
            4 => run_case::<4>(case),
            8 => run_case::<8>(case),
            c => panic!("{}: a capacity of {c} (4 or 8)", case["description"]),
        });
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
