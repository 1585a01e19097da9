//! Operator commands through `rig monitor --allow-commands` (`POST /api/command`) and
//! `rig command`, answered by a fake operator server standing in for the service.

mod monitor_support;

use ipc_types::operator::{OperatorReply, OperatorRequest, OperatorServer, command, outcome};
use monitor_support::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

/// A thread that answers rig `rig`'s operator requests: `set-tunable` of `alpha` within
/// [0, 1] applies, everything else applies too except `stop-run`, which it refuses.
struct FakeOperator {
    stop: Arc<AtomicBool>,
    seen: Arc<Mutex<Vec<OperatorRequest>>>,
    thread: Option<JoinHandle<()>>,
}

impl FakeOperator {
    fn start(rig: &str) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let seen = Arc::new(Mutex::new(Vec::new()));
        let (s, log, rig) = (stop.clone(), seen.clone(), rig.to_string());
        let (ready_tx, ready_rx) = std::sync::mpsc::channel();
        let thread = std::thread::spawn(move || {
            // iceoryx2 ports stay on the thread that made them.
            let server = match OperatorServer::create(&rig) {
                Ok(s) => s,
                Err(e) => {
                    let _ = ready_tx.send(Err(e.to_string()));
                    return;
                }
            };
            let _ = ready_tx.send(Ok(()));
            while !s.load(Ordering::Relaxed) {
                while let Some(p) = server.receive() {
                    let r = p.request();
                    log.lock().unwrap().push(r);
                    let mut reply = match r.command {
                        command::STOP_RUN => {
                            OperatorReply::new(r.request_id, outcome::REFUSED, "not in this test")
                        }
                        command::SET_TUNABLE if r.tunable() != "alpha" => {
                            OperatorReply::new(r.request_id, outcome::REFUSED, "unknown tunable")
                        }
                        command::SET_TUNABLE if !(0.0..=1.0).contains(&r.value) => {
                            OperatorReply::new(
                                r.request_id,
                                outcome::REFUSED,
                                "out of bounds [0, 1]",
                            )
                        }
                        _ => OperatorReply::new(r.request_id, outcome::APPLIED, ""),
                    };
                    if reply.outcome == outcome::APPLIED {
                        reply.applied_before_seq = 1234;
                        if r.command == command::SET_TUNABLE {
                            reply.value = r.value;
                        }
                    }
                    p.reply(&reply);
                }
                std::thread::sleep(Duration::from_millis(1));
            }
        });
        match ready_rx.recv() {
            Ok(Ok(())) => {}
            Ok(Err(e)) => panic!("operator server: {e}"),
            Err(_) => panic!("the operator thread ended"),
        }
        Self {
            stop,
            seen,
            thread: Some(thread),
        }
    }

    fn seen(&self) -> Vec<OperatorRequest> {
        self.seen.lock().unwrap().clone()
    }
}

