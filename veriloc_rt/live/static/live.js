// The live view: polls /api/state every POLL_MS and redraws; the map's fixed layer comes from
// /api/scene once per run. Points are fetched incrementally (?from=N) per scenario.
"use strict";

const POLL_MS = 500;
const OUTCOME_COLOURS = ["#2e9d55", "#f08c2e", "#8a8f98"];  // success, large error, failure
let selected = null;        // scenario shown on the map and the timeline
let scene = null;           // /api/scene
let sceneVersion = -1;
let lastState = null;
const points = {};          // scenario -> {generation, cols}

function emptyCols() {
  return {index: [], time_s: [], x_true: [], y_true: [], x_est: [], y_est: [], outcome: [],
          attack: [], verdicts: {}};
}

function merge(p) {
  let have = points[p.scenario];
  if (!have || have.generation !== p.generation || p.from !== have.cols.index.length) {
    if (p.from !== 0) return false;           // out of step: ask again from 0
    have = points[p.scenario] = {generation: p.generation, cols: emptyCols()};
  }
  const c = have.cols;
  for (const k of ["index", "time_s", "x_true", "y_true", "x_est", "y_est", "outcome", "attack"])
    c[k].push(...p[k]);
  for (const [d, v] of Object.entries(p.verdicts)) (c.verdicts[d] = c.verdicts[d] || []).push(...v);
  return true;
}

async function poll() {
  try {
    let from = 0;
    if (selected && points[selected]) from = points[selected].cols.index.length;
    let url = "/api/state?from=" + from + (selected ? "&scenario=" + encodeURIComponent(selected) : "");
    let st = await getJSON(url);
    if (st.points && !merge(st.points)) {
      st = await getJSON("/api/state?from=0&scenario=" + encodeURIComponent(st.points.scenario));
      if (st.points) { delete points[st.points.scenario]; merge(st.points); }
    }
    if (st.points) selected = st.points.scenario;
    if (st.scene_version !== sceneVersion || (scene && !scene.ready)) {
      const sc = await getJSON("/api/scene");
      scene = sc; sceneVersion = sc.version;
    }
    lastState = st;
    render(st);
  } catch (e) {
    const s = document.getElementById("status");
    s.textContent = e.status === 403 ? "no access: open the URL (with its ?token=) the command printed"
                                     : "view server not reachable";
    s.className = "badge stopped";
  }
  setTimeout(poll, POLL_MS);
}

function render(st) {
  const s = document.getElementById("status");
  let status = st.status;
  if (st.process && st.process.returncode !== null && st.process.returncode !== 0) status = "failed";
  s.textContent = status; s.className = "badge " + status;
  const stages = {setup: "setting up", propagation: "computing the links (ray tracing or UMa)",
                  scenarios: "evaluating the points", done: "finished"};
  let stage = stages[st.stage] || st.stage;
  if (st.montecarlo) stage = "Monte Carlo: " + st.montecarlo.done + " of " + st.montecarlo.total +
    " realisations complete; showing " + st.montecarlo.following + " (" + stage + ")";
  document.getElementById("stage").textContent = stage;
  document.getElementById("eta").textContent = st.status === "complete" ? "done" : fmtDuration(st.eta_s);
  document.getElementById("folder").textContent = st.folder;
  const proc = document.getElementById("process");
  if (st.process && st.process.returncode !== null && st.process.returncode !== 0) {
    proc.textContent = "the run stopped (exit " + st.process.returncode + "): " + st.process.message;
    proc.className = "message error";
  } else if (st.status === "stopped") {
    proc.textContent = "the run ended unfinished: `veriloc-rt run ... --resume` continues it";
    proc.className = "message error";
  } else proc.textContent = "";
  renderProgress(st);
  renderShares(st);
  renderTabs(st);
  drawMap();
  renderDecisions(st);
}

function renderProgress(st) {
  const box = document.getElementById("progress");
  box.replaceChildren(...st.scenarios.map(sc => {
    const frac = sc.total ? sc.done / sc.total : 0;
    const row = el("div", {class: "progress-row" + (sc.name === selected ? " selected" : ""),
                           id: "progress-" + sc.name, "data-done": sc.done, "data-total": sc.total ?? ""},
      el("span", {class: "name", text: sc.name}),
      el("div", {class: "bar"}, el("div", {style: "width:" + (100 * frac).toFixed(1) + "%"})),
      el("span", {class: "num", text: sc.done + " / " + (sc.total ?? "?")}),
      el("span", {class: "eta", text: sc.done >= sc.total ? "done" : "ETA " + fmtDuration(sc.eta_s)}));
    row.addEventListener("click", () => select(sc.name));
    return row;
  }));
}

