//! The monitor's HTTP routes (axum):
//!
//! | route | what |
//! |---|---|
//! | `GET /` | the web page ([`super::page`]) |
//! | `GET /page.js` | its script |
//! | `GET /api/state` | every rig's state as JSON ([`StateView`]) |
//! | `GET /api/points?rig=R&since=SEQ&max=N` | the rig's points after sample `SEQ` ([`PointsView`]) |
//! | `POST /api/command` | an operator command `{rig, command, tunable?, value?}` → the reply ([`CommandReply`]) |
//! | `GET /metrics` | Prometheus text format ([`super::metrics`]) |
//!
//! Every error is JSON `{"error": "..."}` with a status that says whose fault it is: 400 a
//! malformed query or body, 403 commands not allowed (`--allow-commands` not given, or a
//! request from a page of another origin), 404 an unknown rig or route, 415 a command
//! that is not `application/json`, 502/503/504 when the service could not be reached or
//! did not answer.

use super::commands::{self, CommandReply, CommandRequest};
use super::metrics;
use super::page;
use super::snapshot::{MonitorView, PointsView, StateView, now_unix_ms};
use super::state::{Hub, POINT_RING, STALE_AFTER};
use axum::Router;
use axum::body::Bytes;
use axum::extract::{Query, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::{get, post};
use ipc_types::operator::OperatorError;
use prometheus_client::registry::Registry;
use std::collections::HashMap;
use std::sync::Arc;
use std::time::Duration;

/// What the routes share.
#[derive(Clone)]
pub struct AppState {
    /// Every rig's state.
    pub hub: Arc<Hub>,
    /// Whether commands are forwarded (`--allow-commands`).
    pub allow_commands: bool,
    /// The Foxglove server's address, when there is one.
    pub foxglove: Option<String>,
    /// The registry `/metrics` encodes.
    pub registry: Arc<Registry>,
    /// How long a command waits for its reply.
    pub command_timeout: Duration,
}

impl core::fmt::Debug for AppState {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("AppState")
            .field("rigs", &self.hub.names())
            .field("allow_commands", &self.allow_commands)
            .finish()
    }
}

impl AppState {
    fn monitor_view(&self) -> MonitorView {
        MonitorView {
            version: env!("CARGO_PKG_VERSION"),
            commands_allowed: self.allow_commands,
            foxglove: self.foxglove.clone(),
            now_unix_ms: now_unix_ms(),
            stale_after_s: STALE_AFTER.as_secs_f64(),
        }
    }
}

/// The router of every route.
pub fn router(state: AppState) -> Router {
    Router::new()
        .route("/", get(index))
        .route("/page.js", get(script))
        .route("/api/state", get(api_state))
        .route("/api/points", get(api_points))
        .route("/api/command", post(api_command))
        .route("/metrics", get(metrics_text))
        .fallback(not_found)
        .with_state(state)
}

/// A JSON error reply.
fn error(status: StatusCode, message: impl Into<String>) -> Response {
    let body = serde_json::json!({ "error": message.into() });
    (status, no_store(), axum::Json(body)).into_response()
}

fn no_store() -> [(header::HeaderName, HeaderValue); 1] {
    [(header::CACHE_CONTROL, HeaderValue::from_static("no-store"))]
}

fn json<T: serde::Serialize>(value: &T) -> Response {
    match serde_json::to_vec(value) {
        Ok(body) => (
            no_store(),
            [(
                header::CONTENT_TYPE,
                HeaderValue::from_static("application/json"),
            )],
            body,
        )
            .into_response(),
        Err(e) => error(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("encoding the reply: {e}"),
        ),
    }
}

async fn index() -> Html<&'static str> {
    Html(page::HTML)
}

async fn script() -> Response {
    (
        [(
            header::CONTENT_TYPE,
            HeaderValue::from_static("text/javascript; charset=utf-8"),
        )],
        page::SCRIPT,
    )
        .into_response()
}

async fn not_found() -> Response {
    error(
        StatusCode::NOT_FOUND,
        "no such route (see /, /api/state, /api/points, /api/command, /metrics)",
    )
}

async fn api_state(State(s): State<AppState>) -> Response {
    json(&StateView::of(&s.hub, s.monitor_view()))
}

/// The rig a request names: `rig` when given, else the only rig; or the status and
/// message of the error.
fn rig_index(hub: &Hub, rig: Option<&str>) -> Result<usize, (StatusCode, String)> {
    match rig {
        Some(r) => hub.index(r).ok_or_else(|| {
            (
                StatusCode::NOT_FOUND,
                format!(
                    "rig '{r}' is not monitored (monitored: {})",
                    hub.names().join(", ")
                ),
            )
        }),
        None if hub.names().len() == 1 => Ok(0),
        None => Err((
            StatusCode::BAD_REQUEST,
            format!(
                "name the rig: ?rig=NAME (monitored: {})",
                hub.names().join(", ")
            ),
        )),
    }
}

