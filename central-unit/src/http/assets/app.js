// ICKON live map: draws /api/site once (again when the schedule version
// changes: a reload), then every snapshot of the /events stream (20 Hz).
// Plain JavaScript and SVG; nothing is fetched from anywhere else.
"use strict";

const SVG = "http://www.w3.org/2000/svg";
const PX_PER_M = 60;
const MARGIN_M = 0.6;
// A cell counts as firing this long after its last burst arrived.
const FLASH_MS = 160;
const TRAIL_PIECES = 5;
// The side panel's tables are rebuilt at most this often (the map itself
// follows every snapshot): text changing 20 times a second cannot be read,
// and rebuilding it costs the browser more than the whole map.
const PANEL_MS = 250;
// The header says `live` only while snapshots arrive (20 a second): after
// this long without one it says how long the stream has been quiet.
const QUIET_MS = 2000;

const state = {
  site: null,
  snap: null,
  frame: 0,
  scheduleVersion: null,
  panelAt: -Infinity,
  messages: 0,
  lastMessageAt: -Infinity,
  robots: new Map(),
  cells: new Map(),
  txs: new Map(),
  es: null,
};
// For tests and the curious: what arrived and when.
window.ickon = state;

function el(name, attrs, parent) {
  const e = document.createElementNS(SVG, name);
  for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
  if (parent) parent.appendChild(e);
  return e;
}

function px(x) { return (x - state.site.bounds_m[0] + MARGIN_M) * PX_PER_M; }
function py(y) { return (state.site.bounds_m[3] + MARGIN_M - y) * PX_PER_M; }
function points(poly) { return poly.map(p => `${px(p[0]).toFixed(1)},${py(p[1]).toFixed(1)}`).join(" "); }
function deg(rad) { return -rad * 180 / Math.PI; }

async function getJson(path) {
  const r = await fetch(path, { cache: "no-store" });
  if (!r.ok) throw new Error(`${path}: ${r.status}`);
  return r.json();
}

// The static layers: coverage (empty until asked), cells, columns, walls,
// transmitters; robots on top.
function drawSite(site) {
  state.site = site;
  state.robots.clear(); state.cells.clear(); state.txs.clear();
  const svg = document.getElementById("map");
  svg.replaceChildren();
  const [x0, y0, x1, y1] = site.bounds_m;
  const w = (x1 - x0 + 2 * MARGIN_M) * PX_PER_M, h = (y1 - y0 + 2 * MARGIN_M) * PX_PER_M;
  svg.setAttribute("viewBox", `0 0 ${w.toFixed(0)} ${h.toFixed(0)}`);
  document.getElementById("site-name").textContent = site.name;
  const cells = el("g", { id: "layer-cells" }, svg);
  el("g", { id: "layer-coverage", class: "coverage hidden" }, svg);
  const fixed = el("g", { id: "layer-fixed" }, svg);
  el("g", { id: "layer-robots" }, svg);
  for (const c of site.cells) {
    const poly = el("polygon", { points: points(c.polygon), class: "cell up", "data-cell": c.id, "data-state": "up" }, cells);
    const cx = c.polygon.reduce((s, p) => s + p[0], 0) / c.polygon.length;
    const cy = c.polygon.reduce((s, p) => s + p[1], 0) / c.polygon.length;
    const label = el("text", { x: px(cx), y: py(cy), class: "cell-label", "text-anchor": "middle" }, cells);
    label.textContent = c.id;
    state.cells.set(c.id, poly);
  }
  for (const col of site.columns) el("polygon", { points: points(col), class: "column" }, fixed);
  for (const w of site.walls) el("line", { x1: px(w[0]), y1: py(w[1]), x2: px(w[2]), y2: py(w[3]), class: "wall" }, fixed);
  for (const t of site.transmitters) {
    const c = el("circle", { cx: px(t.x_m), cy: py(t.y_m), r: 5, class: "tx", "data-tx": t.id }, fixed);
    const label = el("text", { x: px(t.x_m) + 7, y: py(t.y_m) - 6, class: "tx-label" }, fixed);
    label.textContent = t.id;
    state.txs.set(t.id, c);
  }
  if (document.getElementById("show-coverage").checked) loadCoverage();
}

