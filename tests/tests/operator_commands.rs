//! Operator commands on a running loop, as an operator sends them: a lockstep run of RCAC
//! (gradient update) on the tone plant, watched through the telemetry services and
//! commanded through the operator service (the `ipc_types` client, as `rig command` and
//! `rig monitor` use it). Each command is applied at a sample boundary and answered; while
//! adaptation is frozen `‖θ‖` does not change, and it changes again after resuming; the
//! safe state holds the safe input; a tunable is set within its declared bounds and refused
//! outside them; `stop-run` ends the run with its report; and the run, commands included,
//! replays bit for bit.

use ipc_types::actuation_status;
use ipc_types::operator::{OperatorClient, OperatorReply, OperatorRequest, command, outcome};
use ipc_types::telemetry::ports::TelemetryReader;
use ipc_types::telemetry::{TelemetryPoint, live_flags, run_state};
use rig_tests::*;
use serde_json::Value;
use std::time::{Duration, Instant};

/// Reads frames until `done` says so (or panics after `timeout`), keeping every point.
struct Watch {
    reader: TelemetryReader,
    points: Vec<TelemetryPoint>,
    flags: u32,
    state: u32,
    last_seq: u64,
    tunable: f64,
}

impl Watch {
    fn until(&mut self, what: &str, timeout: Duration, done: impl Fn(&Watch) -> bool) {
        let start = Instant::now();
        loop {
            let mut frames = Vec::new();
            self.reader.frames(|f| frames.push(*f));
            for f in frames {
                self.points.extend_from_slice(f.points());
                self.flags = f.flags;
                self.state = f.state;
                self.last_seq = f.last_seq;
                self.tunable = f.tunable_values[0];
            }
            if done(self) {
                return;
            }
            assert!(start.elapsed() < timeout, "waited {timeout:?} for {what}");
            std::thread::sleep(Duration::from_millis(5));
        }
    }
}

fn send(client: &OperatorClient, r: OperatorRequest) -> OperatorReply {
    client
        .send(&r, Duration::from_secs(20))
        .unwrap_or_else(|e| panic!("command {}: {e}", r.command))
}

fn applied(client: &OperatorClient, code: u32, id: u64) -> u64 {
    let reply = send(client, OperatorRequest::new(code, id));
    assert_eq!(
        reply.outcome,
        outcome::APPLIED,
        "{}: {}",
        command::name(code).unwrap(),
        reply.message()
    );
    assert_eq!(reply.request_id, id);
    reply.applied_before_seq
}

