"use strict";
// grainplug review: the diagram (canvas), the frame under a click, the tracks and the corrections.
// Whatever the server sends (run names, warnings, corrections, errors) is shown as text, never parsed as HTML:
// the page is built with createElement and textContent only.
const $ = (id) => document.getElementById(id);
// the server's token, written in the page by the server: sent with every request of this script (the images
// carry the cookie set by the first visit); the address bar drops it, so it is not left in sight or in a link
const TOKEN = document.querySelector('meta[name="grainplug-token"]').content;
if (location.search) history.replaceState(null, "", location.pathname);
let run = null, state = null, img = null, view = null, frame = null, selected = null, playing = null;
let npStart = null, busy = 0, clickZ = null, blStart = null;
// the frame shown is `frame` (its label, the cursor on the diagram, the edits' "here"); `asked` is the one whose
// image is on its way (null: none), since `askedAt` (ms): the label changes with the image, never before it
let asked = null, askedAt = 0;
//: the slow-downs offered for playing, and the one picked by default: the fewest that shows at most this many of
// the movie's frames per second (a display's rate; a slower server skips frames rather than falling behind)
const SLOWDOWNS = [1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000], DISPLAY_FPS = 25;
const api = (path) => `api/run/${encodeURIComponent(run)}/${path}`;
const fmt = (x, d) => (x === null || x === undefined) ? "—" : Number(x).toFixed(d);

async function getJSON(url, body) {
  const headers = {"X-Grainplug-Token": TOKEN};
  const opts = body === undefined ? {headers} : {method: "POST", body: JSON.stringify(body),
                                                 headers: Object.assign(headers, {"Content-Type": "application/json"})};
  const r = await fetch(url, Object.assign(opts, {credentials: "same-origin", cache: "no-store"}));
  const data = await r.json();
  if (!r.ok) {
    const err = new Error(data.error || r.statusText);
    err.state = data.state;  // a stale page's edit (409): the state as it is on disk now
    throw err;
  }
  return data;
}

// an element with its text (never HTML) and, optionally, attributes and children
function el(tag, text, attrs, ...children) {
  const e = document.createElement(tag);
  if (text !== undefined && text !== null) e.textContent = String(text);
  for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, String(v));
  e.append(...children);
  return e;
}

function say(text) { $("error").textContent = text; }
function notice(text) { $("notice").textContent = text; }

// an edit, undo or save, sent with the version of the state it was made on: the server refuses it (and
// sends the state as it is now) when corrections.json or result.npz changed on disk since
async function post(path, body) {
  busy++;
  try {
    say(""); notice(""); saveStatus("", "");  // written outputs are now behind the corrections
    show(await getJSON(api(path), Object.assign({}, body || {}, {version: state.version})));
  } catch (e) {
    if (e.state) adopt(e.state);
    say(e.message);
  } finally { busy--; }
}

function saveStatus(text, kind) { const e = $("save-status"); e.textContent = text; e.className = kind; }

// "Write outputs": says while it works, then what was written and where (or why nothing was), beside the button
async function save() {
  busy++;
  $("save").disabled = true;
  saveStatus("writing the outputs…", "");
  try {
    say(""); notice("");
    const s = await getJSON(api("save"), {version: state.version});
    show(s);
    const w = s.saved, n = w.corrections;
    saveStatus(`written at ${new Date().toLocaleTimeString()}, with ${n} correction${n === 1 ? "" : "s"}: ` +
               `${w.files.length} files in ${w.folder} (${w.files.join(", ")})`, "ok");
  } catch (e) {
    if (e.state) adopt(e.state);
    saveStatus(`not written: ${e.message}`, "failed");
    say(`Write outputs: ${e.message}`);
  } finally { busy--; $("save").disabled = false; }
}

