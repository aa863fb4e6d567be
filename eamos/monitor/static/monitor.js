// The EAMOS monitor page: plain JavaScript, no library, no build step.
// State arrives over a websocket as a snapshot, then as ordered patches (eamos/monitor/state.py
// documents them); everything on the page is drawn from that state.
"use strict";

const SVGNS = "http://www.w3.org/2000/svg";
const NODE_COLOURS = {
  waiting: null, // the drone's own colour, faded
  running: "#4dabf7",
  done: "#69db7c",
  skipped: "#dee2e6",
  failed: "#ff6b6b",
  cancelled: "#ffa94d",
};
const FINAL = new Set(["finished", "failed", "aborted", "timed out"]);
const params = new URLSearchParams(location.search);
const token = params.get("token");

let setup = null;
let state = null;
let replay = null; // {start, end, started} in a replay
let replayT = null;
let playing = null;
let seekPending = false;
let dirty = false;
let ws = null;

function $(id) { return document.getElementById(id); }

function el(tag, attrs, text) {
  const e = document.createElementNS(SVGNS, tag);
  for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
  if (text !== undefined) e.textContent = text;
  return e;
}

function item(cls, text) {
  // An HTML list item (el() makes SVG elements).
  const li = document.createElement("li");
  li.className = cls;
  li.textContent = text;
  return li;
}

function colourOf(name) {
  const p = setup && setup.participants.find((q) => q.name === name);
  return p ? p.colour : "#999";
}

// -- state --------------------------------------------------------------------------------

function applyPatches(patches) {
  for (const p of patches) {
    const { k, ...body } = p;
    if (k === "drone") {
      const d = state.drones[p.drone] || (state.drones[p.drone] = { trail: [] });
      const add = body.trail_add || [];
      delete body.trail_add;
      d.trail = (d.trail || []).concat(add);
      Object.assign(d, body);
    } else if (k === "node") {
      const key = body.node;
      delete body.node;
      state.nodes[key] = body;
    } else if (k === "bar") {
      const i = body.i;
      delete body.i;
      state.bars[i] = body;
    } else if (k === "mission") {
      state.mission = body;
    } else if (k === "forecast") {
      state.forecast = body;
    } else if (k === "link") {
      (state.links || (state.links = {}))[`${body.src}>${body.dst}`] = body;
    } else if (k === "amended") {
      redrawGraphs(body.drones); // an amendment was applied: their graphs as they fly now
    }
  }
}

function onMessage(ev) {
  const msg = JSON.parse(ev.data);
  if (msg.type === "snapshot") {
    state = msg.state;
    seekPending = false;
  } else if (msg.type === "patches" && state) {
    applyPatches(msg.patches);
  }
  document.body.dataset.seq = msg.seq;
  schedule();
}

function connect() {
  const proto = location.protocol === "https:" ? "wss:" : "ws:";
  ws = new WebSocket(`${proto}//${location.host}/ws`);
  ws.onopen = () => {
    $("conn").textContent = replay ? "replay" : "live";
    $("conn").dataset.conn = "live";
    if (replay) seek(replayT === null ? replay.end : replayT);
  };
  ws.onmessage = onMessage;
  ws.onclose = () => {
    const over = state && FINAL.has(state.mission.state);
    $("conn").textContent = over ? "run over: the monitor stopped (this page keeps the end)" : "disconnected";
    $("conn").dataset.conn = "closed";
    $("abort").disabled = true;
  };
}

function schedule() {
  if (dirty) return;
  dirty = true;
  requestAnimationFrame(() => { dirty = false; draw(); });
}

// -- drawing ------------------------------------------------------------------------------

function nowClock() {
  const m = state.mission;
  if (replay) return replayT - replay.started;
  if (m.started === null || m.started === undefined) return 0;
  const end = m.ended !== null && m.ended !== undefined ? m.ended : Date.now() / 1000;
  return end - m.started;
}

