// rig monitor page: polls /api/state (4 Hz) and /api/points (20 Hz), draws the scope on
// the next animation frame after new points came (at most two vertices per pixel column
// and channel), and measures the display latency: the newest drawn point's
// sample time (Unix, from the service's clock) against this browser's clock when it is
// first drawn.
"use strict";

const WINDOW_MS = 2000;
const COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf"];
const KEY_COUNTERS = ["deadline_misses", "plant_reported_misses", "max_consecutive_misses", "lost",
  "lost_past_startup", "held_past_startup", "caught_up", "rejected", "safe_state_entries",
  "plant_silent_events", "publish_failures", "telemetry_dropped", "commands_applied", "commands_refused"];

const ui = {
  rig: null,            // the rig shown
  runId: null,          // its run, as /api/points says
  lastSeq: null,        // newest point held
  points: [],           // {t, seq, z, u, th}
  drawnSeq: null,       // newest point drawn
  dirty: true,          // points changed since the last drawing
  latencies: [],        // recent display latencies, ms
  allow: false,
  rigView: null,
};

const $ = (id) => document.getElementById(id);
const text = (id, v) => { const e = $(id); if (e) e.textContent = v; };
const us = (ns) => (ns === null || ns === undefined) ? "–" : (ns / 1000).toFixed(1);

async function getJson(url, opts) {
  const r = await fetch(url, Object.assign({ cache: "no-store" }, opts || {}));
  const body = await r.json().catch(() => ({ error: "reply was not JSON (HTTP " + r.status + ")" }));
  return { ok: r.ok, status: r.status, body };
}

// ---- state (4 Hz) ----
async function pollState() {
  try {
    const { ok, body } = await getJson("/api/state");
    if (ok) renderState(body);
  } catch (e) {
    $("connection").textContent = "monitor unreachable";
    $("connection").className = "badge stale";
  }
  setTimeout(pollState, 250);
}

function renderState(s) {
  ui.allow = s.monitor.commands_allowed;
  const sel = $("rig-select");
  if (sel.options.length !== s.rigs.length) {
    sel.innerHTML = "";
    for (const r of s.rigs) { const o = document.createElement("option"); o.value = o.textContent = r.rig; sel.appendChild(o); }
    $("rig-select-label").hidden = s.rigs.length < 2;
  }
  if (ui.rig === null && s.rigs.length) { ui.rig = s.rigs[0].rig; }
  sel.value = ui.rig;
  const v = s.rigs.find((r) => r.rig === ui.rig);
  if (!v) return;
  ui.rigView = v;
  text("rig-name", v.rig);
  const c = $("connection");
  c.textContent = v.connection + (v.last_frame_age_s !== null && v.connection === "stale" ? ` (${v.last_frame_age_s.toFixed(0)} s)` : "");
  c.className = "badge " + v.connection;
  text("reader-error", v.reader_error || "");
  const run = v.run;
  if (run) {
    text("run-state", run.run_state);
    text("run-id", "#" + run.run_id + " pid " + run.service_pid);
    text("last-seq", String(run.last_seq));
    text("theta-norm", run.theta_norm === null ? "–" : run.theta_norm.toPrecision(5));
    // The full value, for a script or test that compares it exactly.
    $("theta-norm").dataset.value = run.theta_norm === null ? "" : String(run.theta_norm);
    const ve = $("verdict");
    ve.textContent = run.verdict; ve.className = run.verdict;
    text("verdict-text", run.verdict_text || (run.verdict === "ok" ? "no failure so far" : ""));
    const flags = { "flag-safe-state": run.flags.safe_state, "flag-operator-safe-state": run.flags.operator_safe_state,
      "flag-adaptation-frozen": run.flags.adaptation_frozen, "flag-open-loop": run.flags.open_loop,
      "flag-plant-silent": run.flags.plant_silent };
    for (const [id, on] of Object.entries(flags)) {
      const e = $(id); e.classList.toggle("on", !!on);
      e.classList.toggle("alarm", !!on && (id === "flag-safe-state" || id === "flag-plant-silent"));
    }
    for (const h of ["response", "compute", "wakeup", "jitter"]) {
      const l = run.latency[h];
      text(`lat-${h}-p50`, us(l.p50_ns)); text(`lat-${h}-p99`, us(l.p99_ns));
      text(`lat-${h}-max`, us(l.max_ns)); text(`lat-${h}-count`, String(l.count));
    }
    fillTable("counters", KEY_COUNTERS.map((k) => [k, run.counters[k]]));
    fillTable("all-counters", Object.entries(run.counters));
    renderTones(run);
    renderTunables(run);
  } else {
    text("run-state", "no frame yet"); text("last-seq", "–");
  }
  const info = v.info;
  if (info) {
    text("controller", info.controller + " (" + info.timing + ")" + (info.current ? "" : " — of an earlier run"));
    text("config-path", info.config_path);
    text("run-folder", info.run_folder);
    text("sample-period", (info.sample_period_ns / 1000).toFixed(1) + " µs");
    text("config", info.config_text + (info.config_cut ? "\n… (cut)" : ""));
  }
  const tb = $("previous-runs").tBodies[0];
  tb.innerHTML = "";
  for (const p of v.previous_runs.slice().reverse()) {
    const tr = tb.insertRow();
    for (const x of ["#" + p.run_id, p.run_state, p.verdict, p.last_seq, p.deadline_misses, p.lost]) tr.insertCell().textContent = String(x);
  }
  renderCommands(run);
}

