// The lab dashboard's page (scripts/dashboard, docs/dashboard.md). Plain JavaScript and canvas,
// nothing loaded from elsewhere. Every text that comes from a stand (namespace, device serial,
// messages, faults) is set with textContent, never parsed as HTML.
"use strict";

const PHASES = ["x", "y", "z"];
const ACCEL = ["u", "v", "w"];
const ANGLES = ["uv", "vw", "wu"];
const COLORS = { x: "#dc2626", y: "#16a34a", z: "#2563eb", "-": "#7c3aed" };
const stands = new Map(); // ns -> {card, dwells: Map(index -> dwell), fits, el: {...}}

function el(tag, cls, text) {
  const e = document.createElement(tag);
  if (cls) e.className = cls;
  if (text !== undefined) e.textContent = text;
  return e;
}

function fmtFixed(x, d) { return Number.isFinite(x) ? x.toFixed(d) : "-"; }
function fmtExp(x, d) { return Number.isFinite(x) ? x.toExponential(d) : "-"; }

// ---- Cards ------------------------------------------------------------------------------------

function makeCard(ns) {
  const root = el("section", "card");
  root.dataset.ns = ns;
  const h = el("h2");
  const name = el("span", "ns", ns);
  const device = el("span", "device");
  const state = el("span", "badge state");
  const lost = el("span", "lostbadge");
  h.append(name, device, state, lost);
  const controller = el("div", "line controller");
  const bar = el("div", "bar");
  const fill = el("div");
  bar.append(fill);
  const counts = el("div", "line counts");
  const message = el("div", "line message");
  const plots = el("div", "plots");
  const canvases = {};
  for (const a of ACCEL) {
    const box = el("div", "plot");
    const title = el("span", "", a + ": dwell means and residuals (m/s\u00b2)");
    const main = document.createElement("canvas");
    main.width = 240; main.height = 150; main.className = "means";
    main.dataset.accel = a;
    const resid = document.createElement("canvas");
    resid.width = 240; resid.height = 60; resid.className = "residuals";
    box.append(title, main, resid);
    plots.append(box);
    canvases[a] = { main, resid };
  }
  const points = el("div", "line points");
  const tumble = el("div", "tumble");
  const result = el("div", "resultbox");
  const faultsTitle = el("div", "line", "Faults");
  const faults = el("ul", "faults");
  root.append(h, controller, bar, counts, message, plots, points, tumble, result, faultsTitle, faults);
  document.getElementById("stands").append(root);
  return { root, device, state, lost, controller, fill, counts, message, canvases, points,
           tumble, result, faults, faultsTitle };
}

function standOf(ns) {
  let s = stands.get(ns);
  if (!s) {
    s = { card: null, dwells: new Map(), fits: {}, el: makeCard(ns) };
    stands.set(ns, s);
    const main = document.getElementById("stands");
    [...main.children].sort((a, b) => a.dataset.ns.localeCompare(b.dataset.ns))
      .forEach((c) => main.append(c));
    document.getElementById("empty").hidden = true;
  }
  return s;
}

function renderCard(s) {
  const c = s.card, e = s.el;
  e.device.textContent = c.device ? "device " + c.device : "";
  e.state.textContent = c.state || "?";
  e.state.className = "badge state " + (c.state || "");
  e.lost.textContent = c.lost ? "LOST: " + c.lost : "";
  e.root.classList.toggle("lost", !!c.lost);
  const where = c.phase !== "" ? "phase " + c.phase + ", step " + c.step + " of " + c.steps : "";
  const pos = c.positions ? "position " + c.position + " of " + c.positions : "";
  const left = c.time_left_s !== null ? Math.round(c.time_left_s) + " s left" : "";
  e.controller.textContent = ["gimbal " + (c.controller_state || "?"), where, pos, left]
    .filter((t) => t).join(" \u00b7 ");
  const frac = c.fraction !== null ? c.fraction : (c.state === "RESULT" ? 1 : 0);
  e.fill.style.width = Math.max(0, Math.min(100, 100 * frac)).toFixed(1) + "%";
  e.counts.textContent = "dwells x/y/z: " + c.dwells_per_phase.join("/") + " \u00b7 table rows: " + c.rows;
  e.message.textContent = [c.status_message, c.controller_message].filter((t) => t).join(" | ");
  renderTumble(c, e);
  renderResult(c.result, e.result);
  e.faults.replaceChildren(...c.faults.map((f) => el("li", "fault", f.source + ": " + f.text)));
  e.faultsTitle.hidden = c.faults.length === 0;
}