#[test]
fn an_operator_freezes_adapts_tunes_holds_safe_and_stops_a_run_that_replays_bit_for_bit() {
    let dir = TestDir::new("operator-commands");
    let rig = rig_name("operator");
    let scenario = operator_tone_scenario(&dir, &rig);
    let folder = dir.path.join("run");
    let reader = TelemetryReader::open(&rig).unwrap();
    let mut service = start_service("service", &scenario, &folder);
    // Far more samples than the test needs: the operator ends the run.
    let mut plant = start_lockstep_plant("plant", &scenario, 50_000_000, &[]);
    let mut watch = Watch {
        reader,
        points: Vec::new(),
        flags: 0,
        state: run_state::WAITING,
        last_seq: 0,
        tunable: f64::NAN,
    };
    let t = Duration::from_secs(120);
    watch.until("the loop to run 3000 samples", t, |w| w.last_seq > 3_000);
    assert_eq!(watch.state, run_state::RUNNING);
    assert_ne!(watch.flags & live_flags::COMMANDS_ENABLED, 0);
    assert_eq!(watch.tunable, 0.5);
    let client = OperatorClient::open(&rig).unwrap();

    // Frozen: θ stays what it was from the sample the command came before.
    let frozen_at = applied(&client, command::FREEZE_ADAPTATION, 1);
    watch.until("2000 frozen samples", t, |w| {
        w.last_seq > frozen_at + 2_000 && w.flags & live_flags::ADAPTATION_FROZEN != 0
    });
    let frozen: Vec<f64> = watch
        .points
        .iter()
        .filter(|p| p.seq >= frozen_at)
        .map(|p| p.theta_norm)
        .collect();
    assert!(frozen.len() > 1_000, "{} points", frozen.len());
    assert!(
        frozen.iter().all(|v| *v == frozen[0]),
        "θ changed while frozen"
    );

    // A tunable within its declared bounds is set; outside them, or undeclared, refused.
    let reply = send(&client, OperatorRequest::set_tunable("alpha", 0.25, 2));
    assert_eq!(reply.outcome, outcome::APPLIED, "{}", reply.message());
    assert_eq!(reply.value, 0.25);
    let reply = send(&client, OperatorRequest::set_tunable("alpha", 5.0, 3));
    assert_eq!(reply.outcome, outcome::REFUSED);
    assert!(reply.message().contains("[0.1, 1]"), "{}", reply.message());
    let reply = send(&client, OperatorRequest::set_tunable("lambda", 0.5, 4));
    assert_eq!(reply.outcome, outcome::REFUSED);
    assert!(reply.message().contains("'lambda'"), "{}", reply.message());

    // Resumed: θ moves again.
    let resumed_at = applied(&client, command::RESUME_ADAPTATION, 5);
    watch.until("2000 adapting samples", t, |w| {
        w.last_seq > resumed_at + 2_000
    });
    assert_eq!(watch.tunable, 0.25);
    let after: Vec<f64> = watch
        .points
        .iter()
        .filter(|p| p.seq >= resumed_at)
        .map(|p| p.theta_norm)
        .collect();
    assert!(after.iter().any(|v| *v != frozen[0]), "θ did not move");

    // The safe state: the safe input, flagged, until the operator releases it.
    let safe_at = applied(&client, command::ENTER_SAFE_STATE, 6);
    watch.until("500 safe samples", t, |w| w.last_seq > safe_at + 500);
    let left_at = applied(&client, command::LEAVE_SAFE_STATE, 7);
    watch.until("samples after the safe state", t, |w| {
        w.last_seq > left_at + 500
    });
    for p in watch
        .points
        .iter()
        .filter(|p| p.seq > safe_at && p.seq < left_at)
    {
        assert_ne!(p.status & actuation_status::SAFE_STATE, 0, "seq {}", p.seq);
        assert_eq!(p.u[0], 0.0, "seq {}", p.seq);
    }
    assert!(
        watch
            .points
            .iter()
            .any(|p| p.seq > left_at && p.status & actuation_status::SAFE_STATE == 0)
    );

    // Stop: the run ends with its report, and the plant is left without a service.
    applied(&client, command::STOP_RUN, 8);
    service.wait(Duration::from_secs(60));
    plant.signal(libc::SIGTERM);
    plant.wait(Duration::from_secs(60));
    watch.until("the last frame", t, |w| w.state == run_state::ENDED);

    let report: Value = read_json(&folder.join("report.json"));
    assert_eq!(report["stop_reason"], Value::String("operator".into()));
    let commands = report["operator_commands"].as_array().unwrap();
    let outcomes: Vec<(&str, &str)> = commands
        .iter()
        .map(|c| {
            (
                c["command"].as_str().unwrap(),
                c["outcome"].as_str().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        outcomes,
        [
            ("freeze-adaptation", "applied"),
            ("set-tunable", "applied"),
            ("set-tunable", "refused"),
            ("set-tunable", "refused"),
            ("resume-adaptation", "applied"),
            ("enter-safe-state", "applied"),
            ("leave-safe-state", "applied"),
            ("stop-run", "applied"),
        ]
    );
    assert_eq!(commands[0]["before_seq"].as_u64(), Some(frozen_at));
    assert!(report["adaptation"]["frozen"].as_u64().unwrap() >= 2_000);
    assert_eq!(report["stats"]["commands_applied"].as_u64(), Some(6));

    // The record holds the six commands the loop applied; the replay applies them at the
    // same samples and gives every actuation bit for bit.
    let out = std::process::Command::new(bin("service"))
        .arg("replay")
        .arg(&folder)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert_eq!(out.status.code(), Some(0), "{text}");
    assert!(text.contains("6 operator commands"), "{text}");
    assert!(
        text.lines().any(|l| l.starts_with("replay: EQUAL")),
        "{text}"
    );
}