function draw() {
  if (!state || !setup) return;
  const m = state.mission;
  const ms = $("mission-state");
  ms.textContent = m.state;
  ms.dataset.state = m.state;
  $("mission-clock").textContent = `${Math.max(0, nowClock()).toFixed(1)} s`;
  $("mission-detail").textContent = m.detail || "";
  const st = state.stats;
  if (st) $("stats").textContent = `updates coalesced ${st.coalesced}, frames dropped ${st.dropped}`;
  $("abort").disabled = !token || !!replay || FINAL.has(m.state) || ws.readyState !== 1;
  $("pause").disabled = !commandsOn() || m.state !== "running";
  $("amend-check").disabled = !commandsOn();
  $("resume").disabled = !commandsOn() || m.state !== "paused";
  drawDrones();
  drawLinks();
  drawForecast();
  drawMap();
  drawAltitude();
  drawGantt();
  colourGraphs();
  markPredicted();
}

function fmt(v, digits) { return v === null || v === undefined ? "" : Number(v).toFixed(digits); }

function drawDrones() {
  const body = $("drones").tBodies[0];
  for (const name of setup.drones) {
    const d = state.drones[name] || {};
    const part = setup.participants.find((p) => p.name === name);
    let row = body.querySelector(`tr[data-drone="${name}"]`);
    if (!row) {
      row = document.createElement("tr");
      row.dataset.drone = name;
      row.dataset.home = part.home.join(",");
      row.innerHTML = `<td><span class="swatch" style="background:${part.colour}"></span>${name}</td>` +
        "<td class='mode'></td><td class='armed'></td><td class='battery'></td><td class='link'></td>" +
        "<td class='action'></td><td class='pos'></td><td class='trig'></td><td class='cmds'></td>";
      for (const [command, label] of DRONE_COMMANDS) {
        const b = document.createElement("button");
        b.type = "button";
        b.className = "cmd";
        b.dataset.command = command;
        b.textContent = label;
        b.addEventListener("click", () => askCommand(command, name));
        row.querySelector(".cmds").appendChild(b);
      }
      const line = document.createElement("tr");
      line.dataset.line = name;
      line.innerHTML = "<td class='line' colspan='9'></td>";
      body.appendChild(row);
      body.appendChild(line);
    }
    const cell = (c) => row.querySelector(`.${c}`);
    cell("mode").textContent = (d.mode || "") + (d.autopilot ? ` (${d.autopilot})` : "") +
      (d.operator ? ` · ${d.operator}` : "");
    cell("mode").dataset.autopilot = d.autopilot || "";
    cell("mode").dataset.operator = d.operator || "";
    for (const b of row.querySelectorAll("button.cmd")) b.disabled = !commandsOn();
    cell("armed").textContent = d.armed === null || d.armed === undefined ? "" : d.armed ? "armed" : "disarmed";
    cell("battery").textContent = d.battery === null || d.battery === undefined ? "" : `${fmt(d.battery, 0)} %`;
    cell("link").textContent = d.link || "";
    cell("link").className = `link link-${d.link}`;
    cell("action").textContent = d.action || "";
    const pos = cell("pos");
    pos.textContent = d.x === null || d.x === undefined ? "" : `${fmt(d.x, 2)}, ${fmt(d.y, 2)}, ${fmt(d.z, 2)}`;
    if (d.lat !== null && d.lat !== undefined) pos.textContent += ` (${fmt(d.lat, 6)}°, ${fmt(d.lon, 6)}°)`;
    for (const a of ["x", "y", "z"]) pos.dataset[a] = d[a] === null || d[a] === undefined ? "" : d[a];
    // The report's counts once it arrived; until then the live counts of the links table.
    const live = liveTotals(name);
    const sent = d.triggers_sent === null || d.triggers_sent === undefined ? live[0] : d.triggers_sent;
    const recv = d.triggers_received === null || d.triggers_received === undefined ? live[1] : d.triggers_received;
    cell("trig").textContent = `${sent} / ${recv} of ${part.external_out} / ${part.external_in}`;
    const said = (d.statustext || []).map(([sev, text]) => `${SEVERITIES[sev] || sev}: ${text}`);
    const lineCell = body.querySelector(`tr[data-line="${name}"] td`);
    lineCell.textContent = (d.line || "") + (d.failure ? `   [failed: ${d.failure}]` : "") +
      (said.length ? `   [autopilot: ${said.join(" | ")}]` : "");
    lineCell.dataset.statustext = said.join("\n");
  }
}