impl Drop for FakeOperator {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[test]
fn without_the_flag_nothing_reaches_the_service() {
    let rig = unique_rig("cmd-off");
    let op = FakeOperator::start(&rig);
    let m = MonitorProcess::start(&["--rig", &rig]);
    let body = format!(r#"{{"rig": "{rig}", "command": "enter-safe-state"}}"#);
    let r = post_json(m.http, "/api/command", &body);
    assert_eq!(r.status, 403);
    assert!(op.seen().is_empty());
    assert!(m.stop().success());
}

#[test]
fn with_the_flag_commands_are_forwarded_and_replies_returned() {
    let rig = unique_rig("cmd-on");
    let op = FakeOperator::start(&rig);
    let m = MonitorProcess::start(&["--rig", &rig, "--allow-commands"]);
    assert_eq!(
        get(m.http, "/api/state").json()["monitor"]["commands_allowed"],
        true
    );

    let r = post_json(
        m.http,
        "/api/command",
        &format!(r#"{{"rig": "{rig}", "command": "freeze-adaptation"}}"#),
    );
    assert_eq!(r.status, 200, "{}", r.body);
    let j = r.json();
    assert_eq!(j["outcome"], "applied");
    assert_eq!(j["applied"], true);
    assert_eq!(j["applied_before_seq"], 1234);
    assert_eq!(j["command"], "freeze-adaptation");

    let r = post_json(
        m.http,
        "/api/command",
        &format!(
            r#"{{"rig": "{rig}", "command": "set-tunable", "tunable": "alpha", "value": 0.3}}"#
        ),
    );
    let j = r.json();
    assert_eq!(
        (j["outcome"].as_str(), j["value"].as_f64()),
        (Some("applied"), Some(0.3))
    );

    let r = post_json(
        m.http,
        "/api/command",
        &format!(r#"{{"rig": "{rig}", "command": "set-tunable", "tunable": "alpha", "value": 7}}"#),
    );
    let j = r.json();
    assert_eq!(r.status, 200);
    assert_eq!(j["outcome"], "refused");
    assert_eq!(j["applied"], false);
    assert_eq!(j["message"], "out of bounds [0, 1]");
    assert_eq!(j["applied_before_seq"], serde_json::Value::Null);

    let seen = op.seen();
    assert_eq!(seen.len(), 3);
    assert_eq!(seen[0].command, command::FREEZE_ADAPTATION);
    assert_eq!((seen[1].tunable(), seen[1].value), ("alpha", 0.3));

    // Malformed commands never reach the service.
    for (body, status, words) in [
        ("{not json".to_string(), 400, "bad command"),
        (
            format!(r#"{{"rig": "{rig}"}}"#),
            400,
            "missing field `command`",
        ),
        (
            format!(r#"{{"rig": "{rig}", "command": "reboot"}}"#),
            400,
            "unknown command 'reboot'",
        ),
        (
            format!(r#"{{"rig": "{rig}", "command": "set-tunable", "tunable": "alpha"}}"#),
            400,
            "needs a value",
        ),
        (
            r#"{"rig": "other", "command": "stop-run"}"#.to_string(),
            404,
            "not monitored",
        ),
    ] {
        let r = post_json(m.http, "/api/command", &body);
        assert_eq!(r.status, status, "{body}: {}", r.body);
        assert!(
            r.json()["error"].as_str().unwrap().contains(words),
            "{body}: {}",
            r.body
        );
    }
    let r = request(
        m.http,
        "POST",
        "/api/command",
        &[("Content-Type", "text/plain")],
        "{}",
    );
    assert_eq!(r.status, 415);
    let r = request(
        m.http,
        "POST",
        "/api/command",
        &[
            ("Content-Type", "application/json"),
            ("Origin", "http://evil.example"),
        ],
        &format!(r#"{{"rig": "{rig}", "command": "stop-run"}}"#),
    );
    assert_eq!(r.status, 403);
    assert_eq!(op.seen().len(), 3);
    assert!(m.stop().success());
}

#[test]
fn a_command_to_a_rig_without_a_service_is_a_503() {
    let rig = unique_rig("cmd-none");
    let m = MonitorProcess::start(&["--rig", &rig, "--allow-commands"]);
    let r = post_json(
        m.http,
        "/api/command",
        &format!(r#"{{"rig": "{rig}", "command": "leave-safe-state"}}"#),
    );
    assert_eq!(r.status, 503, "{}", r.body);
    assert!(
        r.json()["error"]
            .as_str()
            .unwrap()
            .contains(&format!("rig '{rig}'"))
    );
    assert!(m.stop().success());
}

#[test]
fn rig_command_prints_the_reply_and_exits_zero_only_when_applied() {
    let rig = unique_rig("cli");
    let _op = FakeOperator::start(&rig);
    let run = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_rig"))
            .args(["command", "--rig", &rig])
            .args(args)
            .output()
            .unwrap()
    };
    let out = run(&["set-tunable", "--tunable", "alpha", "--value", "0.5"]);
    assert_eq!(out.status.code(), Some(0));
    assert_eq!(
        String::from_utf8_lossy(&out.stdout).trim(),
        format!("{rig}: set-tunable: applied before sample 1234, value 0.5")
    );
    let out = run(&["stop-run"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stdout).contains("refused: not in this test"));
    let out = run(&["jump"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown command 'jump'"));
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_rig"))
        .args([
            "command",
            "--rig",
            &unique_rig("cli-none"),
            "stop-run",
            "--timeout",
            "0.5",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("is it running?"));
}