function renderTumble(c, e) {
  const t = c.tumble;
  if (!t) { e.tumble.textContent = ""; return; }
  const cov = t.coverage ? (t.coverage.complete ? "complete" : "missing: " + t.coverage.missing.join("; ")) : "-";
  const next = t.next_pose ? t.next_pose.words : "";
  e.tumble.textContent = "tumble: " + t.rests + " rests (" + t.rejected + " rejected), coverage " + cov +
    (next ? " \u00b7 next pose: " + next : "") + (t.message ? " \u00b7 " + t.message : "");
}

function cell(tr, text, cls, key) {
  const td = el("td", cls, text);
  if (key) td.dataset.key = key;
  tr.append(td);
}

function renderResult(r, box) {
  if (!r) { box.replaceChildren(); return; }
  const gate = el("div", "gate " + (r.quality_pass ? "pass" : "fail"),
    "quality gate: " + (r.quality_pass ? "PASS" : "FAIL") +
    (r.quality_reasons.length ? " (" + r.quality_reasons.join("; ") + ")" : ""));
  const table = el("table", "result");
  const head = el("tr");
  for (const t of ["", "value", "std (k=1)", "", "value", "std (k=1)"]) head.append(el("th", "", t));
  table.append(head);
  for (let i = 0; i < 3; ++i) {
    const tr = el("tr");
    tr.append(el("th", "", "|" + ACCEL[i] + "|"));
    cell(tr, fmtFixed(r.responsivity[i], 6), "v", "responsivity." + ACCEL[i]);
    cell(tr, fmtExp(r.responsivity_std[i], 2), "s", "responsivity_std." + ACCEL[i]);
    tr.append(el("th", "", "angle " + ANGLES[i] + " (deg)"));
    cell(tr, fmtFixed(r.angles_deg[i], 4), "v", "angles_deg." + ANGLES[i]);
    cell(tr, fmtExp(r.angles_std_deg[i], 2), "s", "angles_std_deg." + ANGLES[i]);
    table.append(tr);
  }
  for (let i = 0; i < 3; ++i) {
    const tr = el("tr");
    tr.append(el("th", "", "offset " + ACCEL[i] + " (m/s\u00b2)"));
    cell(tr, fmtFixed(r.offset[i], 6), "v", "offset." + ACCEL[i]);
    cell(tr, fmtExp(r.offset_std[i], 2), "s", "offset_std." + ACCEL[i]);
    tr.append(el("th", "", "positions " + PHASES[i]));
    cell(tr, String(r.positions[i]), "v", "positions." + PHASES[i]);
    tr.append(el("td"));
    table.append(tr);
  }
  const tr = el("tr");
  tr.append(el("th", "", "reduced \u03c7\u00b2"));
  cell(tr, fmtFixed(r.reduced_chi2, 3), "v", "reduced_chi2");
  tr.append(el("td"));
  tr.append(el("th", "", "residual rms (m/s\u00b2)"));
  cell(tr, fmtExp(r.residual_rms, 3), "v", "residual_rms");
  tr.append(el("td"));
  table.append(tr);
  const model = el("div", "line", "model " + r.model + " \u00b7 g = " + fmtFixed(r.local_gravity, 5) + " m/s\u00b2" +
    (r.effects.length ? " \u00b7 effects: " + r.effects.map((f) => f.name + "[" + f.target + "]").join(", ") : ""));
  box.replaceChildren(gate, table, model);
}

// ---- Plots ------------------------------------------------------------------------------------

function eq4(coef, a) { return coef[0] + coef[1] * Math.sin(a) + coef[2] * Math.cos(a); }