function liveTotals(name) {
  let sent = 0, recv = 0;
  for (const l of Object.values(state.links || {})) {
    if (l.src === name) sent += l.sent;
    if (l.dst === name) recv += l.received;
  }
  return [sent, recv];
}

function drawLinks() {
  const body = $("links").tBodies[0];
  for (const l of Object.values(state.links || {})) {
    const key = `${l.src}>${l.dst}`;
    let row = body.querySelector(`tr[data-link="${key}"]`);
    if (!row) {
      row = document.createElement("tr");
      row.dataset.link = key;
      row.innerHTML = `<td><span class="swatch" style="background:${colourOf(l.src)}"></span>${l.src} → ` +
        `<span class="swatch" style="background:${colourOf(l.dst)}"></span>${l.dst}</td>` +
        "<td class='arcs'></td><td class='sent'></td><td class='received'></td>";
      body.appendChild(row);
    }
    for (const c of ["arcs", "sent", "received"]) {
      row.querySelector(`.${c}`).textContent = l[c];
      row.dataset[c] = l[c];
    }
    // More than the arcs: a loop sends its arcs once per iteration (not an error).
    row.classList.toggle("over", l.sent > l.arcs);
  }
}

function niceStep(span, ticks) {
  const raw = span / ticks;
  const p = Math.pow(10, Math.floor(Math.log10(raw)));
  for (const m of [1, 2, 5, 10]) if (raw <= m * p) return m * p;
  return 10 * p;
}

function frame(svg, xs, ys, w, h, pad, equal) {
  // A linear map from data to the picture, with a margin; equal: same metres per pixel on both axes.
  let [x0, x1] = [Math.min(...xs), Math.max(...xs)];
  let [y0, y1] = [Math.min(...ys), Math.max(...ys)];
  if (x1 - x0 < 1) { x0 -= 0.5; x1 += 0.5; }
  if (y1 - y0 < 1) { y0 -= 0.5; y1 += 0.5; }
  const mx = (x1 - x0) * 0.08, my = (y1 - y0) * 0.08;
  x0 -= mx; x1 += mx; y0 -= my; y1 += my;
  let sx = (w - 2 * pad) / (x1 - x0), sy = (h - 2 * pad) / (y1 - y0);
  if (equal) {
    const s = Math.min(sx, sy);
    const cx = (x0 + x1) / 2, cy = (y0 + y1) / 2;
    sx = sy = s;
    x0 = cx - (w - 2 * pad) / s / 2; x1 = cx + (w - 2 * pad) / s / 2;
    y0 = cy - (h - 2 * pad) / s / 2; y1 = cy + (h - 2 * pad) / s / 2;
  }
  return { X: (x) => pad + (x - x0) * sx, Y: (y) => h - pad - (y - y0) * sy, x0, x1, y0, y1 };
}

function grid(svg, f, w, h, pad, xlabel, ylabel) {
  const sxs = niceStep(f.x1 - f.x0, 8), sys = niceStep(f.y1 - f.y0, 5);
  for (let x = Math.ceil(f.x0 / sxs) * sxs; x <= f.x1; x += sxs) {
    svg.appendChild(el("line", { x1: f.X(x), x2: f.X(x), y1: pad, y2: h - pad, class: "grid" }));
    svg.appendChild(el("text", { x: f.X(x), y: h - pad + 12, class: "tick", "text-anchor": "middle" }, +x.toFixed(3)));
  }
  for (let y = Math.ceil(f.y0 / sys) * sys; y <= f.y1; y += sys) {
    svg.appendChild(el("line", { x1: pad, x2: w - pad, y1: f.Y(y), y2: f.Y(y), class: "grid" }));
    svg.appendChild(el("text", { x: pad - 3, y: f.Y(y) + 3, class: "tick", "text-anchor": "end" }, +y.toFixed(3)));
  }
  svg.appendChild(el("text", { x: w - pad, y: h - 2, class: "tick", "text-anchor": "end" }, xlabel));
  svg.appendChild(el("text", { x: 2, y: pad - 6, class: "tick" }, ylabel));
}