// a share's 95 % interval ([lo, hi] fractions in metrics.json) as a tooltip, in percent
function ci(iv) {
  return Array.isArray(iv) ? "95 % interval " + (100 * iv[0]).toFixed(1) + "–" + (100 * iv[1]).toFixed(1) + " %" : "";
}

function renderShares(st) {
  const box = document.getElementById("shares");
  box.replaceChildren(...st.scenarios.map(sc => {
    const o = (sc.metrics && sc.metrics.outcomes) || {};
    const stack = el("div", {class: "stack", title: sc.name});
    for (const k of st.outcomes) {
      const v = 100 * (o[k] || 0);   // metrics hold fractions in [0, 1]
      if (v > 0) stack.append(el("div", {class: "s-" + k, style: "width:" + v + "%",
                                         title: k + " " + v.toFixed(1) + " %", text: v >= 12 ? v.toFixed(0) + "%" : ""}));
    }
    return el("div", {class: "shares-row", "data-scenario": sc.name}, el("span", {text: sc.name}), stack);
  }));
  const t = document.getElementById("rates");
  const head = el("tr", {}, el("th", {text: "scenario"}), ...st.detectors.map(d => el("th", {text: d})));
  const rows = st.scenarios.map(sc => {
    const r = (sc.metrics && sc.metrics.correct_decision_rate) || {};
    const uninf = (sc.metrics && sc.metrics.uninformative_detectors) || [];
    return el("tr", {}, el("td", {text: sc.name}),
              ...st.detectors.map(d => el("td", uninf.includes(d)
                ? {text: "uninf.", title: d + " accepts too few benign fixes: its rejections here are no detections"}
                : {text: r[d] === undefined || r[d] === null ? "–" : (100 * r[d]).toFixed(1),
                   title: ci(r[d + "_ci95"])})));
  });
  t.replaceChildren(head, ...rows);
}

function renderTabs(st) {
  const box = document.getElementById("tabs");
  box.replaceChildren(...st.scenarios.map(sc => {
    const b = el("button", {class: sc.name === selected ? "selected" : "", text: sc.name});
    b.addEventListener("click", () => select(sc.name));
    return b;
  }));
}

function select(name) {
  selected = name;
  if (lastState) render(lastState);
}

// the map's view: fitted to the BSs and the trajectory, then zoomed (wheel) and panned (drag)
// by the user; a double click fits it again
const view = {zoom: 1, dx: 0, dy: 0};

function mapTransform(w, h) {
  let xs = [], ys = [];
  for (const p of [...(scene.bs || []), ...(scene.ue || [])]) { xs.push(p[0]); ys.push(p[1]); }
  if (!xs.length) return null;
  const pad = 40;
  const x0 = Math.min(...xs) - pad, x1 = Math.max(...xs) + pad;
  const y0 = Math.min(...ys) - pad, y1 = Math.max(...ys) + pad;
  const k = view.zoom * Math.min(w / (x1 - x0), h / (y1 - y0));
  const cx = (x0 + x1) / 2, cy = (y0 + y1) / 2;
  return {k, X: x => w / 2 + view.dx + k * (x - cx), Y: y => h / 2 + view.dy - k * (y - cy)};
}

function setupMapControls() {
  const c = document.getElementById("map");
  c.addEventListener("wheel", e => {
    e.preventDefault();
    const f = Math.exp(-e.deltaY * 0.0015);
    const r = c.getBoundingClientRect();
    const mx = e.clientX - r.left - r.width / 2, my = e.clientY - r.top - r.height / 2;
    view.dx = mx - (mx - view.dx) * f; view.dy = my - (my - view.dy) * f;   // zoom about the cursor
    view.zoom *= f;
    drawMap();
  }, {passive: false});
  let drag = null;
  c.addEventListener("mousedown", e => { drag = {x: e.clientX, y: e.clientY}; });
  window.addEventListener("mouseup", () => { drag = null; });
  window.addEventListener("mousemove", e => {
    if (!drag) return;
    view.dx += e.clientX - drag.x; view.dy += e.clientY - drag.y;
    drag = {x: e.clientX, y: e.clientY};
    drawMap();
  });
  c.addEventListener("dblclick", () => { view.zoom = 1; view.dx = 0; view.dy = 0; drawMap(); });
}