// a state read again because the files changed on disk (by hand, another page, a batch)
function adopt(s) {
  const old = state.version;
  if (s.version.result !== old.result) {  // analysed again: another diagram, tracks numbered anew
    selected = null; npStart = null;
    const t = frame === null ? null : timeOf(frame);  // the same time, in the new analysis' frames
    view = [s.diagram.t0, s.diagram.t1];
    img = new Image();
    img.onload = draw;
    img.src = api("diagram.png") + "?" + Date.now();
    notice("result.npz changed on disk (the run analysed again, or remeasured): the page shows it as it is now");
    frame = null; asked = null;
    stop();
    show(s);
    speeds();
    if (t !== null && t >= s.diagram.t0 && t <= s.diagram.t1) showFrame(frameAt(t));
    else { $("frame").hidden = true; $("frame-label").textContent = "click the diagram"; }
    return;
  }
  if (s.version.corrections !== old.corrections) {
    notice("corrections.json changed on disk (by hand, a copy or another page): the page shows it as it is now");
  }
  show(s);
}

async function poll() {  // has a file changed under the page?
  if (!state || busy || document.hidden) return;
  try {
    const asked = run, v = await getJSON(api("version"));
    if (busy || asked !== run || asked !== state.run) return;
    if (v.result !== state.version.result || v.corrections !== state.version.corrections) {
      adopt(await getJSON(api("state")));
    }
  } catch (e) { /* the folder may be mid-swap: asked again at the next tick */ }
}

async function load(name) {
  stop();
  run = name; selected = null; npStart = null; frame = null; asked = null; clickZ = null; blStart = null;
  $("play-info").textContent = ""; saveStatus("", "");
  $("frame").hidden = true;
  $("frame-label").textContent = "click the diagram";
  state = await getJSON(api("state"));
  view = [state.diagram.t0, state.diagram.t1];
  img = new Image();
  img.onload = draw;
  img.src = api("diagram.png") + "?" + Date.now();
  show(state);
  speeds();
}

/** " (95% CI lo to hi)" with ``digits`` decimals, or nothing without an interval. */
function ci(pair, digits) {
  return pair && pair[0] !== null && pair[1] !== null ? ` (95% CI ${fmt(pair[0], digits)} to ${fmt(pair[1], digits)})`
    : "";
}