function drawPlots(s) {
  const dwells = [...s.dwells.values()].sort((p, q) => p.index - q.index);
  const byIndex = dwells.some((d) => d.phase === "-"); // a tumble: rests by number, no curve
  const xOf = (d) => byIndex ? d.index : ((d.angle * 180 / Math.PI) % 360 + 360) % 360;
  const xMax = byIndex ? Math.max(1, dwells.length) : 360;
  ACCEL.forEach((a, i) => {
    const { main, resid } = s.el.canvases[a];
    const ys = dwells.map((d) => d.mean[i]);
    let lo = Math.min(...ys, Infinity), hi = Math.max(...ys, -Infinity);
    if (!Number.isFinite(lo)) { lo = -10; hi = 10; }
    if (hi - lo < 1e-6) { lo -= 1; hi += 1; }
    const pad = 0.08 * (hi - lo); lo -= pad; hi += pad;
    const g = main.getContext("2d");
    g.clearRect(0, 0, main.width, main.height);
    const X = (x) => 4 + (main.width - 8) * x / xMax;
    const Y = (y) => main.height - 4 - (main.height - 8) * (y - lo) / (hi - lo);
    g.strokeStyle = "#e5e7eb"; g.beginPath(); g.moveTo(0, Y(0)); g.lineTo(main.width, Y(0)); g.stroke();
    for (const p of byIndex ? [] : PHASES) {
      const coef = s.fits[p] && s.fits[p][a];
      if (!coef) continue;
      g.strokeStyle = COLORS[p]; g.lineWidth = 1; g.beginPath();
      for (let k = 0; k <= 120; ++k) {
        const ang = 2 * Math.PI * k / 120;
        const px = X(ang * 180 / Math.PI), py = Y(eq4(coef, ang));
        if (k === 0) g.moveTo(px, py); else g.lineTo(px, py);
      }
      g.stroke();
    }
    let drawn = 0;
    for (const d of dwells) {
      g.fillStyle = COLORS[d.phase] || "#000";
      g.beginPath(); g.arc(X(xOf(d)), Y(d.mean[i]), 2.5, 0, 2 * Math.PI); g.fill();
      ++drawn;
    }
    main.dataset.points = String(drawn);
    g.fillStyle = "#374151"; g.font = "10px sans-serif";
    g.fillText(hi.toFixed(3), 6, 12); g.fillText(lo.toFixed(3), 6, main.height - 6);
    g.fillText(byIndex ? "rest" : "angle 0..360\u00b0", main.width - 80, main.height - 6);
    // Residuals: mean - curve of its phase, same x.
    const rs = dwells.filter((d) => s.fits[d.phase] && s.fits[d.phase][a])
      .map((d) => ({ d, r: d.mean[i] - eq4(s.fits[d.phase][a], d.angle) }));
    const h = resid.getContext("2d");
    h.clearRect(0, 0, resid.width, resid.height);
    const rmax = Math.max(1e-9, ...rs.map((q) => Math.abs(q.r)));
    const RY = (r) => resid.height / 2 - (resid.height / 2 - 4) * r / rmax;
    h.strokeStyle = "#9ca3af"; h.beginPath(); h.moveTo(0, RY(0)); h.lineTo(resid.width, RY(0)); h.stroke();
    for (const q of rs) {
      h.fillStyle = COLORS[q.d.phase];
      h.fillRect(X(xOf(q.d)) - 2, RY(q.r) - 2, 4, 4);
    }
    resid.dataset.points = String(rs.length);
    h.fillStyle = "#374151"; h.font = "10px sans-serif";
    h.fillText("\u00b1" + rmax.toExponential(1), 4, 10);
  });
  s.el.points.textContent = "dwells plotted: " + dwells.length;
  s.el.points.dataset.count = String(dwells.length);
}

// ---- The lab archive (with the dashboard's ~archive) -------------------------------------------

const PARAMS = [["responsivity_u", "|u|", 6], ["responsivity_v", "|v|", 6], ["responsivity_w", "|w|", 6],
  ["angle_uv", "uv (deg)", 4], ["angle_vw", "vw (deg)", 4], ["angle_wu", "wu (deg)", 4],
  ["offset_u", "O_u", 5], ["offset_v", "O_v", 5], ["offset_w", "O_w", 5]];

