//! `--foxglove ADDR`: the rigs' telemetry on Foxglove's WebSocket protocol
//! (`foxglove.websocket.v1`), served by the Foxglove SDK (`foxglove` crate), so that the
//! Foxglove app (Open connection → Foxglove WebSocket → `ws://ADDR`) plots it.
//!
//! Channels, per rig `R`, JSON-encoded with a JSON schema each:
//!
//! | topic | one message per | fields |
//! |---|---|---|
//! | `/R/z` | decimated point | `timestamp`, `seq`, `z` (array) |
//! | `/R/u` | decimated point | `timestamp`, `seq`, `u` (array) |
//! | `/R/theta_norm` | decimated point | `timestamp`, `seq`, `theta_norm` |
//! | `/R/counters` | frame | `timestamp`, `run_id`, every counter of the run report |
//! | `/R/latency` | frame | `timestamp`, per histogram `count`, `p50_us` … `p999_us`, `max_us`, `mean_us` |
//! | `/R/tones` | frame | `timestamp`, `window_samples`, `tones[]` (`hz`, `amplitude`, `open_loop`, `suppression_db`) |
//! | `/R/status` | frame | `timestamp`, `run_id`, `run_state`, `verdict`, `verdict_text`, `last_seq`, `flags` |
//!
//! `timestamp` is `{sec, nsec}` Unix time (the sample's time for a point, the frame's
//! publication time otherwise), and each message's log time is the same. Messages are
//! encoded only while a client subscribes to their channel.
//!
//! The declared tunables are Foxglove parameters named `R/NAME` (float64). Getting them
//! reads the newest frame; setting one sends the operator command `set-tunable` when the
//! monitor runs with `--allow-commands` (the reply's value is what the app then shows, and a
//! refusal is sent to the app as a warning), and is refused with an error message
//! otherwise. When a tunable's value changes in the frames, the new value is published to
//! the app.

use super::commands::{self, CommandRequest};
use super::counters;
use super::reader::FrameObserver;
use super::snapshot::{FlagsView, finite, suppression_db};
use super::state::{Hub, run_state_name, verdict_name};
use ::foxglove::remote_common::{
    AnyClient, GetParametersResponder, Parameter, ParameterHandler, ParameterValue,
    SetParametersResponder,
};
use ::foxglove::{
    Context, PartialMetadata, RawChannel, Schema, WebSocketServer, WebSocketServerHandle,
};
use ipc_types::telemetry::{MAX_TONES, TelemetryFrame, TelemetryInfo, latency_index};
use serde_json::{Value, json};
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The server's handle, shared with the parameter handler (`None` before the start and
/// after the stop).
type Shared = Arc<Mutex<Option<WebSocketServerHandle>>>;

fn with_server(server: &Shared, f: impl FnOnce(&WebSocketServerHandle)) {
    let guard = server.lock().unwrap_or_else(|p| p.into_inner());
    if let Some(h) = guard.as_ref() {
        f(h);
    }
}

/// The channels of one rig.
struct RigChannels {
    z: Arc<RawChannel>,
    u: Arc<RawChannel>,
    theta: Arc<RawChannel>,
    counters: Arc<RawChannel>,
    latency: Arc<RawChannel>,
    tones: Arc<RawChannel>,
    status: Arc<RawChannel>,
}

/// The Foxglove side of the monitor: its server, its channels, its parameters.
pub struct FoxgloveBridge {
    /// The context binding the channels to the server's clients; dropping it would
    /// disconnect them.
    _context: Arc<Context>,
    hub: Arc<Hub>,
    channels: Vec<RigChannels>,
    server: Shared,
    /// The tunable values last published to the app, per rig.
    published: Mutex<Vec<Vec<f64>>>,
    addr: SocketAddr,
}

impl core::fmt::Debug for FoxgloveBridge {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("FoxgloveBridge")
            .field("addr", &self.addr)
            .finish()
    }
}

/// A `{sec, nsec}` time of Unix nanoseconds (0 before the epoch).
fn timestamp(unix_ns: i128) -> Value {
    let ns = unix_ns.max(0);
    json!({ "sec": (ns / 1_000_000_000) as u64, "nsec": (ns % 1_000_000_000) as u32 })
}

fn schema(name: &str, properties: Value) -> Schema {
    let doc = json!({
        "type": "object",
        "properties": properties,
    });
    Schema::new(
        name,
        "jsonschema",
        serde_json::to_vec(&doc).unwrap_or_default(),
    )
}

fn time_schema() -> Value {
    json!({
        "type": "object",
        "title": "time",
        "properties": { "sec": { "type": "integer", "minimum": 0 }, "nsec": { "type": "integer", "minimum": 0 } }
    })
}

fn number_array() -> Value {
    json!({ "type": "array", "items": { "type": ["number", "null"] } })
}