async fn api_points(
    State(s): State<AppState>,
    Query(q): Query<HashMap<String, String>>,
) -> Response {
    let i = match rig_index(&s.hub, q.get("rig").map(String::as_str)) {
        Ok(i) => i,
        Err((status, message)) => return error(status, message),
    };
    let since = match q.get("since").map(String::as_str) {
        None | Some("") => None,
        Some(v) => match v.parse::<u64>() {
            Ok(v) => Some(v),
            Err(_) => {
                return error(
                    StatusCode::BAD_REQUEST,
                    format!("since={v}: not a sample index (a whole number ≥ 0)"),
                );
            }
        },
    };
    let max = match q.get("max").map(String::as_str) {
        None | Some("") => POINT_RING,
        Some(v) => match v.parse::<usize>() {
            Ok(v) => v.min(POINT_RING),
            Err(_) => {
                return error(
                    StatusCode::BAD_REQUEST,
                    format!("max={v}: not a count (a whole number ≥ 0)"),
                );
            }
        },
    };
    let view = PointsView::of(&s.hub.lock(i), since, max);
    json(&view)
}

async fn metrics_text(State(s): State<AppState>) -> Response {
    match metrics::render(&s.registry) {
        Ok(text) => (
            [(
                header::CONTENT_TYPE,
                HeaderValue::from_static(metrics::CONTENT_TYPE),
            )],
            text,
        )
            .into_response(),
        Err(_) => error(
            StatusCode::INTERNAL_SERVER_ERROR,
            "encoding the metrics failed",
        ),
    }
}

/// Whether the request came from a page of another origin than this server (a browser
/// sends `Origin` with a cross-origin POST; a script or curl sends none).
fn cross_origin(headers: &HeaderMap) -> bool {
    let Some(origin) = headers.get(header::ORIGIN).and_then(|v| v.to_str().ok()) else {
        return false;
    };
    let host = headers
        .get(header::HOST)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("");
    let origin_host = origin
        .split_once("://")
        .map(|(_, rest)| rest)
        .unwrap_or(origin);
    origin_host != host
}

async fn api_command(State(s): State<AppState>, headers: HeaderMap, body: Bytes) -> Response {
    if !s.allow_commands {
        return error(
            StatusCode::FORBIDDEN,
            "commands are disabled: this monitor was started without --allow-commands",
        );
    }
    if cross_origin(&headers) {
        return error(
            StatusCode::FORBIDDEN,
            "a command from a page of another origin is refused",
        );
    }
    let is_json = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.trim_start().starts_with("application/json"));
    if !is_json {
        return error(
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            "a command is JSON: send it with Content-Type: application/json",
        );
    }
    let req: CommandRequest = match serde_json::from_slice(&body) {
        Ok(r) => r,
        Err(e) => {
            return error(
                StatusCode::BAD_REQUEST,
                format!(
                    "bad command: {e} (expected {{\"rig\": NAME, \"command\": NAME, \"tunable\"?: NAME, \"value\"?: NUMBER}})"
                ),
            );
        }
    };
    if let Err((status, message)) = rig_index(&s.hub, Some(&req.rig)) {
        return error(status, message);
    }
    let request = match req.to_request(commands::next_request_id()) {
        Ok(r) => r,
        Err(e) => return error(StatusCode::BAD_REQUEST, format!("bad command: {e}")),
    };
    let rig = req.rig.clone();
    let timeout = s.command_timeout;
    let sent = tokio::task::spawn_blocking(move || {
        commands::send(&rig, &request, timeout).map(|r| (request, r))
    })
    .await;
    match sent {
        Ok(Ok((request, reply))) => json(&CommandReply::of(&req.rig, &request, &reply)),
        Ok(Err(e)) => {
            let status = match e {
                OperatorError::NoService { .. } => StatusCode::SERVICE_UNAVAILABLE,
                OperatorError::Timeout { .. } => StatusCode::GATEWAY_TIMEOUT,
                OperatorError::Connect(_) | OperatorError::Send(_) => StatusCode::BAD_GATEWAY,
            };
            error(status, format!("rig '{}': {}: {e}", req.rig, req.command))
        }
        Err(e) => error(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("rig '{}': the command's task failed: {e}", req.rig),
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_a_foreign_origin_counts_as_cross_origin() {
        let mut h = HeaderMap::new();
        h.insert(header::HOST, HeaderValue::from_static("127.0.0.1:9187"));
        assert!(!cross_origin(&h));
        h.insert(
            header::ORIGIN,
            HeaderValue::from_static("http://127.0.0.1:9187"),
        );
        assert!(!cross_origin(&h));
        h.insert(
            header::ORIGIN,
            HeaderValue::from_static("https://example.org"),
        );
        assert!(cross_origin(&h));
    }
}