function drawForecast() {
  // The look-ahead's latest cycle: each prediction, then when the mission should end.
  const fc = state.forecast;
  if (!fc) return;
  const ul = $("forecast");
  ul.replaceChildren();
  for (const p of fc.predictions || []) {
    const when = p.in_s === null || p.in_s === undefined ? "" : ` in ${Math.round(p.in_s)} s`;
    const li = item(p.severity, `${p.check} ${p.severity}${when}: ${p.message}`);
    li.dataset.check = p.check;
    li.dataset.drones = (p.drones || []).join(" ");
    ul.appendChild(li);
  }
  const end = fc.end_in_s === null || fc.end_in_s === undefined ? "not foreseen" : `in ${Math.round(fc.end_in_s)} s`;
  ul.appendChild(item("end", `${(fc.predictions || []).length ? "" : "nothing ahead; "}mission end ${end} (cycle ${fc.cycle})`));
}

function drawAhead(svg, f) {
  // Each drone's predicted track (dotted), and a ring where a conflict is predicted.
  const fc = state.forecast;
  if (!fc) return;
  for (const [name, pts] of Object.entries(fc.ahead || {})) {
    if (!setup.drones.includes(name)) continue;
    const line = pts.map((p) => `${f.X(p[2]).toFixed(1)},${f.Y(p[1]).toFixed(1)}`).join(" ");
    if (line) svg.appendChild(el("polyline", { points: line, class: "ahead", stroke: colourOf(name), "data-drone": name }));
  }
  for (const p of fc.predictions || []) {
    if (!p.position) continue;
    const g = el("g", { class: "predicted", "data-check": p.check, transform: `translate(${f.X(p.position[1]).toFixed(1)},${f.Y(p.position[0]).toFixed(1)})` });
    g.appendChild(el("circle", { r: 10 }));
    const when = p.in_s === null || p.in_s === undefined ? "" : ` in ${Math.round(p.in_s)} s`;
    g.appendChild(el("text", { x: 13, y: 4, class: "dlabel" }, `${p.check}${when}: ${(p.drones || []).join(", ")}`));
    svg.appendChild(g);
  }
}

function drawMap() {
  const svg = $("map");
  const w = 640, h = 440, pad = 34;
  svg.replaceChildren();
  const xs = [], ys = [];
  // North up, east to the right: screen x is the mission's y (east), screen y its x (north).
  for (const p of setup.participants) if (setup.drones.includes(p.name)) { xs.push(p.home[1]); ys.push(p.home[0]); }
  for (const name of setup.drones) {
    const d = state.drones[name] || {};
    for (const t of d.trail || []) { xs.push(t[2]); ys.push(t[1]); }
    if (d.x !== null && d.x !== undefined) { xs.push(d.y); ys.push(d.x); }
    for (const p of ((state.forecast || {}).ahead || {})[name] || []) { xs.push(p[2]); ys.push(p[1]); }
  }
  const f = frame(svg, xs, ys, w, h, pad, true);
  grid(svg, f, w, h, pad, "y, east (m)", "x, north (m)");
  drawAhead(svg, f);
  setup.drones.forEach((name, i) => {
    const part = setup.participants.find((p) => p.name === name);
    const d = state.drones[name] || {};
    const hx = f.X(part.home[1]), hy = f.Y(part.home[0]);
    svg.appendChild(el("rect", { x: hx - 5, y: hy - 5, width: 10, height: 10, fill: "none", stroke: part.colour, "stroke-width": 2 }));
    const pts = (d.trail || []).map((t) => `${f.X(t[2]).toFixed(1)},${f.Y(t[1]).toFixed(1)}`).join(" ");
    const dash = ["", "6 3", "2 3", "8 3 2 3"][i % 4];
    if (pts) svg.appendChild(el("polyline", { points: pts, class: "trail", stroke: part.colour, "stroke-dasharray": dash, filter: "brightness(0.8)" }));
    if (d.x === null || d.x === undefined) return;
    const g = el("g", { class: "drone", "data-drone": name, transform: `translate(${f.X(d.y).toFixed(1)},${f.Y(d.x).toFixed(1)})` });
    const heading = d.heading === null || d.heading === undefined ? 0 : d.heading;
    g.appendChild(el("polygon", { points: "12,0 -7,7 -3,0 -7,-7", fill: part.colour, stroke: "#222", transform: `rotate(${heading - 90})` }));
    g.appendChild(el("text", { x: 9, y: -9 - 12 * (i % 4), class: "dlabel", fill: "#222" }, `${name} z ${fmt(d.z, 1)}`));
    svg.appendChild(g);
  });
}