fn schemas() -> [(&'static str, Schema); 7] {
    let hist = json!({
        "type": "object",
        "properties": {
            "count": { "type": "integer" },
            "p50_us": { "type": "number" }, "p90_us": { "type": "number" },
            "p99_us": { "type": "number" }, "p999_us": { "type": "number" },
            "max_us": { "type": "number" }, "mean_us": { "type": ["number", "null"] }
        }
    });
    let mut counter_props = serde_json::Map::new();
    counter_props.insert("timestamp".into(), time_schema());
    counter_props.insert("run_id".into(), json!({ "type": "integer" }));
    for c in counters::COUNTERS {
        counter_props.insert(
            c.name.into(),
            json!({ "type": "integer", "description": c.help }),
        );
    }
    [
        (
            "z",
            schema(
                "adaptive_rig.Z",
                json!({ "timestamp": time_schema(), "seq": { "type": "integer" }, "z": number_array() }),
            ),
        ),
        (
            "u",
            schema(
                "adaptive_rig.U",
                json!({ "timestamp": time_schema(), "seq": { "type": "integer" }, "u": number_array() }),
            ),
        ),
        (
            "theta_norm",
            schema(
                "adaptive_rig.ThetaNorm",
                json!({ "timestamp": time_schema(), "seq": { "type": "integer" },
                        "theta_norm": { "type": ["number", "null"] } }),
            ),
        ),
        (
            "counters",
            schema("adaptive_rig.Counters", Value::Object(counter_props)),
        ),
        (
            "latency",
            schema(
                "adaptive_rig.Latency",
                json!({ "timestamp": time_schema(), "wakeup": hist, "compute": hist,
                        "response": hist, "jitter": hist }),
            ),
        ),
        (
            "tones",
            schema(
                "adaptive_rig.Tones",
                json!({
                    "timestamp": time_schema(),
                    "window_samples": { "type": "integer" },
                    "tones": { "type": "array", "items": { "type": "object", "properties": {
                        "hz": { "type": "number" }, "amplitude": number_array(),
                        "open_loop": number_array(), "suppression_db": number_array() } } }
                }),
            ),
        ),
        (
            "status",
            schema(
                "adaptive_rig.Status",
                json!({
                    "timestamp": time_schema(), "run_id": { "type": "integer" },
                    "run_state": { "type": "string" }, "verdict": { "type": "string" },
                    "verdict_text": { "type": "string" }, "last_seq": { "type": "integer" },
                    "flags": { "type": "object", "additionalProperties": { "type": "boolean" } }
                }),
            ),
        ),
    ]
}

impl FoxgloveBridge {
    /// Builds every rig's channels and starts the server on `addr` (port 0: any free
    /// port); call it inside the tokio runtime that is to serve it.
    ///
    /// # Errors
    ///
    /// A channel could not be made, or the server could not bind `addr`.
    pub async fn start(
        hub: Arc<Hub>,
        addr: SocketAddr,
        allow_commands: bool,
        command_timeout: Duration,
    ) -> Result<Arc<Self>, String> {
        let ctx = Context::new();
        let mut channels = Vec::new();
        for rig in hub.names() {
            let mut built = Vec::new();
            for (topic, schema) in schemas() {
                let ch = ctx
                    .channel_builder(format!("/{rig}/{topic}"))
                    .message_encoding("json")
                    .schema(schema)
                    .build_raw()
                    .map_err(|e| format!("foxglove: channel /{rig}/{topic}: {e}"))?;
                built.push(ch);
            }
            let mut it = built.into_iter();
            let mut next = || {
                it.next()
                    .ok_or("foxglove: a channel is missing".to_string())
            };
            channels.push(RigChannels {
                z: next()?,
                u: next()?,
                theta: next()?,
                counters: next()?,
                latency: next()?,
                tones: next()?,
                status: next()?,
            });
        }
        let server: Shared = Arc::new(Mutex::new(None));
        let params = Arc::new(Params {
            hub: hub.clone(),
            allow_commands,
            command_timeout,
            runtime: tokio::runtime::Handle::current(),
            server: server.clone(),
        });
        let handle = WebSocketServer::new()
            .name("rig monitor")
            .bind(addr.ip().to_string(), addr.port())
            .context(&ctx)
            .parameter_handler(params)
            .start()
            .await
            .map_err(|e| format!("foxglove: serving on {addr}: {e}"))?;
        let bound = SocketAddr::new(addr.ip(), handle.port());
        *server.lock().unwrap_or_else(|p| p.into_inner()) = Some(handle);
        let n = hub.names().len();
        Ok(Arc::new(Self {
            _context: ctx,
            hub,
            channels,
            server,
            published: Mutex::new(vec![Vec::new(); n]),
            addr: bound,
        }))
    }

    /// The address the server listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Stops the server and waits until it closed its connections.
    pub async fn stop(&self) {
        let handle = self.server.lock().unwrap_or_else(|p| p.into_inner()).take();
        if let Some(h) = handle {
            h.stop().wait().await;
        }
    }

    fn log(ch: &RawChannel, msg: &Value, unix_ns: i128) {
        if let Ok(bytes) = serde_json::to_vec(msg) {
            let t = u64::try_from(unix_ns.max(0)).unwrap_or(0);
            ch.log_with_meta(&bytes, PartialMetadata::with_log_time(t));
        }
    }

    fn publish_changed_tunables(&self, rig: usize, frame: &TelemetryFrame) {
        let params = {
            let s = self.hub.lock(rig);
            match s.current_info() {
                Some(info) => tunable_parameters(&s.rig, frame, info),
                None => return,
            }
        };
        let values: Vec<f64> = frame.tunable_values[..params.len()].to_vec();
        let mut published = self.published.lock().unwrap_or_else(|p| p.into_inner());
        let same = published[rig].len() == values.len()
            && published[rig]
                .iter()
                .zip(&values)
                .all(|(a, b)| a.to_bits() == b.to_bits());
        if !same {
            published[rig] = values;
            drop(published);
            with_server(&self.server, |s| s.publish_parameter_values(params));
        }
    }
}

impl FrameObserver for FoxgloveBridge {
    fn on_frame(&self, rig: usize, f: &TelemetryFrame) {
        let Some(ch) = self.channels.get(rig) else {
            return;
        };
        let off = i128::from(f.unix_minus_monotonic_ns);
        let n_z = usize::from(f.n_z).min(ipc_types::MAX_Z);
        let n_u = usize::from(f.n_u).min(ipc_types::MAX_U);
        let (want_z, want_u, want_th) = (ch.z.has_sinks(), ch.u.has_sinks(), ch.theta.has_sinks());
        if want_z || want_u || want_th {
            for p in f.points() {
                let t = i128::from(p.t_sample_ns) + off;
                let ts = timestamp(t);
                if want_z {
                    let m = json!({ "timestamp": ts.clone(), "seq": p.seq, "z": &p.z[..n_z] });
                    Self::log(&ch.z, &m, t);
                }
                if want_u {
                    let m = json!({ "timestamp": ts.clone(), "seq": p.seq, "u": &p.u[..n_u] });
                    Self::log(&ch.u, &m, t);
                }
                if want_th {
                    let m = json!({ "timestamp": ts, "seq": p.seq, "theta_norm": finite(p.theta_norm) });
                    Self::log(&ch.theta, &m, t);
                }
            }
        }
        let t = i128::from(f.t_publish_ns) + off;
        let ts = timestamp(t);
        if ch.counters.has_sinks() {
            let mut m = serde_json::Map::new();
            m.insert("timestamp".into(), ts.clone());
            m.insert("run_id".into(), json!(f.run_id));
            for (name, v) in counters::pairs(&f.counters) {
                m.insert(name.into(), json!(v));
            }
            Self::log(&ch.counters, &Value::Object(m), t);
        }
        if ch.latency.has_sinks() {
            let mut m = serde_json::Map::new();
            m.insert("timestamp".into(), ts.clone());
            for (k, name) in latency_index::NAMES.iter().enumerate() {
                let s = &f.latency[k];
                let mean = (s.count > 0).then(|| s.sum_ns / s.count as f64 / 1e3);
                m.insert(
                    (*name).into(),
                    json!({
                        "count": s.count,
                        "p50_us": s.p50_ns as f64 / 1e3, "p90_us": s.p90_ns as f64 / 1e3,
                        "p99_us": s.p99_ns as f64 / 1e3, "p999_us": s.p999_ns as f64 / 1e3,
                        "max_us": s.max_ns as f64 / 1e3, "mean_us": mean,
                    }),
                );
            }
            Self::log(&ch.latency, &Value::Object(m), t);
        }
        if ch.tones.has_sinks() {
            let tones: Vec<Value> = (0..(f.tones.n_tones as usize).min(MAX_TONES))
                .map(|i| {
                    let a = &f.tones.amplitude[i][..n_z];
                    let o = &f.tones.open_loop[i][..n_z];
                    json!({
                        "hz": f.tones.hz[i],
                        "amplitude": a.iter().map(|&x| finite(x)).collect::<Vec<_>>(),
                        "open_loop": o.iter().map(|&x| finite(x)).collect::<Vec<_>>(),
                        "suppression_db": a.iter().zip(o).map(|(&now, &open)| suppression_db(open, now)).collect::<Vec<_>>(),
                    })
                })
                .collect();
            let m = json!({ "timestamp": ts.clone(), "window_samples": f.tones.window_samples, "tones": tones });
            Self::log(&ch.tones, &m, t);
        }
        if ch.status.has_sinks() {
            let m = json!({
                "timestamp": ts,
                "run_id": f.run_id,
                "run_state": run_state_name(f.state),
                "verdict": verdict_name(f.verdict),
                "verdict_text": f.verdict_text(),
                "last_seq": f.last_seq,
                "flags": FlagsView::of(f.flags),
            });
            Self::log(&ch.status, &m, t);
        }
        self.publish_changed_tunables(rig, f);
    }

    fn on_info(&self, _rig: usize, _info: &TelemetryInfo) {}
}

/// The parameters (`RIG/NAME`, float64) of rig `rig`'s declared tunables: the value now,
/// or the initial value while the frame has none.
fn tunable_parameters(rig: &str, frame: &TelemetryFrame, info: &TelemetryInfo) -> Vec<Parameter> {
    info.tunables()
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let v = frame
                .tunable_values
                .get(i)
                .copied()
                .and_then(finite)
                .unwrap_or(t.initial);
            Parameter::float64(format!("{rig}/{}", t.name()), v)
        })
        .collect()
}

