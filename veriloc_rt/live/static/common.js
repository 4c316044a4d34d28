// Shared helpers of the live view and the config editor (no dependencies, no network).
"use strict";

// the session token: in the URL the command printed (?token=...); every /api/ call sends it
const TOKEN = new URLSearchParams(window.location.search).get("token") || "";

// a page of this server with the token, for links and redirects
function withToken(path) {
  return path + (path.includes("?") ? "&" : "?") + "token=" + encodeURIComponent(TOKEN);
}

class HTTPError extends Error {
  constructor(url, status) { super(url + ": HTTP " + status); this.status = status; }
}

async function getJSON(url) {
  const r = await fetch(url, {cache: "no-store", headers: {"X-Veriloc-Token": TOKEN}});
  if (!r.ok) throw new HTTPError(url, r.status);
  return r.json();
}

async function postJSON(url, body) {
  const r = await fetch(url, {
    method: "POST", cache: "no-store",
    headers: {"Content-Type": "application/json", "X-Veriloc": "1", "X-Veriloc-Token": TOKEN},
    body: JSON.stringify(body),
  });
  return r.json();
}

// links between the pages keep the token
document.addEventListener("DOMContentLoaded", () => {
  for (const a of document.querySelectorAll("a[data-page]")) a.href = withToken(a.dataset.page);
});

function el(tag, attrs, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (k === "class") e.className = v;
    else if (k === "text") e.textContent = v;
    else if (k === "style") e.style.cssText = v;   // CSSOM: allowed by the page's CSP
    else e.setAttribute(k, v);
  }
  for (const c of children) if (c !== null && c !== undefined) e.append(c);
  return e;
}

function fmtDuration(s) {
  if (s === null || s === undefined || !isFinite(s)) return "–";
  s = Math.round(s);
  const h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60), sec = s % 60;
  if (h) return h + " h " + String(m).padStart(2, "0") + " min";
  if (m) return m + " min " + String(sec).padStart(2, "0") + " s";
  return sec + " s";
}

function fmtPct(v) {
  return v === null || v === undefined ? "n/a" : v.toFixed(1) + " %";
}

// a canvas sized to its CSS box at the device's pixel ratio; returns its 2-D context in CSS px
function fitCanvas(canvas) {
  const dpr = window.devicePixelRatio || 1;
  const w = canvas.clientWidth, h = canvas.clientHeight;
  if (canvas.width !== Math.round(w * dpr) || canvas.height !== Math.round(h * dpr)) {
    canvas.width = Math.round(w * dpr);
    canvas.height = Math.round(h * dpr);
  }
  const ctx = canvas.getContext("2d");
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  return {ctx, w, h};
}
