// The config editor: one input per leaf field of the schema (/api/form), values from
// /api/config; Validate / Save / Save and run post the whole config to the server, which
// answers with the package's own one-line error. The config file and the run's folder are the
// ones the editor was started on (shown, not editable: the server refuses any other).
"use strict";

let fields = [];
const inputs = {};     // path -> input element

function fieldId(path) { return "f-" + path.replace(/\./g, "-"); }

function get(obj, path) {
  for (const k of path.split(".")) { if (obj === null || typeof obj !== "object") return undefined; obj = obj[k]; }
  return obj;
}

function setPath(obj, path, value) {
  const ks = path.split(".");
  for (const k of ks.slice(0, -1)) obj = obj[k] = obj[k] || {};
  obj[ks[ks.length - 1]] = value;
}

function makeInput(f) {
  let inp;
  if (f.kind === "boolean") {
    inp = el("input", {type: "checkbox"});
  } else if (f.kind === "enum" || f.kind === "choices") {
    inp = el("select", {});
    for (const c of f.choices) inp.append(el("option", {value: JSON.stringify(c), text: String(c)}));
    // a list of registered names: several may be chosen
    if (f.kind === "choices") { inp.multiple = true; inp.size = Math.min(f.choices.length, 6); }
  } else if (f.kind === "integer" || f.kind === "number") {
    inp = el("input", {type: "number", step: f.kind === "integer" ? "1" : "any"});
    if (f.minimum !== null) inp.min = f.minimum;
    if (f.maximum !== null) inp.max = f.maximum;
  } else {
    inp = el("input", {type: "text"});
  }
  inp.id = fieldId(f.path);
  inp.dataset.path = f.path;
  inp.dataset.kind = f.kind;
  return inp;
}

function setValue(f, v) {
  const inp = inputs[f.path];
  if (f.kind === "boolean") inp.checked = !!v;
  else if (f.kind === "enum") inp.value = JSON.stringify(v);
  else if (f.kind === "choices") {
    const want = (Array.isArray(v) ? v : []).map(c => JSON.stringify(c));
    // a name the config gives that no plug-in here registered stays chosen, for the check to name
    for (const c of want) {
      if (![...inp.options].some(o => o.value === c)) inp.append(el("option", {value: c, text: JSON.parse(c)}));
    }
    for (const o of inp.options) o.selected = want.includes(o.value);
  }
  else if (f.kind === "json") inp.value = v === null || v === undefined ? "" : JSON.stringify(v);
  else inp.value = v === null || v === undefined ? "" : String(v);
  markChanged(f);
}

// the JSON value of an input; text the kind cannot parse goes as it is, for the server to reject
function readValue(f) {
  const inp = inputs[f.path];
  if (f.kind === "boolean") return inp.checked;
  if (f.kind === "enum") return JSON.parse(inp.value);
  if (f.kind === "choices") return Array.from(inp.selectedOptions, o => JSON.parse(o.value));
  const t = inp.value.trim();
  if (f.kind === "integer" || f.kind === "number") {
    if (t === "") return f.nullable ? null : t;
    const x = Number(t);
    return isFinite(x) ? x : t;
  }
  if (f.kind === "json") {
    if (t === "") return null;
    try { return JSON.parse(t); } catch (e) { return t; }
  }
  return inp.value;
}

function markChanged(f) {
  const row = inputs[f.path].closest(".field");
  let v;
  try { v = readValue(f); } catch (e) { v = undefined; }
  row.classList.toggle("changed", JSON.stringify(v) !== JSON.stringify(f.default));
}

function configFromForm() {
  const cfg = {};
  for (const f of fields) setPath(cfg, f.path, readValue(f));
  return cfg;
}

function show(res, okText) {
  const m = document.getElementById("message");
  document.querySelectorAll(".field.bad").forEach(e => e.classList.remove("bad"));
  document.querySelectorAll(".field-error").forEach(e => e.remove());
  if (res.ok) { m.textContent = okText; m.className = "message ok"; return; }
  m.textContent = res.error; m.className = "message error";
  if (res.field) {
    // the error names the dotted field, maybe with a list index: trajectory.num_points, nr.prs_ids[1]
    const path = res.field.replace(/\[\d+\]$/, "");
    const inp = inputs[path];
    if (inp) {
      const row = inp.closest(".field");
      row.classList.add("bad");
      row.append(el("div", {class: "field-error", text: res.error}));
      inp.scrollIntoView({block: "center"});
    }
  }
}

function body() {
  return {config: configFromForm(), path: document.getElementById("save-path").value || null,
          out: document.getElementById("out-dir").value || null};
}

async function build() {
  document.getElementById("form").addEventListener("submit", e => e.preventDefault());
  const form = await getJSON("/api/form");
  fields = form.fields;
  const root = document.getElementById("form");
  const sets = {};
  for (const f of fields) {
    const sec = f.section || "(top level)";
    if (!sets[sec]) { sets[sec] = el("fieldset", {"data-section": sec}, el("legend", {text: sec})); root.append(sets[sec]); }
    const inp = makeInput(f);
    inputs[f.path] = inp;
    inp.addEventListener("input", () => markChanged(f));
    inp.addEventListener("change", () => markChanged(f));
    const name = f.path.slice(f.section ? f.section.length + 1 : 0);
    const info = el("div", {class: "info"},
      el("b", {text: "range "}), f.range + "  ", el("b", {text: " default "}),
      JSON.stringify(f.default) + " — " + f.doc);
    sets[sec].append(el("div", {class: "field", "data-path": f.path},
      el("label", {for: inp.id, text: name}), inp, info));
  }
  const cur = await getJSON("/api/config");
  if (cur.ok === false) show(cur, "");
  else {
    for (const f of fields) setValue(f, get(cur.config, f.path));
    document.getElementById("save-path").value = cur.path;
    document.getElementById("out-dir").value = cur.out;
    if (!cur.editable) {   // veriloc-rt view: the checks only
      for (const id of ["save", "run"]) document.getElementById(id).disabled = true;
      show({ok: true}, "this server only views a run folder: `veriloc-rt edit CONFIG --out DIR` saves and runs");
    }
  }
  document.getElementById("validate").addEventListener("click", async () =>
    show(await postJSON("/api/validate", body()), "valid"));
  document.getElementById("save").addEventListener("click", async () => {
    const r = await postJSON("/api/save", body());
    show(r, "saved " + r.path);
  });
  document.getElementById("run").addEventListener("click", async () => {
    const r = await postJSON("/api/run", body());
    show(r, "started the run into " + r.out);
    if (r.ok) window.location.href = withToken(r.view);
  });
  document.getElementById("reset").addEventListener("click", () => {
    for (const f of fields) setValue(f, f.default);
    show({ok: true}, "defaults restored (not saved)");
  });
  document.body.dataset.ready = "1";
}

build();