function drawAltitude() {
  const svg = $("alt");
  const w = 640, h = 140, pad = 26;
  svg.replaceChildren();
  const t0 = state.mission.started || state.mission.created;
  const ts = [0], zs = [0, 1];
  for (const name of setup.drones) for (const p of (state.drones[name] || {}).trail || []) { ts.push(p[0] - t0); zs.push(p[3]); }
  ts.push(Math.max(1, nowClock()));
  const f = frame(svg, ts, zs, w, h, pad, false);
  grid(svg, f, w, h, pad, "s", "z (m)");
  for (const name of setup.drones) {
    const pts = ((state.drones[name] || {}).trail || []).map((p) => `${f.X(p[0] - t0).toFixed(1)},${f.Y(p[3]).toFixed(1)}`).join(" ");
    if (pts) svg.appendChild(el("polyline", { points: pts, class: "trail", stroke: colourOf(name), filter: "brightness(0.8)" }));
  }
}

function drawGantt() {
  const svg = $("gantt");
  const names = setup.drones.concat(setup.participants.some((p) => p.name === "GCS") ? [] : []);
  const rowH = 22, pad = 60, top = 8;
  const h = top + rowH * names.length + 24, w = 640;
  svg.setAttribute("viewBox", `0 0 ${w} ${h}`);
  svg.replaceChildren();
  const t0 = state.mission.started || state.mission.created;
  const nowT = t0 + Math.max(0, nowClock());
  let tmax = Math.max(0.5, nowClock());
  for (const b of state.bars) if (b && b.end !== null && b.end !== undefined) tmax = Math.max(tmax, b.end - t0);
  const X = (t) => pad + (Math.max(0, t) / tmax) * (w - pad - 10);
  const step = niceStep(tmax, 8);
  for (let t = 0; t <= tmax; t += step) {
    svg.appendChild(el("line", { x1: X(t), x2: X(t), y1: top, y2: h - 20, class: "grid" }));
    svg.appendChild(el("text", { x: X(t), y: h - 8, class: "tick", "text-anchor": "middle" }, +t.toFixed(2)));
  }
  names.forEach((name, r) => {
    svg.appendChild(el("text", { x: 4, y: top + r * rowH + 15, class: "tick" }, name));
  });
  state.bars.forEach((b) => {
    if (!b) return;
    const r = names.indexOf(b.drone);
    if (r < 0) return;
    const end = b.end === null || b.end === undefined ? nowT : b.end;
    const x = X(b.start - t0), x2 = Math.max(x + 2, X(end - t0));
    const fill = { ok: colourOf(b.drone), running: "#4dabf7", failed: "#ff6b6b", cancelled: "#ffa94d" }[b.result] || "#ddd";
    const g = el("g", { class: "bar", "data-drone": b.drone, "data-node": b.node, "data-result": b.result });
    g.appendChild(el("title", {}, `${b.drone} ${b.label} (${b.node}) ${b.result}: ${(b.start - t0).toFixed(2)}..${(end - t0).toFixed(2)} s`));
    g.appendChild(el("rect", { x, y: top + r * rowH + 3, width: x2 - x, height: rowH - 6, fill, stroke: "#333", "stroke-width": 0.5 }));
    if (x2 - x > 7 * b.label.length) g.appendChild(el("text", { x: x + 3, y: top + r * rowH + 15, class: "tick", fill: "#000" }, b.label));
    svg.appendChild(g);
  });
}

// -- graphs -------------------------------------------------------------------------------

async function graphPicture(svgText) {
  // A compiler's MDG picture, ready for the page: sized, each node named by its key.
  const doc = new DOMParser().parseFromString(svgText, "image/svg+xml");
  const svg = document.importNode(doc.documentElement, true);
  // Graphviz sizes pictures in points: show them at 3/4 of that, scrolling inside their box.
  const vb = (svg.getAttribute("viewBox") || "").split(/[ ,]+/).map(Number);
  if (vb.length === 4 && vb[2] > 0) {
    svg.setAttribute("width", Math.round(vb[2] * 0.75));
    svg.setAttribute("height", Math.round(vb[3] * 0.75));
  }
  for (const g of svg.querySelectorAll("g.node")) {
    const title = g.querySelector("title");
    if (!title) continue;
    g.dataset.node = title.textContent.trim();
    g.dataset.state = "waiting";
    for (const s of g.querySelectorAll("ellipse, polygon, path, rect")) s.dataset.fill = s.getAttribute("fill") || "none";
  }
  return svg;
}