function show(s) {
  state = s;
  const m = s.measures;
  const parts = ["regime ", el("b", m.regime, {id: "regime"}),
    " · celerity ", el("b", fmt(m.celerity_m_s, 4), {id: "celerity", "data-value": m.celerity_m_s}), " m/s",
    " · plug ", el("b", fmt(m.plug_length_mm, 2)), " mm · bubble ", el("b", fmt(m.bubble_length_mm, 2)), " mm",
    ` · ${m.n_plugs} plugs`];
  if ((m.oscillation_frequency_hz ?? null) !== null || m.regime === "oscillating") {
    parts.push(" · oscillation ", el("b", fmt(m.oscillation_frequency_hz, 2),
                                     {id: "frequency", "data-value": m.oscillation_frequency_hz}),
               " Hz", ci(m.oscillation_frequency_ci95_hz, 3),
               ", amplitude ", el("b", fmt(m.oscillation_amplitude_mm, 2), {id: "amplitude"}), " mm",
               ci(m.oscillation_amplitude_ci95_mm, 2), " (half peak-to-peak)");
    if (m.oscillation_kind) {
      parts.push(", ", el("b", m.oscillation_kind, {id: "oscillation-kind"}),
                 ` (still ${fmt(100 * m.oscillation_stick_fraction, 0)} % of the period)`);
    }
  }
  $("measures").replaceChildren(...parts);
  const tb = $("tracks").querySelector("tbody");
  tb.replaceChildren();
  for (const t of s.tracks) {
    const tr = document.createElement("tr");
    tr.dataset.track = t.plug_id;
    if (t.excluded) tr.classList.add("excluded");
    if (t.plug_id === selected) tr.classList.add("selected");
    const toggle = el("button", t.excluded ? "restore" : "exclude", {class: "toggle"});
    tr.append(el("td", t.plug_id), el("td", fmt(t.first_time_s, 3)), el("td", fmt(t.last_time_s, 3)),
              el("td", t.n_frames ?? "—"), el("td", fmt(t.celerity_m_s, 4)), el("td", fmt(t.median_length_mm, 2)),
              el("td", null, {}, toggle));
    toggle.onclick = (ev) => {
      ev.stopPropagation();
      post("edit", {action: t.excluded ? "restore" : "exclude", track: t.plug_id});
    };
    tr.onclick = () => { selected = t.plug_id; show(state); };
    tb.appendChild(tr);
  }
  const corrections = s.corrections.map((c) => el("li", `${c.text} `, {}, el("small", c.at)));
  $("corrections").replaceChildren(...(corrections.length ? corrections : [el("li", "none")]));
  $("warnings").replaceChildren(...s.warnings.map((w) => el("li", w)), ...(s.statement ? [el("li", s.statement)] : []));
  $("movie-status").textContent = s.movie === "ok" ? "" : s.movie;
  const blind = (s.blind || []).map((b) => {
    const how = {"mask_mm": "given", "still contents": "found: nothing changes there", "review": "added here"};
    const text = `${fmt(b.from_mm, 1)}–${fmt(b.to_mm, 1)} mm (${how[b.found_by] || b.found_by})` +
      (b.treated === "seen through" ? `: seen through it, ${Math.round(100 * b.contrast_left)} % of the contrast ` +
       "left and divided out" : "") + (b.kept ? "" : ", removed");
    if (b.treated === "seen through") return el("li", text);  // measured through: nothing to remove
    const button = el("button", b.kept ? "remove" : "restore", {class: "toggle"});
    button.onclick = () => post("edit", {action: b.kept ? "unblind" : "blind", from_mm: b.from_mm, to_mm: b.to_mm});
    const li = el("li", `${text} `, {}, button);
    if (!b.kept) li.classList.add("excluded");
    return li;
  });
  $("blind").replaceChildren(...(blind.length ? blind : [el("li", "none")]));
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
  for (const b of (state.blind || []).filter((x) => x.treated !== "seen through")) {  // blind: bands over the record
    const y0 = zToY(b.from_mm), y1 = zToY(b.to_mm);
    const top = Math.min(y0, y1), height = Math.max(Math.abs(y1 - y0), 2);
    if (b.kept) {  // palette's orange, seen over the plugs' black and the bubbles' white alike
      ctx.fillStyle = "rgba(230, 159, 0, 0.45)"; ctx.fillRect(0, top, w, height);
    }
    ctx.strokeStyle = "#e69f00"; ctx.lineWidth = 2; ctx.setLineDash(b.kept ? [] : [6, 4]);
    ctx.strokeRect(0, top, w, height); ctx.setLineDash([]);
  }
  if (clickZ !== null) {  // the position picked along the tube
    ctx.strokeStyle = "#ffbf00"; ctx.lineWidth = 1; ctx.setLineDash([4, 4]);
    ctx.beginPath(); ctx.moveTo(0, zToY(clickZ)); ctx.lineTo(w, zToY(clickZ)); ctx.stroke(); ctx.setLineDash([]);
  }
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
  const h = ctx.canvas.height;
  for (const [tid, e] of Object.entries(state.edges)) {
    // over its upper edge; under its lower edge where the view cuts the upper one all along
    for (const [key, dy, base] of [["top", -4, "bottom"], ["bottom", 4, "top"]]) {
      const inView = e.t.map((t, i) => [t, i]).filter(([t, i]) => t >= view[0] && t <= view[1] && e[key][i] !== null);
      if (!inView.length) continue;
      const [t, i] = inView[Math.floor(inView.length / 2)];
      const y = zToY(e[key][i]) + dy;
      tag(ctx, tid, tToX(t, w), Math.min(Math.max(18, y), h - 40), "center", base);
      break;
    }
  }
}

function frameAt(t) {
  const d = state.diagram;
  return Math.max(0, Math.min(d.n_frames - 1, Math.round((t - d.t0) / (d.t1 - d.t0 || 1) * (d.n_frames - 1))));
}
function timeOf(k) { const d = state.diagram; return d.t0 + k / Math.max(d.n_frames - 1, 1) * (d.t1 - d.t0); }

