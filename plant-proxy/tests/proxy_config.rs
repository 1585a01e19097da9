//! The `[proxy]` fields of the contract-v3 timing: `deadline` in [0, 1], `late-policy =
//! "plan"` with `plan-fallback`, `overrun`, and `[proxy.faults] stalls`; each refusal names
//! the file and the field, through the library and through `plant-proxy check`.

mod common;

use common::first_order_with;
use ipc_types::ports::Applies;
use plant_proxy::late_policy::{LatePolicy, MissPolicy, PlanFallback};
use plant_proxy::proxy_config::{Mode, ProxyConfig};
use plant_proxy::runtime::Stall;
use plant_proxy::sample_clock::Overrun;
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_plant-proxy");

fn parse(proxy: &str) -> Result<ProxyConfig, String> {
    ProxyConfig::parse(&first_order_with("cfg", proxy), "f.toml", 1).map_err(|e| e.0)
}

fn parse_mode(proxy: &str, mode: Mode) -> Result<ProxyConfig, String> {
    ProxyConfig::parse_with_mode(&first_order_with("cfg", proxy), "f.toml", 1, Some(mode))
        .map_err(|e| e.0)
}

/// `proxy` is refused with a message naming the file and `field`, and containing `words`.
fn assert_refused(result: Result<ProxyConfig, String>, field: &str, words: &str) {
    let e = result.expect_err("must be refused");
    assert!(
        e.starts_with(&format!("f.toml: field '{field}': ")),
        "{field}: {e}"
    );
    assert!(e.contains(words), "{words}: {e}");
}

#[test]
fn a_deadline_of_zero_is_accepted_and_applies_at_the_sample_in_real_time() {
    let c = parse("[proxy]\ndeadline = 0.0").unwrap();
    assert_eq!(c.plant.deadline, 0.0);
    assert_eq!(c.applies(), Applies::AtSample);
    let c = parse("[proxy]\nmode = \"lockstep\"\ndeadline = 0.0").unwrap();
    assert_eq!(c.applies(), Applies::Lockstep);
    assert_eq!(
        parse("[proxy]\ndeadline = 1.0").unwrap().applies(),
        Applies::AtDeadline
    );
    assert_eq!(
        parse("").unwrap().applies(),
        Applies::AtDeadline,
        "default 0.5"
    );
}

#[test]
fn a_deadline_outside_zero_to_one_is_refused() {
    for d in ["-0.1", "1.5", "nan", "inf", "-0.0000001"] {
        assert_refused(
            parse(&format!("[proxy]\ndeadline = {d}")),
            "proxy.deadline",
            "[0, 1]",
        );
    }
}

#[test]
fn the_plan_policy_takes_a_fallback_that_defaults_to_hold() {
    let c = parse("[proxy]\nlate-policy = \"plan\"").unwrap();
    assert_eq!(c.plant.late_policy, LatePolicy::Plan);
    assert_eq!(c.miss_policy(), MissPolicy::Plan(PlanFallback::Hold));
    let c = parse("[proxy]\nlate-policy = \"plan\"\nplan-fallback = \"safe\"").unwrap();
    assert_eq!(c.miss_policy(), MissPolicy::Plan(PlanFallback::Safe));
    assert_eq!(c.describe_late_policy(), "plan (else safe)");
    assert_eq!(parse("").unwrap().miss_policy(), MissPolicy::Hold);
}

#[test]
fn a_plan_fallback_without_the_plan_policy_is_refused() {
    for policy in ["", "late-policy = \"hold\"\n", "late-policy = \"safe\"\n"] {
        assert_refused(
            parse(&format!("[proxy]\n{policy}plan-fallback = \"safe\"")),
            "proxy.plan-fallback",
            "only with late-policy = \"plan\"",
        );
    }
}

#[test]
fn overrun_is_slip_by_default_or_catch_up() {
    assert_eq!(parse("").unwrap().plant.overrun, Overrun::Slip);
    assert_eq!(
        parse("[proxy]\noverrun = \"slip\"").unwrap().plant.overrun,
        Overrun::Slip
    );
    assert_eq!(
        parse("[proxy]\noverrun = \"catch-up\"")
            .unwrap()
            .plant
            .overrun,
        Overrun::CatchUp
    );
    let e = parse("[proxy]\noverrun = \"skip\"").unwrap_err();
    assert!(e.contains("f.toml") && e.contains("skip"), "{e}");
    let e = parse("[proxy]\nlate-policy = \"predict\"").unwrap_err();
    assert!(e.contains("f.toml") && e.contains("predict"), "{e}");
}

