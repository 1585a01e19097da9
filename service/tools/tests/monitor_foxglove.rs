//! `rig monitor --foxglove`: a WebSocket client speaking Foxglove's protocol sees the
//! advertised channels, receives the messages of the channels it subscribes to, and reads
//! the declared tunables as parameters (which it may not set without `--allow-commands`).
//!
//! The Foxglove SDK (0.30) negotiates the subprotocol `foxglove.sdk.v1` (or `v1.1`), the
//! successor of `foxglove.websocket.v1`, whose framing it keeps; a client offering only the
//! old name is refused at the handshake, which the test pins down too.

mod monitor_support;

use futures_util::{SinkExt, StreamExt};
use monitor_support::*;
use serde_json::{Value, json};
use std::collections::HashMap;
use std::time::Duration;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::tungstenite::http::HeaderValue;

type Ws =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

/// The next message from the server (panics after 30 s).
async fn next(ws: &mut Ws) -> Message {
    match tokio::time::timeout(Duration::from_secs(30), ws.next()).await {
        Ok(Some(Ok(m))) => m,
        other => panic!("no message from the Foxglove server: {other:?}"),
    }
}

/// Reads until a JSON message with `op` comes, and returns it.
async fn next_op(ws: &mut Ws, op: &str) -> Value {
    loop {
        if let Message::Text(t) = next(ws).await {
            let v: Value = serde_json::from_str(&t).expect("JSON");
            if v["op"] == op {
                return v;
            }
        }
    }
}

/// Reads until a binary message of subscription `sub` comes, and returns its payload.
async fn next_message(ws: &mut Ws, sub: u32) -> Value {
    loop {
        if let Message::Binary(b) = next(ws).await {
            // opcode 1 (message data), u32 subscription id, u64 log time, payload.
            if b.first() == Some(&1) && u32::from_le_bytes(b[1..5].try_into().unwrap()) == sub {
                return serde_json::from_slice(&b[13..]).expect("a JSON payload");
            }
        }
    }
}

#[tokio::test(flavor = "current_thread")]
async fn a_foxglove_client_sees_the_channels_messages_and_parameters() {
    let rig = unique_rig("fox");
    let service = FakeService::start(&rig, 77);
    let m = MonitorProcess::start(&["--rig", &rig, "--foxglove", "127.0.0.1:0"]);
    let http = m.http;
    let r2 = rig.clone();
    tokio::task::spawn_blocking(move || {
        wait_for("a live rig with its info", || {
            let s = rig_state(http, &r2);
            (s["connection"] == "live" && s["info"]["current"] == true).then_some(())
        })
    })
    .await
    .unwrap();
    assert_eq!(
        get(m.http, "/api/state").json()["monitor"]["foxglove"],
        m.foxglove.unwrap().to_string()
    );

    let request = |protocol: &'static str| {
        let mut req = format!("ws://{}", m.foxglove.unwrap())
            .into_client_request()
            .unwrap();
        req.headers_mut()
            .insert("Sec-WebSocket-Protocol", HeaderValue::from_static(protocol));
        req
    };
    // The old name alone is refused with 400.
    let old = tokio_tungstenite::connect_async(request("foxglove.websocket.v1")).await;
    assert!(
        matches!(&old, Err(tokio_tungstenite::tungstenite::Error::Http(r)) if r.status() == 400),
        "{old:?}"
    );
    let (mut ws, resp) = tokio_tungstenite::connect_async(request("foxglove.sdk.v1"))
        .await
        .expect("WebSocket connect");
    assert_eq!(
        resp.headers().get("sec-websocket-protocol").unwrap(),
        "foxglove.sdk.v1"
    );

    let info = next_op(&mut ws, "serverInfo").await;
    assert_eq!(info["name"], "rig monitor");
    assert!(
        info["capabilities"]
            .as_array()
            .unwrap()
            .contains(&json!("parameters"))
    );

    // Every channel of the rig is advertised (perhaps over several messages).
    let mut topics: HashMap<String, u64> = HashMap::new();
    let want = [
        "z",
        "u",
        "theta_norm",
        "counters",
        "latency",
        "tones",
        "status",
    ];
    while !want
        .iter()
        .all(|t| topics.contains_key(&format!("/{rig}/{t}")))
    {
        let adv = next_op(&mut ws, "advertise").await;
        for c in adv["channels"].as_array().unwrap() {
            assert_eq!(c["encoding"], "json");
            assert_eq!(c["schemaEncoding"], "jsonschema");
            topics.insert(
                c["topic"].as_str().unwrap().to_string(),
                c["id"].as_u64().unwrap(),
            );
        }
    }

    let sub = |id: u32, topic: &str| json!({ "op": "subscribe", "subscriptions": [{ "id": id, "channelId": topics[&format!("/{rig}/{topic}")] }] });
    ws.send(Message::text(sub(7, "counters").to_string()))
        .await
        .unwrap();
    let counters = next_message(&mut ws, 7).await;
    assert_eq!(counters["deadline_misses"], 13);
    assert_eq!(counters["run_id"], 77);
    assert!(counters["timestamp"]["sec"].as_u64().unwrap() > 1_600_000_000);
    ws.send(Message::text(sub(8, "z").to_string()))
        .await
        .unwrap();
    let z = next_message(&mut ws, 8).await;
    assert_eq!(z["z"].as_array().unwrap().len(), 2);
    assert_eq!(z["z"][1], 0.5);
    ws.send(Message::text(sub(9, "status").to_string()))
        .await
        .unwrap();
    let status = next_message(&mut ws, 9).await;
    assert_eq!(status["verdict"], "failed");
    assert_eq!(status["flags"]["adaptation_frozen"], true);

    // Parameters: read, and a refused set.
    let get_params = json!({ "op": "getParameters", "parameterNames": [], "id": "g1" });
    ws.send(Message::text(get_params.to_string()))
        .await
        .unwrap();
    let values = next_op(&mut ws, "parameterValues").await;
    assert_eq!(values["id"], "g1");
    let alpha = format!("{rig}/alpha");
    let p = values["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == alpha.as_str())
        .cloned();
    assert_eq!(p.expect("the tunable")["value"], 0.25);

    let set = json!({ "op": "setParameters", "parameters": [{ "name": alpha, "value": 0.5 }], "id": "s1" });
    ws.send(Message::text(set.to_string())).await.unwrap();
    let status = next_op(&mut ws, "status").await;
    assert!(
        status["message"]
            .as_str()
            .unwrap()
            .contains("--allow-commands"),
        "{status}"
    );
    let values = next_op(&mut ws, "parameterValues").await;
    assert_eq!(values["id"], "s1");
    assert_eq!(values["parameters"][0]["value"], 0.25, "unchanged");

    ws.close(None).await.ok();
    service.stop();
    assert!(m.stop().success());
}