function robotMarker(id) {
  const layer = document.getElementById("layer-robots");
  const g = el("g", { "data-robot-group": id }, layer);
  const m = { trail: [], g };
  for (let i = 0; i < TRAIL_PIECES; i++) {
    m.trail.push(el("polyline", { class: "trail", "stroke-opacity": (0.12 + 0.8 * (i + 1) / TRAIL_PIECES).toFixed(2) }, g));
  }
  m.ellipse = el("ellipse", { class: "ellipse fixlayer" }, g);
  m.fix = el("circle", { r: 3, class: "fix fixlayer" }, g);
  m.truth = el("g", { class: "truthlayer" }, g);
  el("circle", { r: 10, class: "truth" }, m.truth);
  el("line", { x1: 0, y1: 0, x2: 16, y2: 0, class: "truth" }, m.truth);
  m.fused = el("path", { d: "M 13 0 L -8 7 L -8 -7 Z", class: "fused", "data-robot": id }, g);
  m.label = el("text", { class: "robot-label" }, g);
  m.label.textContent = id;
  state.robots.set(id, m);
  return m;
}

function show(node, visible) { node.style.display = visible ? "" : "none"; }

function drawRobot(r) {
  const m = state.robots.get(r.id) || robotMarker(r.id);
  const showFix = document.getElementById("show-fix").checked;
  const showTruth = document.getElementById("show-truth").checked;
  const trail = r.trail || [];
  const per = Math.ceil(trail.length / TRAIL_PIECES);
  for (let i = 0; i < TRAIL_PIECES; i++) {
    const piece = trail.slice(i * per, Math.min(trail.length, (i + 1) * per + 1));
    m.trail[i].setAttribute("points", piece.length > 1 ? points(piece) : "");
  }
  show(m.fused, !!r.fused); show(m.label, !!r.fused);
  if (r.fused) {
    const x = px(r.fused.x_m), y = py(r.fused.y_m);
    m.fused.setAttribute("transform", `translate(${x.toFixed(1)},${y.toFixed(1)}) rotate(${deg(r.fused.theta_rad).toFixed(1)})`);
    m.fused.setAttribute("data-x", r.fused.x_m);
    m.fused.setAttribute("data-y", r.fused.y_m);
    m.label.setAttribute("x", (x + 12).toFixed(1));
    m.label.setAttribute("y", (y + 18).toFixed(1));
  }
  show(m.fix, showFix && !!r.fix); show(m.ellipse, showFix && !!(r.fix && r.fix.ellipse));
  if (r.fix) {
    const x = px(r.fix.x_m), y = py(r.fix.y_m);
    m.fix.setAttribute("cx", x.toFixed(1)); m.fix.setAttribute("cy", y.toFixed(1));
    const e = r.fix.ellipse;
    if (e) {
      m.ellipse.setAttribute("rx", Math.max(1, e.a_m * PX_PER_M).toFixed(1));
      m.ellipse.setAttribute("ry", Math.max(1, e.b_m * PX_PER_M).toFixed(1));
      m.ellipse.setAttribute("transform", `translate(${x.toFixed(1)},${y.toFixed(1)}) rotate(${deg(e.angle_rad).toFixed(1)})`);
    }
  }
  show(m.truth, showTruth && !!r.truth);
  if (r.truth) {
    m.truth.setAttribute("transform", `translate(${px(r.truth.x_m).toFixed(1)},${py(r.truth.y_m).toFixed(1)}) rotate(${deg(r.truth.theta_rad).toFixed(1)})`);
  }
}

// `up` (due to fire), `idle` (alive, not asked to fire: no robot near it),
// `down`, or `paused` while the central unit holds every trigger.
function cellState(c, snap) {
  if (c.state === "down") return "down";
  return snap.paused ? "paused" : c.state;
}

function fmt(v, digits) { return v === null || v === undefined ? "-" : Number(v).toFixed(digits); }