// ask for frame k: its image is fetched, and the label, the cursor and "here" move to it when it is on screen
function showFrame(k) {
  if (state.movie !== "ok" || (k === frame && asked === null && !$("frame").hidden)) return setFrame(k);
  asked = k; askedAt = performance.now();
  $("frame").src = api(`frame/${k}.png`);
}

// frame k is the one on screen (its image arrived, or there is no movie to show)
function setFrame(k) {
  frame = k;
  if (playing) playing.shown++;
  $("frame-label").textContent = `frame ${k}, t = ${timeOf(k).toFixed(4)} s` +
    (clickZ === null ? "" : `, z = ${clickZ.toFixed(1)} mm`);
  draw();
}

function arrived(ok) {  // the image asked for is on screen (or could not be drawn: hidden, the label still moves)
  if (asked === null) return;
  const k = asked;
  asked = null;
  $("frame").hidden = !ok;
  setFrame(k);
}

// -- playing: the movie's own time slowed by the factor picked (stated in the list), whatever the server's pace:
// one image on its way at a time, and each one the frame due when it is asked for (frames skipped, never late)
function movieRate() { const d = state.diagram; return (d.n_frames - 1) / ((d.t1 - d.t0) || 1); }
function perSecond(x) { return x >= 10 ? x.toFixed(0) : x.toPrecision(2); }

function speeds() {  // the list of slow-downs for this run's frame rate
  const r = movieRate(), was = Number($("speed").value) || null;
  const pick = SLOWDOWNS.find((f) => r / f <= DISPLAY_FPS) ?? SLOWDOWNS[SLOWDOWNS.length - 1];
  const offered = SLOWDOWNS.filter((f) => r / f >= 0.5 || f === pick);
  $("speed").replaceChildren(...offered.map((f) => {
    const o = new Option(f === 1 ? `real time: ${perSecond(r)} frames/s` : `slowed ${f}×: ${perSecond(r / f)} frames/s`,
                         String(f));
    o.selected = f === (offered.includes(was) ? was : pick);
    return o;
  }));
}

function stop() {
  if (!playing) return;
  clearInterval(playing.timer);
  playing = null;
  $("play").textContent = "play";
  $("play-info").textContent = $("play-info").textContent.replace(/^playing/, "stopped; played");
}

function play() {
  const n = state.diagram.n_frames, slow = Number($("speed").value), rate = movieRate() / slow;
  const first = frame === null || frame >= n - 1 ? 0 : frame, t0 = performance.now();
  const what = `playing ${slow === 1 ? "in real time" : `slowed ${slow}×`}: ${perSecond(rate)} of the movie's frames a second`;
  playing = {timer: null, shown: 0};
  $("play").textContent = "pause";
  $("play-info").textContent = what;
  const tick = () => {
    if (!playing) return;
    const now = performance.now(), s = (now - t0) / 1000;
    const k = Math.min(n - 1, first + Math.floor(s * rate));
    if (asked !== null && now - askedAt > 10000) asked = null;  // an image that never came: ask again
    if (asked === null) {
      if (k !== frame) showFrame(k);
      else if (k >= n - 1) { stop(); return; }
    }
    if (s > 1 && playing.shown < 0.9 * s * rate) {  // the server draws fewer: said, not hidden
      $("play-info").textContent = `${what}; ${perSecond(playing.shown / s)} a second shown, the others skipped ` +
        `(drawing a frame takes ${Math.round(1000 * s / Math.max(playing.shown, 1))} ms here)`;
    }
  };
  playing.timer = setInterval(tick, 5);
  tick();
}

// a track number typed in a box: a whole number, or the reason it is none (an empty box is not track 0)
function trackBox(id, action, box) {
  const text = $(id).value.trim();
  if (!/^[0-9]+$/.test(text)) {
    throw new Error(`${action}: ${text === "" ? `the box "${box}" is empty` : `"${text}" in the box "${box}" is not a track number`}`
      + " — type a plug number of the table in both boxes");
  }
  return Number(text);
}