function drawMap() {
  const canvas = document.getElementById("map");
  const {ctx, w, h} = fitCanvas(canvas);
  ctx.clearRect(0, 0, w, h);
  canvas.dataset.drawn = "0";
  if (!scene || !scene.ready) {
    // no run in the folder (the editor before its first run): nothing to build, nothing to wait on
    const noRun = scene && scene.run === false;
    canvas.dataset.state = noRun ? "no-run" : (scene && scene.error ? "error" : "building");
    ctx.fillStyle = "#667085"; ctx.font = "14px system-ui";
    ctx.fillText(noRun ? "no run in this folder yet: the map appears when a run starts"
                 : scene && scene.error ? "map not available: " + scene.error : "building the map…", 12, 24);
    if (noRun) ctx.fillText("(the config editor, linked above, starts one)", 12, 44);
    return;
  }
  canvas.dataset.state = "drawn";
  const T = mapTransform(w, h);
  if (!T) return;
  const {X, Y, k} = T;
  const rects = (list, colour) => {
    ctx.fillStyle = colour;
    for (const f of list || []) ctx.fillRect(X(f[0]), Y(f[3]), k * (f[2] - f[0]), k * (f[3] - f[1]));
  };
  rects(scene.context, "#e3e6ea");
  rects(scene.buildings, "#9aa3ad");
  if (scene.triangles) {
    ctx.fillStyle = "rgba(120,128,140,0.45)";
    for (const t of scene.triangles) {
      ctx.beginPath(); ctx.moveTo(X(t[0]), Y(t[1])); ctx.lineTo(X(t[2]), Y(t[3])); ctx.lineTo(X(t[4]), Y(t[5]));
      ctx.closePath(); ctx.fill();
    }
  }
  // the whole true path faint, the part done so far strong
  const ue = scene.ue || [];
  const path = (pts, n, style, width) => {
    if (n < 2) return;
    ctx.strokeStyle = style; ctx.lineWidth = width; ctx.beginPath();
    ctx.moveTo(X(pts[0][0]), Y(pts[0][1]));
    for (let i = 1; i < n; i++) ctx.lineTo(X(pts[i][0]), Y(pts[i][1]));
    ctx.stroke();
  };
  path(ue, ue.length, "rgba(42,98,201,0.25)", 2);
  const p = selected && points[selected] ? points[selected].cols : emptyCols();
  const n = p.index.length;
  const cur = n ? p.index[n - 1] : -1;
  path(ue, Math.min(cur + 1, ue.length), "#2a62c9", 2.5);
  // adversary: its path faint, its position now a marker (it transmits in the attack window)
  const adv = scene.adversary || [];
  ctx.fillStyle = "rgba(142,68,173,0.5)";
  for (let i = 0; i < adv.length; i += 2) { ctx.beginPath(); ctx.arc(X(adv[i][0]), Y(adv[i][1]), 2, 0, 7); ctx.fill(); }
  // estimates coloured by outcome; no fix: a cross at the true position
  for (let i = 0; i < n; i++) {
    const o = p.outcome[i];
    ctx.fillStyle = ctx.strokeStyle = OUTCOME_COLOURS[o];
    if (p.x_est[i] === null) {
      const x = X(p.x_true[i]), y = Y(p.y_true[i]);
      ctx.lineWidth = 1.5; ctx.beginPath();
      ctx.moveTo(x - 3, y - 3); ctx.lineTo(x + 3, y + 3); ctx.moveTo(x - 3, y + 3); ctx.lineTo(x + 3, y - 3); ctx.stroke();
    } else {
      ctx.beginPath(); ctx.arc(X(p.x_est[i]), Y(p.y_est[i]), 3, 0, 7); ctx.fill();
    }
  }
  // the current point: UE, its estimate and the adversary
  if (n) {
    const i = n - 1, x = X(p.x_true[i]), y = Y(p.y_true[i]);
    if (p.x_est[i] !== null) {
      ctx.strokeStyle = "#1d2330"; ctx.lineWidth = 1; ctx.setLineDash([4, 3]);
      ctx.beginPath(); ctx.moveTo(x, y); ctx.lineTo(X(p.x_est[i]), Y(p.y_est[i])); ctx.stroke();
      ctx.setLineDash([]);
    }
    ctx.fillStyle = "#2a62c9"; ctx.strokeStyle = "#fff"; ctx.lineWidth = 2;
    ctx.beginPath(); ctx.arc(x, y, 6, 0, 7); ctx.fill(); ctx.stroke();
    if (cur < adv.length) {
      ctx.fillStyle = p.attack[i] ? "#8e44ad" : "rgba(142,68,173,0.5)";
      ctx.beginPath(); ctx.arc(X(adv[cur][0]), Y(adv[cur][1]), 5, 0, 7); ctx.fill(); ctx.stroke();
    }
  }
  // BSs: once a run that chose among candidate sites has chosen (st.serving, one flag per BS),
  // the serving ones filled and labelled, the candidates no point chose hollow and gray (as the
  // run's maps draw them); else every BS alike
  ctx.font = "12px system-ui";
  const serving = servingMask();
  (scene.bs || []).forEach((b, j) => {
    const x = X(b[0]), y = Y(b[1]);
    ctx.beginPath(); ctx.moveTo(x, y - 8); ctx.lineTo(x + 7, y + 5); ctx.lineTo(x - 7, y + 5); ctx.closePath();
    if (serving && !serving[j]) {
      ctx.strokeStyle = "#595959"; ctx.lineWidth = 1.5; ctx.stroke();
      return;
    }
    ctx.fillStyle = "#c62828"; ctx.strokeStyle = "#1d2330"; ctx.lineWidth = 1;
    ctx.fill(); ctx.stroke();
    ctx.fillStyle = "#1d2330"; ctx.fillText("BS" + j, x + 8, y - 6);
  });
  renderBsLegend(serving);
  // scale bar
  const len = [10, 20, 50, 100, 200, 500, 1000].find(m => m * k > 60) || 1000;
  ctx.strokeStyle = "#1d2330"; ctx.lineWidth = 2;
  ctx.beginPath(); ctx.moveTo(12, h - 14); ctx.lineTo(12 + len * k, h - 14); ctx.stroke();
  ctx.fillStyle = "#1d2330"; ctx.fillText(len + " m", 14, h - 20);
  canvas.dataset.drawn = String(n);
}