async function loadGraph(div, name) {
  const res = await fetch(`/api/graph/${encodeURIComponent(name)}`);
  if (!res.ok) { div.appendChild(document.createTextNode("(no picture)")); return; }
  div.appendChild(await graphPicture(await res.text()));
}

async function loadGraphs() {
  const box = $("graphs");
  for (const p of setup.participants) {
    const div = document.createElement("div");
    div.className = "mdg-box";
    div.dataset.participant = p.name;
    div.innerHTML = `<h3><span class="swatch" style="background:${p.colour}"></span>${p.name}</h3>`;
    box.appendChild(div);
    await loadGraph(div, p.name);
  }
  $("graphs-section").querySelector(".legend").innerHTML = Object.keys(NODE_COLOURS)
    .map((k) => `<span style="background:${NODE_COLOURS[k] || "#fff"}">${k}</span>`).join("");
  schedule();
}

function colourGraphs() {
  for (const g of document.querySelectorAll("#graphs g.node")) {
    const node = state.nodes[g.dataset.node];
    if (!node) continue;
    const changed = g.dataset.state !== node.state || g.dataset.count !== String(node.count);
    if (!changed && g.dataset.value === String(node.value)) continue;
    g.dataset.state = node.state;
    g.dataset.count = node.count;
    g.dataset.value = node.value;
    for (const s of g.querySelectorAll("ellipse, polygon, path, rect")) {
      const c = NODE_COLOURS[node.state];
      s.setAttribute("fill", c || s.dataset.fill);
      s.setAttribute("fill-opacity", c ? "1" : "0.45");
      s.setAttribute("stroke-width", node.state === "running" ? "3" : "1");
    }
    const old = g.querySelector("text.count");
    if (old) old.remove();
    const extra = [];
    if (node.iteration && node.iteration.length) extra.push(`iteration ${node.iteration.join(".")} (#${node.count})`);
    if (node.value !== undefined && node.value !== null) extra.push(node.value ? "true" : "false");
    if (extra.length) {
      const bb = g.getBBox();
      g.appendChild(el("text", { x: bb.x + bb.width, y: bb.y + 8, class: "count" }, extra.join(" ")));
    }
  }
}

function markPredicted() {
  // The nodes whose actions a look-ahead prediction names, outlined on the graphs.
  const names = new Map();
  for (const p of ((state.forecast || {}).predictions || [])) {
    for (const n of p.nodes || []) names.set(n, `${p.check}${p.in_s === null || p.in_s === undefined ? "" : ` in ${Math.round(p.in_s)} s`}`);
  }
  for (const g of document.querySelectorAll("#graphs g.node")) {
    const why = names.get(g.dataset.node);
    if ((g.dataset.predicted || "") === (why || "")) continue;
    g.classList.toggle("predicted", !!why);
    if (why) g.dataset.predicted = why; else delete g.dataset.predicted;
  }
}

// -- the operator's commands --------------------------------------------------------------

// MAVLink's MAV_SEVERITY, 0 to 7.
const SEVERITIES = ["EMERGENCY", "ALERT", "CRITICAL", "ERROR", "WARNING", "NOTICE", "INFO", "DEBUG"];
const DRONE_COMMANDS = [["hold", "Hold"], ["resume", "Resume"], ["land", "Land"],
  ["return-home", "Home"], ["release", "Release"]];
const QUESTIONS = {
  pause: "Pause the mission? Every drone holds where it is until Resume.",
  resume: "Resume the mission? Every suspended action goes on.",
  hold: "holds where it is until Resume.",
  resume1: "goes on (or, released, EAMOS takes it back).",
  land: "lands now; its remaining actions fail.",
  "return-home": "flies home and lands; its remaining actions fail.",
  release: "is handed to a pilot: EAMOS stops commanding it until Resume.",
};
let pending = null;

function commandsOn() {
  return !!token && !replay && !!state && !FINAL.has(state.mission.state) && !!ws && ws.readyState === 1;
}