#[test]
fn stalls_are_accepted_in_lockstep_and_refused_in_real_time() {
    let stalls = "[proxy.faults]\nstalls = [{ at = 4, periods = 2 }, { at = 10, periods = 1 }]";
    let c = parse(&format!("[proxy]\nmode = \"lockstep\"\n{stalls}")).unwrap();
    assert_eq!(
        c.faults.stalls,
        [Stall { at: 4, periods: 2 }, Stall { at: 10, periods: 1 }]
    );
    assert!(c.faults.stalled(5) && !c.faults.stalled(6) && c.faults.stalled(10));
    // Real time by default, or by the file, or by the command line: refused.
    assert_refused(parse(stalls), "proxy.faults.stalls", "lockstep");
    assert_refused(
        parse(&format!("[proxy]\nmode = \"real-time\"\n{stalls}")),
        "proxy.faults.stalls",
        "lockstep",
    );
    assert_refused(
        parse_mode(
            &format!("[proxy]\nmode = \"lockstep\"\n{stalls}"),
            Mode::RealTime,
        ),
        "proxy.faults.stalls",
        "lockstep",
    );
    // The command line's --mode lockstep makes a file without a mode acceptable.
    assert!(parse_mode(stalls, Mode::Lockstep).is_ok());
}

#[test]
fn overlapping_unsorted_and_zero_period_stalls_are_refused_naming_the_entry() {
    for (list, field, words) in [
        (
            "[{ at = 4, periods = 0 }]",
            "proxy.faults.stalls[0].periods",
            "at least 1",
        ),
        (
            "[{ at = 4, periods = 3 }, { at = 6, periods = 1 }]",
            "proxy.faults.stalls[1].at",
            "must not overlap",
        ),
        (
            "[{ at = 9, periods = 1 }, { at = 2, periods = 1 }]",
            "proxy.faults.stalls[1].at",
            "sorted",
        ),
    ] {
        assert_refused(
            parse(&format!(
                "[proxy]\nmode = \"lockstep\"\n[proxy.faults]\nstalls = {list}"
            )),
            field,
            words,
        );
    }
    // A negative sample or an unknown key is refused by the table's reader.
    let e =
        parse("[proxy]\nmode = \"lockstep\"\n[proxy.faults]\nstalls = [{ at = -1, periods = 2 }]")
            .unwrap_err();
    assert!(e.contains("f.toml") && e.contains("proxy"), "{e}");
    let e = parse("[proxy]\nmode = \"lockstep\"\n[proxy.faults]\nstalls = [{ at = 1, for = 2 }]")
        .unwrap_err();
    assert!(e.contains("f.toml") && e.contains("for"), "{e}");
}

fn check(proxy: &str) -> (Option<i32>, String, String) {
    let dir = std::env::temp_dir().join(format!("pp-proxy-config-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{:x}.toml", fxhash(proxy)));
    std::fs::write(&path, first_order_with("cfg-check", proxy)).unwrap();
    let out = Command::new(BIN)
        .args(["check", path.to_str().unwrap()])
        .output()
        .unwrap();
    let _ = std::fs::remove_file(&path);
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A file name per text, so that the tests running side by side do not share a file.
fn fxhash(s: &str) -> u64 {
    s.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ b as u64).wrapping_mul(0x100_0000_01b3)
    })
}

#[test]
fn plant_proxy_check_states_the_new_fields_and_refuses_bad_ones_naming_them() {
    let (code, out, err) = check(
        "[proxy]\ndeadline = 0.0\nlate-policy = \"plan\"\nplan-fallback = \"safe\"\noverrun = \"catch-up\"",
    );
    assert_eq!(code, Some(0), "{err}");
    assert!(
        out.contains("inputs applied at-sample")
            && out.contains("late policy plan (else safe)")
            && out.contains("overrun catch-up"),
        "{out}"
    );
    let (code, out, err) = check(
        "[proxy]\nmode = \"lockstep\"\nlate-policy = \"plan\"\n[proxy.faults]\nstalls = [{ at = 4, periods = 2 }]",
    );
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("1 stall(s) injected"), "{out}");
    for (proxy, field) in [
        ("[proxy]\nplan-fallback = \"hold\"", "proxy.plan-fallback"),
        ("[proxy]\ndeadline = -1.0", "proxy.deadline"),
        (
            "[proxy]\n[proxy.faults]\nstalls = [{ at = 4, periods = 2 }]",
            "proxy.faults.stalls",
        ),
        (
            "[proxy]\nmode = \"lockstep\"\n[proxy.faults]\nstalls = [{ at = 4, periods = 0 }]",
            "proxy.faults.stalls[0].periods",
        ),
    ] {
        let (code, _, err) = check(proxy);
        assert_eq!(code, Some(2), "{proxy}: {err}");
        assert!(
            err.contains(".toml: field '") && err.contains(&format!("field '{field}'")),
            "{proxy}: {err}"
        );
    }
}