/// Answers the app's parameter requests.
struct Params {
    hub: Arc<Hub>,
    allow_commands: bool,
    command_timeout: Duration,
    runtime: tokio::runtime::Handle,
    server: Shared,
}

impl Params {
    /// Every rig's tunables as parameters.
    fn all(&self) -> Vec<Parameter> {
        let mut out = Vec::new();
        for i in 0..self.hub.names().len() {
            let s = self.hub.lock(i);
            if let (Some(f), Some(info)) = (s.latest.as_deref(), s.current_info()) {
                out.extend(tunable_parameters(&s.rig, f, info));
            }
        }
        out
    }

    fn named(&self, names: &[String]) -> Vec<Parameter> {
        let all = self.all();
        if names.is_empty() {
            return all;
        }
        all.into_iter()
            .filter(|p| names.contains(&p.name))
            .collect()
    }
}

fn as_f64(v: &Option<ParameterValue>) -> Option<f64> {
    match v {
        Some(ParameterValue::Float64(x)) => Some(*x),
        Some(ParameterValue::Integer(i)) => Some(*i as f64),
        _ => None,
    }
}

/// Sets one parameter `RIG/NAME` through the operator command; returns the value in force
/// afterwards, or why not.
fn set_one(p: &Parameter, hub: &Hub, timeout: Duration) -> Result<f64, String> {
    let (rig, tunable) = p
        .name
        .split_once('/')
        .ok_or_else(|| format!("parameter '{}' is not RIG/TUNABLE", p.name))?;
    if hub.index(rig).is_none() {
        return Err(format!("rig '{rig}' is not monitored"));
    }
    let value = as_f64(&p.value)
        .ok_or_else(|| format!("parameter '{}': the value must be a number", p.name))?;
    let cmd = CommandRequest {
        rig: rig.to_string(),
        command: "set-tunable".into(),
        tunable: Some(tunable.to_string()),
        value: Some(value),
    };
    let request = cmd.to_request(commands::next_request_id())?;
    let reply = commands::send(rig, &request, timeout).map_err(|e| format!("rig '{rig}': {e}"))?;
    let view = commands::CommandReply::of(rig, &request, &reply);
    if view.applied {
        Ok(view.value.unwrap_or(value))
    } else {
        Err(view.line())
    }
}