function fillTable(id, rows) {
  const tb = $(id).tBodies[0];
  tb.innerHTML = "";
  for (const [k, v] of rows) { const tr = tb.insertRow(); tr.insertCell().textContent = k; tr.insertCell().textContent = String(v); }
}

// ---- tones ----
function db(x) { return (x === null || x <= 0) ? null : 20 * Math.log10(x); }

function renderTones(run) {
  const tb = $("tones-table").tBodies[0];
  tb.innerHTML = "";
  const bars = [];
  for (const t of run.tones.tones) {
    t.amplitude.forEach((a, j) => {
      const o = t.open_loop[j], s = t.suppression_db[j];
      const tr = tb.insertRow();
      for (const x of [t.hz, j, a === null ? "–" : db(a).toFixed(1) + " dB", o === null ? "–" : db(o).toFixed(1) + " dB", s === null ? "–" : s.toFixed(1)]) tr.insertCell().textContent = String(x);
      bars.push({ label: `${t.hz} Hz` + (t.amplitude.length > 1 ? ` z${j}` : ""), now: db(a), open: db(o) });
    });
  }
  const cv = $("tones"), g = cv.getContext("2d");
  g.clearRect(0, 0, cv.width, cv.height);
  if (!bars.length) { g.fillStyle = "#6b6b66"; g.fillText("no tones reported", 10, 20); return; }
  const vals = bars.flatMap((b) => [b.now, b.open]).filter((x) => x !== null);
  const hi = Math.max(...vals, -200) + 3, lo = Math.min(...vals, hi - 20) - 3;
  const y = (d) => cv.height - 20 - (d - lo) / (hi - lo) * (cv.height - 30);
  const w = cv.width / bars.length;
  g.font = "12px system-ui";
  bars.forEach((b, i) => {
    const x0 = i * w + w * 0.2, bw = w * 0.6;
    if (b.now !== null) { g.fillStyle = "#1f77b4"; g.fillRect(x0, y(b.now), bw, cv.height - 20 - y(b.now)); }
    if (b.open !== null) { g.strokeStyle = "#d62728"; g.lineWidth = 2; g.beginPath(); g.moveTo(x0 - 4, y(b.open)); g.lineTo(x0 + bw + 4, y(b.open)); g.stroke(); }
    g.fillStyle = "#1d1d1b"; g.fillText(b.label, x0, cv.height - 5);
  });
  g.fillStyle = "#6b6b66"; g.fillText(`bars: now; red: open loop; ${lo.toFixed(0)}…${hi.toFixed(0)} dB`, 5, 12);
}