function row(cells) {
  const tr = document.createElement("tr");
  for (const [text, cls] of cells) {
    const td = document.createElement("td");
    td.textContent = text;
    if (cls) td.className = cls;
    tr.appendChild(td);
  }
  return tr;
}

function render() {
  state.frame = 0;
  const snap = state.snap;
  if (!snap || !state.site) return;
  const firing = new Set();
  for (const c of snap.cells) {
    const poly = state.cells.get(c.id);
    if (!poly) continue;
    const s = cellState(c, snap);
    const fire = s === "up" && c.last_burst_ms !== null && c.last_burst_ms < FLASH_MS;
    if (fire && c.last_tx !== null) firing.add(c.last_tx);
    poly.setAttribute("class", `cell ${s}${fire ? " fire" : ""}`);
    poly.setAttribute("data-state", s);
  }
  const leftOut = new Set(snap.transmitters_left_out || []);
  for (const [id, c] of state.txs) {
    c.setAttribute("class", leftOut.has(id) ? "tx out" : firing.has(id) ? "tx fire" : "tx");
  }
  for (const r of snap.robots) drawRobot(r);

  const now = performance.now();
  if (now - state.panelAt >= PANEL_MS) {
    state.panelAt = now;
    renderPanel(snap);
  }
  if (snap.schedule_version !== state.scheduleVersion) {
    const first = state.scheduleVersion === null;
    state.scheduleVersion = snap.schedule_version;
    loadSchedule();
    if (!first) loadSite();
  }
}

// The fleet's check of a robot's fixes: its standing, and for a quarantined
// robot how many of its fixes were kept out of the survey calibration.
function surveyCell(r) {
  const check = r.survey_check;
  if (!check) return ["-", "txt"];
  if (check === "quarantined") return [`quarantined (${r.fixes_quarantined})`, "txt down"];
  return [check.startsWith("unchecked") ? "unchecked (no other robot)" : check, "txt"];
}

function renderPanel(snap) {
  document.getElementById("cycle").textContent =
    `cycle ${snap.cycle}${snap.paused ? " (paused)" : ""} · ${fmt(snap.update_rate_hz, 2)} cycles/s` +
    ` · sound ${fmt(snap.speed_of_sound_m_s, 2)} m/s${snap.speed_of_sound_learnt ? " (learnt)" : ""}` +
    ((snap.transmitters_left_out || []).length
      ? ` · left out: ${snap.transmitters_left_out.join(", ")}` : "");
  const robots = document.querySelector("#robots tbody");
  robots.replaceChildren(...snap.robots.map(r => row([
    [r.id], [r.state, r.state === "down" ? "down" : ""], [r.estimator || "-", "txt"],
    [fmt(r.fixes_per_s, 1)], [String(r.fixes_over_rate), r.fixes_over_rate > 0 ? "down" : ""],
    surveyCell(r),
    [fmt(r.err_mm, 0)], [fmt(r.staleness_ms, 0)], [r.receivers || "-", "txt device"],
  ])));
  const cells = document.querySelector("#cells tbody");
  cells.replaceChildren(...snap.cells.map(c => {
    const s = cellState(c, snap);
    return row([[c.id], [s, s], [fmt(c.sync_error_us, 1)], [String(c.cycles_fired)],
      [String(c.cycles_missed + c.slots_skipped)], [c.device || "-", "txt device"]]);
  }));
  document.getElementById("clients").textContent =
    `web clients ${snap.clients}, dropped as slow ${snap.clients_dropped}; messages ignored ${snap.ignored_messages}`;
}

async function loadSchedule() {
  try {
    const s = await getJson("/api/schedule");
    document.getElementById("schedule").textContent =
      `v${s.version} from cycle ${s.effective_cycle}: period ${fmt(s.period_ms, 1)} ms, ` +
      `slot ${fmt(s.slot_ms, 1)} ms, ${fmt(s.update_rate_hz, 2)} updates/s, ` +
      `${s.emissions.length} emissions, cells ${s.active_cells.join(", ")}`;
  } catch (e) {
    document.getElementById("schedule").textContent = `schedule unavailable (${e.message})`;
  }
}

