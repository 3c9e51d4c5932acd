"use strict";
// grainplug review: the diagram (canvas), the frame under a click, the tracks and the corrections.
const $ = (id) => document.getElementById(id);
let run = null, state = null, img = null, view = null, frame = null, selected = null, playing = null;
let npStart = null;
const api = (path) => `api/run/${encodeURIComponent(run)}/${path}`;
const fmt = (x, d) => (x === null || x === undefined) ? "—" : Number(x).toFixed(d);

async function getJSON(url, body) {
  const opts = body === undefined ? {} : {method: "POST", headers: {"Content-Type": "application/json"},
                                          body: JSON.stringify(body)};
  const r = await fetch(url, opts);
  const data = await r.json();
  if (!r.ok) throw new Error(data.error || r.statusText);
  return data;
}

async function post(path, body) {
  try { $("error").textContent = ""; show(await getJSON(api(path), body || {})); }
  catch (e) { $("error").textContent = e.message; }
}

async function load(name) {
  run = name;
  state = await getJSON(api("state"));
  view = [state.diagram.t0, state.diagram.t1];
  img = new Image();
  img.onload = draw;
  img.src = api("diagram.png") + "?" + Date.now();
  show(state);
}

function show(s) {
  state = s;
  const m = s.measures;
  $("measures").innerHTML = `regime <b id="regime">${m.regime}</b> · celerity <b id="celerity" data-value="${m.celerity_m_s}">${fmt(m.celerity_m_s, 4)}</b> m/s`
    + ` · plug <b>${fmt(m.plug_length_mm, 2)}</b> mm · bubble <b>${fmt(m.bubble_length_mm, 2)}</b> mm`
    + ` · ${m.n_plugs} plugs`;
  const tb = $("tracks").querySelector("tbody");
  tb.innerHTML = "";
  for (const t of s.tracks) {
    const tr = document.createElement("tr");
    tr.dataset.track = t.plug_id;
    if (t.excluded) tr.classList.add("excluded");
    if (t.plug_id === selected) tr.classList.add("selected");
    tr.innerHTML = `<td>${t.plug_id}</td><td>${fmt(t.first_time_s, 3)}</td><td>${fmt(t.last_time_s, 3)}</td>`
      + `<td>${t.n_frames ?? "—"}</td><td>${fmt(t.celerity_m_s, 4)}</td><td>${fmt(t.median_length_mm, 2)}</td>`
      + `<td><button class="toggle">${t.excluded ? "restore" : "exclude"}</button></td>`;
    tr.querySelector(".toggle").onclick = (ev) => {
      ev.stopPropagation();
      post("edit", {action: t.excluded ? "restore" : "exclude", track: t.plug_id});
    };
    tr.onclick = () => { selected = t.plug_id; show(state); };
    tb.appendChild(tr);
  }
  $("corrections").innerHTML = s.corrections.map((c) => `<li>${c.text} <small>${c.at}</small></li>`).join("")
    || "<li>none</li>";
  $("warnings").innerHTML = s.warnings.map((w) => `<li>${w}</li>`).join("") + (s.statement ? `<li>${s.statement}</li>` : "");
  $("movie-status").textContent = s.movie === "ok" ? "" : s.movie;
  draw();
}

function tToX(t, w) { return (t - view[0]) / (view[1] - view[0]) * w; }
function xToT(x, w) { return view[0] + x / w * (view[1] - view[0]); }