// ---- commands ----
function renderTunables(run) {
  const sel = $("tunable-name");
  const names = run.tunables.map((t) => t.name).join(",");
  if (sel.dataset.names !== names) {
    sel.innerHTML = "";
    for (const t of run.tunables) { const o = document.createElement("option"); o.value = o.textContent = t.name; sel.appendChild(o); }
    sel.dataset.names = names;
  }
  const t = run.tunables.find((x) => x.name === sel.value);
  text("tunable-bounds", t ? `now ${t.value} · [${t.min}, ${t.max}] · initial ${t.initial}` : "no tunable declared");
}

function renderCommands(run) {
  let why = "";
  if (!ui.allow) why = "Commands are disabled: this monitor was started without --allow-commands.";
  else if (!run) why = "No run yet.";
  else if (!run.flags.commands_enabled) why = "The service does not accept operator commands (service.operator.commands = false).";
  else if (run.run_state === "ended") why = "The run has ended.";
  for (const b of document.querySelectorAll("button[data-command], #set-tunable")) {
    b.disabled = why !== "" || (b.id === "set-tunable" && !(run && run.tunables.length));
    b.title = why;
  }
  $("tunable-value").disabled = why !== "";
  text("commands-note", why);
}

async function sendCommand(cmd) {
  const body = { rig: ui.rig, command: cmd };
  if (cmd === "set-tunable") {
    body.tunable = $("tunable-name").value;
    body.value = Number($("tunable-value").value);
    if ($("tunable-value").value === "" || !Number.isFinite(body.value)) { text("command-result", "enter a number"); return; }
  }
  if (cmd === "stop-run" && !confirm(`Stop the run on rig ${ui.rig}?`)) return;
  text("command-result", `${cmd}: sending…`);
  try {
    const { body: r } = await getJson("/api/command", { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body) });
    text("command-result", r.error ? "error: " + r.error
      : `${r.command}: ${r.outcome}` + (r.applied_before_seq !== null ? ` before sample ${r.applied_before_seq}` : "")
        + (r.value !== null ? `, value ${r.value}` : "") + (r.message ? ` — ${r.message}` : ""));
  } catch (e) { text("command-result", "error: " + e); }
}

// ---- points (20 Hz) ----
async function pollPoints() {
  if (ui.rig !== null) {
    try {
      const since = ui.lastSeq === null ? "" : ui.lastSeq;
      const { ok, body } = await getJson(`/api/points?rig=${encodeURIComponent(ui.rig)}&since=${since}&max=4096`);
      if (ok) takePoints(body);
    } catch (e) { /* the state poll reports an unreachable monitor */ }
  }
  setTimeout(pollPoints, 50);
}

function takePoints(p) {
  if (p.run_id !== ui.runId) {
    // Another run (or rig): start over; the next poll asks for all its points.
    ui.runId = p.run_id; ui.points = []; ui.lastSeq = null; ui.drawnSeq = null; ui.dirty = true;
    return;
  }
  for (const q of p.points) ui.points.push({ t: q.t_unix_ms, seq: q.seq, z: q.z, u: q.u, th: q.theta_norm });
  if (p.points.length) { ui.lastSeq = p.points[p.points.length - 1].seq; ui.dirty = true; }
  const newest = ui.points.length ? ui.points[ui.points.length - 1].t : 0;
  let cut = 0;
  while (cut < ui.points.length && ui.points[cut].t < newest - WINDOW_MS) cut++;
  if (cut) ui.points.splice(0, cut);
}