impl ParameterHandler for Params {
    fn get(
        &self,
        _client: AnyClient,
        names: Vec<String>,
        _request_id: Option<String>,
        responder: GetParametersResponder,
    ) {
        responder.respond(self.named(&names));
    }

    fn set(
        &self,
        client: AnyClient,
        parameters: Vec<Parameter>,
        _request_id: Option<String>,
        responder: SetParametersResponder,
    ) {
        let names: Vec<String> = parameters.iter().map(|p| p.name.clone()).collect();
        if !self.allow_commands {
            client.send_error(
                "rig monitor: tunables are read-only here: start rig monitor with --allow-commands to set them",
            );
            responder.respond(self.named(&names));
            return;
        }
        let hub = self.hub.clone();
        let timeout = self.command_timeout;
        let server = self.server.clone();
        let current = self.named(&names);
        self.runtime.spawn_blocking(move || {
            let mut out = Vec::new();
            for p in &parameters {
                match set_one(p, &hub, timeout) {
                    Ok(v) => out.push(Parameter::float64(p.name.clone(), v)),
                    Err(e) => {
                        client.send_warning(format!("rig monitor: {}: {e}", p.name));
                        if let Some(c) = current.iter().find(|c| c.name == p.name) {
                            out.push(c.clone());
                        }
                    }
                }
            }
            with_server(&server, |s| s.publish_parameter_values(out.clone()));
            responder.respond(out);
        });
    }
}