function canvasX(ev) {
  const c = $("diagram"), r = c.getBoundingClientRect();
  return (ev.clientX - r.left) / r.width * c.width;
}
function canvasZ(ev) {  // the position along the tube (mm) under the pointer
  const c = $("diagram"), r = c.getBoundingClientRect(), d = state.diagram;
  return d.z0 + (ev.clientY - r.top) / r.height * (d.z1 - d.z0);
}

function setup() {
  const c = $("diagram");
  let drag = null, moved = false;
  c.addEventListener("mousedown", (ev) => { drag = {x: canvasX(ev), view: view.slice()}; moved = false; });
  window.addEventListener("mouseup", (ev) => {
    if (drag && !moved && ev.target === c) {
      stop();
      clickZ = canvasZ(ev); showFrame(frameAt(xToT(canvasX(ev), c.width)));
    }
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
  const current = () => asked ?? frame;  // a step from the frame on its way, if one is
  $("prev").onclick = () => { stop(); if (current() !== null) showFrame(Math.max(0, current() - 1)); };
  $("next").onclick = () => {
    stop();
    if (current() !== null) showFrame(Math.min(state.diagram.n_frames - 1, current() + 1));
  };
  $("play").onclick = () => (playing ? stop() : play());
  $("speed").onchange = () => { if (playing) { stop(); play(); } };
  $("frame").onload = () => arrived(true);
  $("frame").onerror = () => arrived(false);
  const here = () => frame === null ? null : timeOf(frame);
  // each button says what it lacks instead of doing nothing (or sending a 0 for an empty box)
  const noTime = (what) => say(`${what}: click a time on the diagram first`);
  $("undo").onclick = () => post("undo");
  $("save").onclick = save;
  $("win-start").onclick = () => here() === null ? noTime("time window")
    : post("edit", {action: "window", start_s: here()});
  $("win-end").onclick = () => here() === null ? noTime("time window")
    : post("edit", {action: "window", end_s: here()});
  $("np-start").onclick = () => {
    if (here() === null) return noTime("no plugs");
    npStart = here(); say("");
    notice(`no plugs from ${npStart.toFixed(4)} s: click where they end, then "to here"`);
  };
  $("np-end").onclick = () => {
    if (npStart === null) return say('no plugs: click where the span starts and "from here" first');
    if (here() === null) return noTime("no plugs");
    post("edit", {action: "no_plugs", start_s: Math.min(npStart, here()), end_s: Math.max(npStart, here())});
    npStart = null;
  };
  $("np-clear").onclick = () => post("edit", {action: "clear_no_plugs"});
  const noPlace = () => say("blind stretch: click a position along the tube on the diagram first");
  $("bl-start").onclick = () => {
    if (clickZ === null) return noPlace();
    blStart = clickZ; say("");
    notice(`blind from ${blStart.toFixed(1)} mm: click where it ends along the tube, then "to here"`);
  };
  $("bl-end").onclick = () => {
    if (blStart === null) return say('blind stretch: click where it starts and "from here" first');
    if (clickZ === null) return noPlace();
    post("edit", {action: "blind", from_mm: Math.min(blStart, clickZ), to_mm: Math.max(blStart, clickZ)});
    blStart = null;
  };
  $("merge").onclick = () => {
    let track, other;
    try {
      other = trackBox("merge-b", "merge", "merge track");
      track = trackBox("merge-a", "merge", "into");
    } catch (e) { return say(e.message); }
    post("edit", {action: "merge", track: track, other: other});
  };
  $("split").onclick = () => {
    if (selected === null) return say("split: select a track in the table first");
    if (frame === null) return noTime("split");
    post("edit", {action: "split", track: selected, frame: frame});
  };
  $("run").onchange = () => { say(""); notice(""); load($("run").value); };
}

(async () => {
  setup();
  const runs = (await getJSON("api/runs")).runs;
  $("run").replaceChildren(...runs.map((r) => new Option(r, r)));
  if (runs.length < 2) $("run").disabled = true;
  await load(runs[0]);
  setInterval(poll, 2000);
})();