function draw() {
  const c = $("diagram"), ctx = c.getContext("2d");
  const w = c.width, h = c.height, d = state.diagram;
  ctx.clearRect(0, 0, w, h);
  if (img && img.complete) {
    const n = img.width, span = d.t1 - d.t0 || 1;
    const sx = (view[0] - d.t0) / span * n, sw = (view[1] - view[0]) / span * n;
    ctx.imageSmoothingEnabled = false;
    ctx.drawImage(img, sx, 0, sw, img.height, 0, 0, w, h);
  }
  const zToY = (z) => (z - d.z0) / (d.z1 - d.z0 || 1) * h;
  for (const [tid, e] of Object.entries(state.edges)) {
    for (const [key, colour] of [["top", "#d55e00"], ["bottom", "#0072b2"]]) {  // grainplug.plotting.palette
      ctx.beginPath();
      ctx.strokeStyle = colour;
      ctx.lineWidth = Number(tid) === selected ? 3 : 1.2;
      let pen = false;
      for (let i = 0; i < e.t.length; i++) {
        const z = e[key][i];
        if (z === null) { pen = false; continue; }
        const x = tToX(e.t[i], w), y = zToY(z);
        if (pen) ctx.lineTo(x, y); else ctx.moveTo(x, y);
        pen = true;
      }
      ctx.stroke();
    }
  }
  // what the corrections cut away: outside the time window, and the spans marked as not plugs
  ctx.fillStyle = "rgba(255, 255, 255, 0.6)";
  const [w0, w1] = state.window || [null, null];
  if (w0 !== null) ctx.fillRect(0, 0, Math.max(0, tToX(w0, w)), h);
  if (w1 !== null) { const x = Math.min(w, tToX(w1, w)); ctx.fillRect(x, 0, w - x, h); }
  ctx.fillStyle = "rgba(86, 180, 233, 0.35)";  // palette.BUBBLE
  for (const [a, b] of state.no_plugs || []) ctx.fillRect(tToX(a, w), 0, tToX(b, w) - tToX(a, w), h);
  labelTracks(ctx, w, zToY);
  axes(ctx, w, h, d);
  if (frame !== null) {
    const t = d.t0 + frame / Math.max(d.n_frames - 1, 1) * (d.t1 - d.t0);
    ctx.strokeStyle = "#ffbf00"; ctx.lineWidth = 2;
    ctx.beginPath(); ctx.moveTo(tToX(t, w), 0); ctx.lineTo(tToX(t, w), h); ctx.stroke();
  }
}

function niceStep(span, n) {  // 1, 2 or 5 x 10^k, about span / n
  const raw = span / n, p = Math.pow(10, Math.floor(Math.log10(raw)));
  return [1, 2, 5, 10].map((m) => m * p).find((s) => s >= raw);
}

function tag(ctx, text, x, y, align, base) {  // text on a white box, readable over the grey levels
  ctx.font = "13px system-ui, sans-serif"; ctx.textAlign = align; ctx.textBaseline = base;
  const m = ctx.measureText(text), bw = m.width + 6, bh = 16;
  const bx = align === "left" ? x - 3 : align === "right" ? x - bw + 3 : x - bw / 2;
  const by = base === "top" ? y - 1 : base === "bottom" ? y - bh + 1 : y - bh / 2;
  ctx.fillStyle = "rgba(255, 255, 255, 0.85)"; ctx.fillRect(bx, by, bw, bh);
  ctx.fillStyle = "#222"; ctx.fillText(text, x, y);
}

function axes(ctx, w, h, d) {  // time along the bottom, position along the flow on the left
  const dt = niceStep(view[1] - view[0], 6), digits = Math.max(0, -Math.floor(Math.log10(dt)));
  ctx.strokeStyle = "#222"; ctx.lineWidth = 1;
  for (let t = Math.ceil(view[0] / dt) * dt; t <= view[1]; t += dt) {
    const x = tToX(t, w);
    ctx.beginPath(); ctx.moveTo(x, h); ctx.lineTo(x, h - 6); ctx.stroke();
    if (x > 30 && x < w - 30) tag(ctx, `${t.toFixed(digits)} s`, x, h - 7, "center", "bottom");
  }
  const dz = niceStep(Math.abs(d.z1 - d.z0), 5);
  for (let z = Math.ceil(Math.min(d.z0, d.z1) / dz) * dz; z <= Math.max(d.z0, d.z1); z += dz) {
    const y = (z - d.z0) / (d.z1 - d.z0 || 1) * h;
    ctx.beginPath(); ctx.moveTo(0, y); ctx.lineTo(6, y); ctx.stroke();
    if (y > 12 && y < h - 28) tag(ctx, `${Math.round(z)} mm`, 8, y, "left", "middle");
  }
}

