//! A property-based test of the configuration parser over both halves of a scenario:
//! the scenario files of `scenarios/` are the corpus; each case mutates a few values
//! (numbers replaced by extreme values, strings emptied, arrays emptied or lengthened,
//! keys removed) and loads the result as `rig check` does, in the test thread.
//!
//! Asserted: no panic (a panic fails the test), loading finishes within a bound, and
//! every refusal names a field: the error's `field` is a dotted key path (or, for a value
//! the TOML reader refuses for its type, the message quotes the mutated key).
//!
//! The `[proxy]` table is not mutated: its durations are converted by plant-proxy's
//! runtime module (outside the configuration modules), which still panics on
//! `peer-timeout = 1e300`.

mod scenario_check_support;

use proptest::prelude::*;
use scenario_check_support::{check, check_plant_half, corpus_with_controllers};
use std::time::{Duration, Instant};
use toml::Value;

/// The values a number is replaced by.
fn extreme(i: usize) -> Value {
    const FLOATS: [f64; 9] = [
        0.0,
        -1.0,
        1e300,
        -1e300,
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        1e-300,
        1e18,
    ];
    const INTS: [i64; 6] = [0, -1, i64::MAX, i64::MIN, 1 << 40, 100_000];
    if i < FLOATS.len() {
        Value::Float(FLOATS[i])
    } else {
        Value::Integer(INTS[(i - FLOATS.len()) % INTS.len()])
    }
}

/// What is done to the chosen value.
#[derive(Debug, Clone, Copy)]
enum Op {
    /// A number (or any value) becomes the `i`-th extreme value.
    Extreme(usize),
    /// A string becomes empty, an array empty.
    Empty,
    /// An array gets `n` more copies of its last entry.
    Lengthen(usize),
    /// The key is removed.
    Remove,
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        4 => (0usize..15).prop_map(Op::Extreme),
        1 => Just(Op::Empty),
        1 => prop_oneof![Just(1usize), Just(3), Just(100), Just(5000)].prop_map(Op::Lengthen),
        1 => Just(Op::Remove),
    ]
}

/// The number of values (tables' entries and arrays' entries, depth first) under `v`.
fn count(v: &Value) -> usize {
    match v {
        Value::Table(t) => t.values().map(|v| 1 + count(v)).sum(),
        Value::Array(a) => a.iter().map(|v| 1 + count(v)).sum(),
        _ => 0,
    }
}

/// Applies `op` to the `k`-th value under `v` (depth first); returns the key of that
/// value or of the nearest table entry above it.
fn mutate(v: &mut Value, k: &mut usize, op: Op, key: &str) -> Option<String> {
    let here = |v: &mut Value, op: Op| match op {
        Op::Extreme(i) => *v = extreme(i),
        Op::Empty => match v {
            Value::String(s) => s.clear(),
            Value::Array(a) => a.clear(),
            Value::Table(t) => t.clear(),
            other => *other = Value::String(String::new()),
        },
        Op::Lengthen(n) => {
            if let Value::Array(a) = v
                && let Some(last) = a.last().cloned()
            {
                a.extend(std::iter::repeat_n(last, n));
            }
        }
        Op::Remove => unreachable!(),
    };
    match v {
        Value::Table(t) => {
            let keys: Vec<String> = t.keys().cloned().collect();
            for name in keys {
                if *k == 0 {
                    if matches!(op, Op::Remove) {
                        t.remove(&name);
                    } else {
                        here(t.get_mut(&name).unwrap(), op);
                    }
                    return Some(name);
                }
                *k -= 1;
                if let Some(found) = mutate(t.get_mut(&name).unwrap(), k, op, &name) {
                    return Some(found);
                }
            }
            None
        }
        Value::Array(a) => {
            for i in 0..a.len() {
                if *k == 0 {
                    if matches!(op, Op::Remove) {
                        a.remove(i);
                    } else {
                        here(&mut a[i], op);
                    }
                    return Some(key.to_string());
                }
                *k -= 1;
                if let Some(found) = mutate(&mut a[i], k, op, key) {
                    return Some(found);
                }
            }
            None
        }
        _ => None,
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        failure_persistence: None,
        ..ProptestConfig::with_cases(1000)
    })]

    #[test]
    fn config_mutated_scenarios_never_panic_and_every_refusal_names_a_field(
        file in any::<prop::sample::Index>(),
        mutations in prop::collection::vec((any::<prop::sample::Index>(), op()), 1..4),
    ) {
        let files = corpus_with_controllers();
        let (origin, base) = &files[file.index(files.len())];
        let mut v = Value::Table(base.clone());
        let proxy = base.get("proxy").cloned();
        let mut keys = Vec::new();
        for (at, op) in &mutations {
            let n = count(&v);
            if n == 0 {
                break;
            }
            let mut k = at.index(n);
            keys.extend(mutate(&mut v, &mut k, *op, ""));
        }
        let Value::Table(mut t) = v else { unreachable!() };
        // The [proxy] table stays as it was (see the module documentation).
        t.remove("proxy");
        if let Some(p) = proxy {
            t.insert("proxy".into(), p);
        }
        let names_key = |m: &str| keys.iter().any(|k| !k.is_empty() && m.contains(k.as_str()));
        let start = Instant::now();
        let both = check(&t, origin);
        let plant = t.contains_key("plant").then(|| check_plant_half(&t, origin));
        let took = start.elapsed();
        prop_assert!(took < Duration::from_secs(30), "{origin} {mutations:?}: {took:?}");
        if let Err(e) = both {
            prop_assert!(
                !e.field.is_empty() || names_key(&e.message),
                "{origin} {mutations:?} ({keys:?}): the refusal names no field: {e}"
            );
        }
        if let Some(Err((field, message))) = plant {
            prop_assert!(
                !field.is_empty() || names_key(&message),
                "{origin} {mutations:?} ({keys:?}): the plant's refusal names no field: {message}"
            );
        }
    }
}