// the serving flags of the last poll when they are the map's BSs' (null: every BS alike)
function servingMask() {
  const m = lastState && lastState.serving;
  return Array.isArray(m) && scene && scene.bs && m.length === scene.bs.length ? m : null;
}

// the map's legend of the BSs: with serving flags their counts and the unused candidates' key
function renderBsLegend(serving) {
  const used = serving ? serving.filter(Boolean).length : 0;
  document.getElementById("legend-bs").textContent = serving ? "serving BSs (" + used + ")" : "BS";
  const unused = document.getElementById("legend-unused");
  unused.hidden = !serving || used === serving.length;
  if (serving) document.getElementById("legend-unused-count").textContent = String(serving.length - used);
}

function renderDecisions(st) {
  const box = document.getElementById("decisions");
  if (box.children.length !== st.detectors.length) {
    box.replaceChildren(...st.detectors.map(d =>
      el("div", {class: "decision-row", "data-detector": d}, el("span", {text: d}), el("canvas", {}))));
  }
  const p = selected && points[selected] ? points[selected].cols : emptyCols();
  const total = st.num_points || Math.max(p.index.length, 1);
  const attack = selected !== "none" && scene && scene.attack ? scene.attack : null;
  document.getElementById("decisions-scenario").textContent = selected ? "— " + selected : "";
  document.getElementById("axis-end").textContent = "point " + (total - 1);
  box.dataset.points = String(p.index.length);
  for (const row of box.children) {
    const d = row.dataset.detector;
    const {ctx, w, h} = fitCanvas(row.querySelector("canvas"));
    ctx.clearRect(0, 0, w, h);
    const dx = w / total;
    if (attack) {
      ctx.fillStyle = "rgba(214,69,69,0.22)";
      ctx.fillRect(attack[0] * dx, 0, (attack[1] - attack[0]) * dx, h);
      ctx.strokeStyle = "rgba(214,69,69,0.7)"; ctx.lineWidth = 1;
      ctx.strokeRect(attack[0] * dx + 0.5, 0.5, (attack[1] - attack[0]) * dx - 1, h - 1);
    }
    const v = p.verdicts[d] || [];
    for (let i = 0; i < v.length; i++) {
      ctx.fillStyle = v[i] ? "#2e9d55" : "#d64545";
      ctx.fillRect(p.index[i] * dx, 5, Math.max(dx - (dx > 3 ? 1 : 0), 1), h - 10);
    }
    row.dataset.points = String(v.length);
  }
}

window.addEventListener("resize", () => { if (lastState) render(lastState); });
setupMapControls();
poll();