function hdopColour(h) {
  if (h <= 0) return "#b03a3a";
  const t = Math.min(1, Math.max(0, (h - 1) / 4));
  return `hsl(${(120 * (1 - t)).toFixed(0)}, 70%, 50%)`;
}

async function loadCoverage() {
  const layer = document.getElementById("layer-coverage");
  try {
    const c = await getJson("/api/coverage");
    layer.replaceChildren();
    const s = c.resolution_m * PX_PER_M;
    for (let row = 0; row < c.rows; row++) {
      for (let col = 0; col < c.columns; col++) {
        const i = row * c.columns + col;
        if (!c.on_floor[i]) continue;
        const x = c.origin_x_m + col * c.resolution_m, y = c.origin_y_m + row * c.resolution_m;
        el("rect", { x: (px(x) - s / 2).toFixed(1), y: (py(y) - s / 2).toFixed(1), width: s.toFixed(1), height: s.toFixed(1),
          fill: hdopColour(c.hdop[i]) }, layer).appendChild(document.createElementNS(SVG, "title")).textContent =
          `HDOP ${c.hdop[i].toFixed(2)}, ${c.visible[i]} transmitters`;
      }
    }
    layer.classList.remove("hidden");
  } catch (e) {
    document.getElementById("control-msg").textContent = `coverage unavailable (${e.message})`;
  }
}

async function loadSite() {
  try {
    drawSite(await getJson("/api/site"));
    schedule();
  } catch (e) {
    document.getElementById("control-msg").textContent = `site unavailable (${e.message})`;
  }
}

function schedule() {
  if (!state.frame) state.frame = requestAnimationFrame(render);
}

// The stream's state in the header, from what is true now rather than from
// the last event handler that ran: the EventSource's own state, and how
// long ago the last snapshot arrived.
function showConn() {
  const conn = document.getElementById("conn");
  const es = state.es;
  const quiet = performance.now() - state.lastMessageAt;
  let text = "live", up = true;
  if (!es || es.readyState === EventSource.CONNECTING) {
    text = state.messages ? "reconnecting" : "connecting"; up = false;
  } else if (es.readyState === EventSource.CLOSED) {
    text = "disconnected"; up = false;
  } else if (quiet >= QUIET_MS) {
    text = state.messages ? `no data for ${(quiet / 1000).toFixed(0)} s` : "waiting for data"; up = false;
  }
  if (conn.textContent !== text) {
    conn.textContent = text;
    conn.className = up ? "conn up" : "conn down";
  }
}

function connect() {
  const es = new EventSource("/events");
  state.es = es;
  let opened = false;
  es.onopen = () => {
    // A restarted central unit may serve another site version.
    if (opened || state.site === null) loadSite();
    opened = true;
    showConn();
  };
  es.onmessage = (m) => {
    state.snap = JSON.parse(m.data);
    state.messages += 1;
    state.lastMessageAt = performance.now();
    showConn();
    schedule();
  };
  es.onerror = () => {
    showConn();
    // The browser retries by itself unless the stream was refused outright.
    if (es.readyState === EventSource.CLOSED) setTimeout(connect, 1000);
  };
}

async function control(command) {
  const msg = document.getElementById("control-msg");
  const token = document.getElementById("token").value.trim();
  try {
    const r = await fetch(`/api/${command}`, { method: "POST", headers: { Authorization: `Bearer ${token}` } });
    const body = await r.json();
    msg.textContent = r.ok ? body.messages.join("; ") : body.error;
  } catch (e) {
    msg.textContent = e.message;
  }
}

document.getElementById("show-coverage").addEventListener("change", (e) => {
  if (e.target.checked) loadCoverage();
  else document.getElementById("layer-coverage").classList.add("hidden");
});
for (const id of ["show-truth", "show-fix"]) document.getElementById(id).addEventListener("change", schedule);
document.getElementById("pause").addEventListener("click", () => control("pause"));
document.getElementById("resume").addEventListener("click", () => control("resume"));
setInterval(showConn, 500);
loadSite().then(connect);