function renderArchive(view) {
  const box = document.getElementById("archive");
  if (!view) { box.hidden = true; return; }
  box.hidden = false;
  const parts = [el("h2", "", "Lab archive " + view.url)];
  if (view.error) parts.push(el("p", "archive-error", "cannot read the archive: " + view.error));
  for (const d of view.devices) {
    const section = el("div", "archive-device");
    section.dataset.serial = d.serial;
    section.append(el("h3", "serial", d.serial));
    section.append(el("div", "line", "rig " + d.rig + " \u00b7 " + d.records + " records \u00b7 latest " + d.latest));
    const table = el("table", "result history");
    const head = el("tr");
    for (const t of ["time", "rig", "method"].concat(PARAMS.map((p) => p[1]))) head.append(el("th", "", t));
    table.append(head);
    for (const r of (view.histories[d.serial] || []).filter((r) => r.rig === d.rig)) {
      const tr = el("tr");
      tr.append(el("td", "", r.time), el("td", "", r.rig), el("td", "", r.method));
      for (const [key, , digits] of PARAMS) {
        tr.append(el("td", "", fmtFixed(r.values[key], digits) + " \u00b1 " + fmtExp(r.expanded[key], 1)));
      }
      table.append(tr);
    }
    const rows = (view.histories[d.serial] || []).filter((r) => r.rig === d.rig);
    const plots = el("div", "plots history-plots");
    for (const [key, label] of PARAMS.slice(0, 3)) {
      plots.append(smallPlot(label + " over time", (c) => drawTimeSeries(c, rows.map((r) => ({
        t: Date.parse(r.time), y: r.values[key], lo: r.values[key] - r.expanded[key],
        hi: r.values[key] + r.expanded[key] }))), "history"));
    }
    section.append(plots, table);
    parts.push(section);
  }
  if (!view.error && !view.devices.length) parts.push(el("p", "", "no records yet"));
  for (const rig of Object.keys(view.charts || {}).sort()) parts.push(renderChart(rig, view.charts[rig]));
  box.replaceChildren(...parts);
}

// A labelled canvas; draw(canvas) fills it.
function smallPlot(label, draw, cls) {
  const box = el("div", "plot");
  const c = document.createElement("canvas");
  c.width = 240; c.height = 110; c.className = cls;
  box.append(el("span", "", label), c);
  draw(c);
  return box;
}

// Points {t (ms), y, lo, hi, flagged} against time, with optional limit bands {lo, hi} per point.
function drawTimeSeries(c, pts, limits) {
  const g = c.getContext("2d");
  g.clearRect(0, 0, c.width, c.height);
  c.dataset.points = String(pts.length);
  if (!pts.length) return;
  const ts = pts.map((p) => p.t);
  const ys = pts.flatMap((p) => [p.lo, p.hi, p.y]).concat((limits || []).flatMap((l) => l ? [l.lo, l.hi] : []));
  let t0 = Math.min(...ts), t1 = Math.max(...ts);
  if (t1 - t0 < 1) { t0 -= 1000; t1 += 1000; }
  let lo = Math.min(...ys), hi = Math.max(...ys);
  if (!(hi - lo > 1e-12)) { lo -= 1e-6; hi += 1e-6; }
  const pad = 0.08 * (hi - lo); lo -= pad; hi += pad;
  const X = (t) => 8 + (c.width - 16) * (t - t0) / (t1 - t0);
  const Y = (y) => c.height - 4 - (c.height - 8) * (y - lo) / (hi - lo);
  if (limits) {
    for (const [k, color] of [[2, "#f59e0b"], [3, "#dc2626"]]) {
      for (const side of [1, -1]) {
        g.strokeStyle = color; g.setLineDash([4, 3]); g.beginPath();
        pts.forEach((p, i) => {
          const y = Y(side * k * limits[i].U);
          if (i === 0) g.moveTo(X(p.t), y); else g.lineTo(X(p.t), y);
        });
        g.stroke();
      }
    }
    g.setLineDash([]);
    g.strokeStyle = "#9ca3af"; g.beginPath(); g.moveTo(0, Y(0)); g.lineTo(c.width, Y(0)); g.stroke();
  }
  let flagged = 0;
  for (const p of pts) {
    g.strokeStyle = "#6b7280"; g.beginPath(); g.moveTo(X(p.t), Y(p.lo)); g.lineTo(X(p.t), Y(p.hi)); g.stroke();
    g.fillStyle = p.flagged ? "#dc2626" : "#2563eb";
    g.beginPath(); g.arc(X(p.t), Y(p.y), p.flagged ? 4 : 2.5, 0, 2 * Math.PI); g.fill();
    if (p.flagged) ++flagged;
  }
  c.dataset.flagged = String(flagged);
  g.fillStyle = "#374151"; g.font = "10px sans-serif";
  g.fillText(hi.toExponential(2), 4, 10); g.fillText(lo.toExponential(2), 4, c.height - 4);
}

