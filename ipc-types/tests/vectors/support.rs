//! Reading `timing.json`, the test vectors of the timing rules, for the Rust tests that run
//! them (`ipc-types/tests/timing_vectors.rs`, `plant-proxy/plant-side/tests/book_vectors.rs`,
//! which include this file by path). The encodings are described in the file itself.

#![allow(dead_code)]

use ipc_types::{
    Actuation, CONTRACT_VERSION, ChannelCounts, Timing, actuation_status, measurement_flags,
};
use serde_json::Value;

/// The vector file, parsed.
pub fn vectors() -> Value {
    serde_json::from_str(include_str!("timing.json")).expect("timing.json is JSON")
}

/// A number, or `"nan"`, `"inf"`, `"-inf"`.
pub fn value(v: &Value) -> f64 {
    match v {
        Value::String(s) if s == "nan" => f64::NAN,
        Value::String(s) if s == "inf" => f64::INFINITY,
        Value::String(s) if s == "-inf" => f64::NEG_INFINITY,
        _ => v.as_f64().unwrap_or_else(|| panic!("not a number: {v}")),
    }
}

/// An unsigned integer.
pub fn int(v: &Value) -> u64 {
    v.as_u64()
        .unwrap_or_else(|| panic!("not an unsigned integer: {v}"))
}

/// An optional unsigned integer (`null`: `None`).
pub fn opt_int(v: &Value) -> Option<u64> {
    (!v.is_null()).then(|| int(v))
}

/// A boolean.
pub fn boolean(v: &Value) -> bool {
    v.as_bool().unwrap_or_else(|| panic!("not a boolean: {v}"))
}

/// A timing by name, or by wire value (unknown wire values panic).
pub fn timing(v: &Value) -> Timing {
    match v {
        Value::String(s) => Timing::from_name(s).unwrap_or_else(|| panic!("no timing {s}")),
        _ => Timing::from_wire(int(v) as u32).unwrap_or_else(|| panic!("no timing {v}")),
    }
}

/// A timing's wire value, by name or as a number (unknown values allowed).
pub fn timing_wire(v: &Value) -> u32 {
    match v {
        Value::String(_) => timing(v).wire(),
        _ => int(v) as u32,
    }
}

/// Measurement flags or actuation status bits, by name.
pub fn bits(v: &Value) -> u32 {
    let names = v
        .as_array()
        .unwrap_or_else(|| panic!("not a list of names: {v}"));
    names.iter().fold(0, |acc, n| {
        acc | match n.as_str().unwrap_or_default() {
            "LOCKSTEP" => measurement_flags::LOCKSTEP,
            "PLANT_SAFE_OUTPUT" => measurement_flags::PLANT_SAFE_OUTPUT,
            "PREVIOUS_ACTUATION_MISSED" => measurement_flags::PREVIOUS_ACTUATION_MISSED,
            "LAST_SAMPLE" => measurement_flags::LAST_SAMPLE,
            "U_APPLIED" => measurement_flags::U_APPLIED,
            "PLAN_APPLIED" => measurement_flags::PLAN_APPLIED,
            "INJECTED_STALL" => measurement_flags::INJECTED_STALL,
            "STALL_ACK" => actuation_status::STALL_ACK,
            other => panic!("unknown bit name {other}"),
        }
    })
}

/// An actuation (see the file's description for the fields and defaults).
pub fn actuation(v: &Value) -> Actuation {
    let u = v["u"].as_array().expect("an actuation has u");
    let n_u = v.get("n_u").map_or(u.len() as u64, int) as usize;
    let mut a = Actuation::zeroed(ChannelCounts::new(1, 1, 0, n_u).expect("counts"));
    a.seq = int(&v["seq"]);
    a.reply_to = int(&v["reply_to"]);
    a.timing = v
        .get("timing")
        .map_or(Timing::SendAhead.wire(), timing_wire);
    a.status = v.get("status").map_or(0, bits);
    a.contract_version = v
        .get("contract_version")
        .map_or(CONTRACT_VERSION, |c| int(c) as u32);
    for (dst, x) in a.u.iter_mut().zip(u) {
        *dst = value(x);
    }
    let plan = v.get("plan").and_then(Value::as_array);
    for (row, values) in a.plan.iter_mut().zip(plan.into_iter().flatten()) {
        for (dst, x) in row.iter_mut().zip(values.as_array().expect("a plan row")) {
            *dst = value(x);
        }
    }
    a.plan_len = v
        .get("plan_len")
        .map_or(plan.map_or(0, Vec::len) as u64, int) as u32;
    a
}

/// `{variant: payload}` for a variant with a payload, else the variant's name.
pub fn variant(name: &str, payload: Option<Value>) -> Value {
    match payload {
        Some(p) => serde_json::json!({ name: p }),
        None => Value::String(name.into()),
    }
}