function labelTracks(ctx, w, zToY) {  // each track's number at the middle of what is in view
  for (const [tid, e] of Object.entries(state.edges)) {
    const inView = e.t.map((t, i) => [t, i]).filter(([t, i]) => t >= view[0] && t <= view[1] && e.top[i] !== null);
    if (!inView.length) continue;
    const [t, i] = inView[Math.floor(inView.length / 2)];
    const y = zToY(e.top[i]) - 4;
    tag(ctx, tid, tToX(t, w), Math.max(18, y), "center", "bottom");
  }
}

function frameAt(t) {
  const d = state.diagram;
  return Math.max(0, Math.min(d.n_frames - 1, Math.round((t - d.t0) / (d.t1 - d.t0 || 1) * (d.n_frames - 1))));
}
function timeOf(k) { const d = state.diagram; return d.t0 + k / Math.max(d.n_frames - 1, 1) * (d.t1 - d.t0); }

function showFrame(k) {
  frame = k;
  $("frame-label").textContent = `frame ${k}, t = ${timeOf(k).toFixed(4)} s`;
  if (state.movie === "ok") $("frame").src = api(`frame/${k}.png`);
  draw();
}

function canvasX(ev) {
  const c = $("diagram"), r = c.getBoundingClientRect();
  return (ev.clientX - r.left) / r.width * c.width;
}

function setup() {
  const c = $("diagram");
  let drag = null, moved = false;
  c.addEventListener("mousedown", (ev) => { drag = {x: canvasX(ev), view: view.slice()}; moved = false; });
  window.addEventListener("mouseup", (ev) => {
    if (drag && !moved && ev.target === c) showFrame(frameAt(xToT(canvasX(ev), c.width)));
    drag = null;
  });
  c.addEventListener("mousemove", (ev) => {
    if (!drag) return;
    const dx = canvasX(ev) - drag.x;
    if (Math.abs(dx) > 3) moved = true;
    const dt = dx / c.width * (drag.view[1] - drag.view[0]);
    view = [drag.view[0] - dt, drag.view[1] - dt];
    draw();
  });
  c.addEventListener("wheel", (ev) => {
    ev.preventDefault();
    const t = xToT(canvasX(ev), c.width), f = ev.deltaY > 0 ? 1.25 : 0.8;
    view = [t - (t - view[0]) * f, t + (view[1] - t) * f];
    draw();
  }, {passive: false});
  c.addEventListener("dblclick", () => { view = [state.diagram.t0, state.diagram.t1]; draw(); });
  $("prev").onclick = () => frame !== null && showFrame(Math.max(0, frame - 1));
  $("next").onclick = () => frame !== null && showFrame(Math.min(state.diagram.n_frames - 1, frame + 1));
  $("play").onclick = () => {
    if (playing) { clearInterval(playing); playing = null; $("play").textContent = "play"; return; }
    $("play").textContent = "pause";
    playing = setInterval(() => {
      if (frame === null || frame >= state.diagram.n_frames - 1) { $("play").click(); return; }
      showFrame(frame + 1);
    }, 150);
  };
  const here = () => frame === null ? null : timeOf(frame);
  $("undo").onclick = () => post("undo");
  $("save").onclick = () => post("save");
  $("win-start").onclick = () => here() !== null && post("edit", {action: "window", start_s: here()});
  $("win-end").onclick = () => here() !== null && post("edit", {action: "window", end_s: here()});
  $("np-start").onclick = () => { npStart = here(); };
  $("np-end").onclick = () => npStart !== null && here() !== null &&
    post("edit", {action: "no_plugs", start_s: Math.min(npStart, here()), end_s: Math.max(npStart, here())});
  $("np-clear").onclick = () => post("edit", {action: "clear_no_plugs"});
  $("merge").onclick = () => post("edit", {action: "merge", track: Number($("merge-a").value),
                                           other: Number($("merge-b").value)});
  $("split").onclick = () => selected !== null && frame !== null &&
    post("edit", {action: "split", track: selected, frame: frame});
  $("run").onchange = () => load($("run").value);
}

(async () => {
  setup();
  const runs = (await getJSON("api/runs")).runs;
  $("run").innerHTML = runs.map((r) => `<option>${r}</option>`).join("");
  if (runs.length < 2) $("run").disabled = true;
  await load(runs[0]);
})();