// A rig's control chart: its check standard's deviations from the reference with the 2U and 3U
// limits (U: each record's expanded uncertainty); points a run rule flagged in red.
function renderChart(rig, chart) {
  const section = el("div", "control-chart");
  section.dataset.rig = rig;
  section.append(el("h3", "rig", "control chart of rig " + rig));
  section.append(el("div", "line", "check standard " + chart.serial + " \u00b7 " + chart.points.length +
    " records \u00b7 dashed: 2U (amber), 3U (red)"));
  const plots = el("div", "plots");
  for (const [key, label] of PARAMS.slice(0, 6)) {
    const flaggedAt = new Set(chart.flags.filter((f) => f.parameter === key).map((f) => f.index));
    const pts = chart.points.map((p, i) => ({
      t: Date.parse(p.time), y: p.deviation[key], lo: p.deviation[key] - p.expanded[key],
      hi: p.deviation[key] + p.expanded[key], flagged: flaggedAt.has(i) }));
    plots.append(smallPlot("deviation of " + label, (c) => drawTimeSeries(c, pts,
      chart.points.map((p) => ({ U: p.expanded[key], lo: -3 * p.expanded[key], hi: 3 * p.expanded[key] }))),
      "chart"));
  }
  section.append(plots);
  const flags = el("ul", "faults");
  for (const f of chart.flags) flags.append(el("li", "", f.time + " " + f.parameter + ": " + f.rule));
  if (chart.flags.length) section.append(flags);
  return section;
}

// ---- Events from the server -------------------------------------------------------------------

function onStand(card) {
  const s = standOf(card.ns);
  s.card = card;
  renderCard(s);
}

function onEvent(ev) {
  if (ev.type === "snapshot") {
    renderArchive(ev.archive);
    for (const card of ev.stands) {
      const s = standOf(card.ns);
      s.dwells = new Map(card.dwells.map((d) => [d.index, d]));
      s.fits = card.fits;
      onStand(card);
      drawPlots(s);
    }
  } else if (ev.type === "archive") {
    renderArchive(ev.archive);
  } else if (ev.type === "stand") {
    onStand(ev.stand);
  } else if (ev.type === "dwell") {
    const s = standOf(ev.ns);
    for (const k of [...s.dwells.keys()]) if (k >= ev.dwell.index) s.dwells.delete(k);
    s.dwells.set(ev.dwell.index, ev.dwell);
    s.fits = ev.fits;
    drawPlots(s);
  }
  document.getElementById("updated").textContent = "updated " + new Date().toLocaleTimeString();
}

function connect() {
  const badge = document.getElementById("connection");
  const ws = new WebSocket((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws");
  ws.onopen = () => { badge.textContent = "live"; badge.className = "connection open"; };
  ws.onmessage = (m) => onEvent(JSON.parse(m.data));
  ws.onclose = () => {
    badge.textContent = "disconnected: retrying"; badge.className = "connection closed";
    setTimeout(connect, 1000);
  };
}

document.addEventListener("DOMContentLoaded", connect);