function askCommand(command, drone) {
  pending = { command, drone };
  const q = drone ? `${drone} ${QUESTIONS[command === "resume" ? "resume1" : command]}` : QUESTIONS[command];
  $("cmd-question").textContent = q;
  $("cmd-confirm").hidden = false;
}

async function doCommand() {
  $("cmd-confirm").hidden = true;
  $("amend-confirm").hidden = true;
  if (!pending) return;
  const { command, drone } = pending;
  pending = null;
  const res = await fetch("/api/command", {
    method: "POST",
    headers: { "Content-Type": "application/json" },
    body: JSON.stringify({ token, command, drone }),
  });
  const body = await res.json().catch(() => ({}));
  const out = command === "amend" ? $("amend-result") : $("cmd-result");
  out.hidden = false;
  out.dataset.ok = res.ok ? "yes" : "no";
  if (command === "amend") {
    out.textContent = res.ok ? `amendment ${drone} applied.` : `amendment ${drone} not applied: ${body.error || res.status}`;
    if (res.ok) { $("amend-apply").hidden = true; $("amend-compare").replaceChildren(); amendment = null; markAmended(); }
  } else {
    out.textContent = res.ok ? `${command} sent to ${drone || "every drone"}.` : `${command} refused: ${body.error || res.status}`;
  }
}

// -- an amendment: judged as `eamos amend` judges it, then applied with a confirmation -------

let amendment = null; // the latest judgement: its changes, to mark on the graphs
let staged = null; // the number of the staged amendment the Apply button applies

async function checkAmendment() {
  const file = $("amend-file").files[0];
  if (!file) return;
  const out = $("amend-report");
  out.hidden = false;
  out.dataset.verdict = "checking";
  out.textContent = `checking ${file.name} ...`;
  $("amend-apply").hidden = true;
  $("amend-result").hidden = true;
  $("amend-compare").replaceChildren();
  staged = null;
  const res = await fetch("/api/amend", {
    method: "POST",
    headers: { "Content-Type": "application/json" },
    body: JSON.stringify({ token, text: await file.text() }),
  });
  const body = await res.json().catch(() => ({}));
  if (!res.ok || !body.ok) {
    amendment = null;
    out.dataset.verdict = "bad";
    out.textContent = `${file.name}: ${body.error || res.status}`;
  } else {
    amendment = body.report;
    out.dataset.verdict = body.accepted ? "accepted" : "refused";
    out.textContent = body.lines.join("\n") + (body.staged ? `\nstaged in ${body.staged}` : "");
    if (body.number !== null && body.number !== undefined) {
      staged = body.number;
      await compareGraphs(body.report, body.graphs || {});
      $("amend-apply").textContent = `Apply amendment ${staged}`;
      $("amend-apply").hidden = false;
    }
  }
  markAmended();
}

async function compareGraphs(report, graphs) {
  // Each drone the amendment changes: its graph as it flies and as amended, side by side.
  const box = $("amend-compare");
  for (const [name, svgText] of Object.entries(graphs)) {
    const change = (report.changes || {})[name] || {};
    const now = document.querySelector(`#graphs .mdg-box[data-participant="${name}"] svg`);
    const pair = document.createElement("div");
    pair.className = "amend-pair";
    pair.dataset.participant = name;
    const before = document.createElement("div");
    before.className = "amend-before";
    before.innerHTML = `<h3>${name}: flying</h3>`;
    if (now) before.appendChild(now.cloneNode(true));
    const after = document.createElement("div");
    after.className = "amend-after";
    after.innerHTML = `<h3>${name}: amended</h3>`;
    after.appendChild(await graphPicture(svgText));
    const old = new Set([...(change.touched || []), ...(change.redirected || [])]);
    const fresh = new Set([...(change.added || []), ...(change.changed || [])].map((n) => n.key));
    for (const g of before.querySelectorAll("g.node")) g.classList.toggle("amended", old.has(g.dataset.node));
    for (const g of after.querySelectorAll("g.node")) g.classList.toggle("amended-new", fresh.has(g.dataset.node));
    pair.append(before, after);
    box.appendChild(pair);
    for (const [side, cls] of [[before, "amended"], [after, "amended-new"]]) {
      // The first marked node in view in its box (the graphs are taller than the box).
      const g = side.querySelector(`g.node.${cls}`);
      if (g) side.scrollTop += g.getBoundingClientRect().top - side.getBoundingClientRect().top - 60;
    }
  }
}