// ---- drawing ----
function plot(g, x0, y0, w, h, pts, get, n, tEnd, label) {
  g.strokeStyle = "#d8d8d2"; g.strokeRect(x0, y0, w, h);
  let lo = Infinity, hi = -Infinity;
  for (const p of pts) for (let j = 0; j < n; j++) { const v = get(p, j); if (v !== null && Number.isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); } }
  if (!(hi > lo)) { hi = (Number.isFinite(hi) ? hi : 0) + 1; lo = hi - 2; }
  const pad = (hi - lo) * 0.05; lo -= pad; hi += pad;
  const X = (t) => x0 + w * (1 - (tEnd - t) / WINDOW_MS), Y = (v) => y0 + h * (hi - v) / (hi - lo);
  g.font = "11px system-ui"; g.fillStyle = "#6b6b66";
  g.fillText(`${label}  [${lo.toPrecision(3)}, ${hi.toPrecision(3)}]`, x0 + 4, y0 + 12);
  // At most two vertices per pixel column: the smallest and largest value in it.
  const cols = Math.max(1, Math.floor(w));
  for (let j = 0; j < n; j++) {
    g.strokeStyle = COLORS[j % COLORS.length]; g.lineWidth = 1.2; g.beginPath();
    let started = false, col = -1, vmin = 0, vmax = 0, tcol = 0;
    const flush = () => {
      if (col < 0) return;
      if (!started) { g.moveTo(X(tcol), Y(vmin)); started = true; } else g.lineTo(X(tcol), Y(vmin));
      if (vmax !== vmin) g.lineTo(X(tcol), Y(vmax));
    };
    for (const p of pts) {
      const v = get(p, j);
      if (v === null || !Number.isFinite(v)) { flush(); col = -1; started = false; continue; }
      const c = Math.floor((X(p.t) - x0) / w * cols);
      if (c !== col) { flush(); col = c; vmin = vmax = v; tcol = p.t; } else { vmin = Math.min(vmin, v); vmax = Math.max(vmax, v); }
    }
    flush();
    g.stroke();
  }
}

function draw() {
  requestAnimationFrame(draw);
  if (!ui.dirty) return;
  ui.dirty = false;
  const pts = ui.points;
  const cv = $("scope"), g = cv.getContext("2d");
  g.clearRect(0, 0, cv.width, cv.height);
  const tEnd = pts.length ? pts[pts.length - 1].t : 0;
  const nz = pts.length ? pts[pts.length - 1].z.length : 0, nu = pts.length ? pts[pts.length - 1].u.length : 0;
  const h = (cv.height - 10) / 2;
  plot(g, 0, 0, cv.width, h, pts, (p, j) => p.z[j], nz, tEnd, "z");
  plot(g, 0, h + 10, cv.width, h, pts, (p, j) => p.u[j], nu, tEnd, "u");
  text("scope-legend", pts.length ? `${pts.length} points, z: ${nz} channel(s), u: ${nu}` : "no points yet");
  const tc = $("theta-scope"), tg = tc.getContext("2d");
  tg.clearRect(0, 0, tc.width, tc.height);
  plot(tg, 0, 0, tc.width, tc.height, pts, (p) => p.th, 1, tEnd, "‖θ‖");
  if (pts.length) {
    const newest = pts[pts.length - 1];
    if (newest.seq !== ui.drawnSeq) {
      // First time this point is on screen: sample time → now.
      ui.drawnSeq = newest.seq;
      const ms = Date.now() - newest.t;
      ui.latencies.push(ms); if (ui.latencies.length > 50) ui.latencies.shift();
      const e = $("display-latency-ms");
      e.textContent = ms.toFixed(1);
      e.dataset.valueMs = String(ms);
      const sorted = ui.latencies.slice().sort((a, b) => a - b);
      e.title = `median of the last ${sorted.length}: ${sorted[sorted.length >> 1].toFixed(1)} ms`;
    }
  }
}

// ---- start ----
$("rig-select").addEventListener("change", (e) => { ui.rig = e.target.value; ui.runId = undefined; ui.points = []; ui.lastSeq = null; ui.dirty = true; });
for (const b of document.querySelectorAll("button[data-command]")) b.addEventListener("click", () => sendCommand(b.dataset.command));
$("set-tunable").addEventListener("click", () => sendCommand("set-tunable"));
$("tunable-name").addEventListener("change", () => { if (ui.rigView && ui.rigView.run) renderTunables(ui.rigView.run); });
pollState();
pollPoints();
requestAnimationFrame(draw);