function askApply() {
  if (staged === null) return;
  pending = { command: "amend", drone: String(staged) };
  const drones = ((amendment || {}).touched || []).join(", ");
  $("amend-question").textContent = `Apply amendment ${staged} to ${drones}? Their nodes not yet begun are replaced; the other drones fly on untouched.`;
  $("amend-confirm").hidden = false;
}

async function redrawGraphs(names) {
  for (const name of names) {
    const div = document.querySelector(`#graphs .mdg-box[data-participant="${name}"]`);
    if (!div) continue;
    for (const svg of div.querySelectorAll("svg")) svg.remove();
    await loadGraph(div, name);
  }
  schedule();
}

function markAmended() {
  // The running nodes an amendment touches (changed, removed, or redirected), outlined.
  const touched = new Set();
  for (const change of Object.values((amendment || {}).changes || {})) {
    for (const key of [...(change.touched || []), ...(change.redirected || [])]) touched.add(key);
  }
  for (const g of document.querySelectorAll("#graphs g.node")) g.classList.toggle("amended", touched.has(g.dataset.node));
}

// -- abort and replay ---------------------------------------------------------------------

async function doAbort() {
  $("confirm").hidden = true;
  const res = await fetch("/api/abort", {
    method: "POST",
    headers: { "Content-Type": "application/json" },
    body: JSON.stringify({ token }),
  });
  const body = await res.json().catch(() => ({}));
  const out = $("abort-result");
  out.hidden = false;
  out.textContent = res.ok ? "Abort sent: every drone lands." : `Abort refused: ${body.error || res.status}`;
}

function seek(t) {
  replayT = Math.min(replay.end, Math.max(replay.start, t));
  $("slider").value = Math.round(((replayT - replay.start) / Math.max(1e-6, replay.end - replay.start)) * 1000);
  $("replay-time").textContent = `${(replayT - replay.started).toFixed(1)} s`;
  if (ws && ws.readyState === 1 && !seekPending) {
    seekPending = true;
    ws.send(JSON.stringify({ type: "seek", t: replayT }));
  }
}

function setupReplay() {
  $("replay").hidden = false;
  $("slider").addEventListener("input", (e) => {
    seekPending = false;
    seek(replay.start + (e.target.value / 1000) * (replay.end - replay.start));
  });
  $("play").addEventListener("click", () => {
    if (playing) { clearInterval(playing); playing = null; $("play").textContent = "Play"; return; }
    if (replayT >= replay.end) replayT = replay.start;
    $("play").textContent = "Pause";
    playing = setInterval(() => {
      const speed = Number($("speed").value);
      seek(replayT + 0.1 * speed);
      if (replayT >= replay.end) { clearInterval(playing); playing = null; $("play").textContent = "Play"; }
    }, 100);
  });
  replayT = replay.end;
}

async function main() {
  setup = await (await fetch("/api/setup")).json();
  replay = setup.replay;
  $("mission-name").textContent = `${setup.mission} (${setup.mission_id})`;
  document.title = `EAMOS monitor: ${setup.mission}`;
  $("abort").addEventListener("click", () => { $("confirm").hidden = false; });
  $("abort-yes").addEventListener("click", doAbort);
  $("abort-no").addEventListener("click", () => { $("confirm").hidden = true; });
  $("pause").addEventListener("click", () => askCommand("pause", ""));
  $("resume").addEventListener("click", () => askCommand("resume", ""));
  $("cmd-yes").addEventListener("click", doCommand);
  $("cmd-no").addEventListener("click", () => { $("cmd-confirm").hidden = true; pending = null; });
  $("amend-check").addEventListener("click", checkAmendment);
  $("amend-apply").addEventListener("click", askApply);
  $("amend-yes").addEventListener("click", doCommand);
  $("amend-no").addEventListener("click", () => { $("amend-confirm").hidden = true; pending = null; });
  if (replay) setupReplay();
  await loadGraphs();
  connect();
  setInterval(() => { if (state && !FINAL.has(state.mission.state)) schedule(); }, 250);
}

main();
