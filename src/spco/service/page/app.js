// The page of `spco serve`: the home's map, its learnt regions, and asking and teaching it.
// Plain JavaScript and SVG, no build step. Coordinates on the map are metres; y points up.
"use strict";

const SVG = "http://www.w3.org/2000/svg";
// matplotlib's tab20 in the order spco's figures use (dark shades first): one colour a concept
const COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
  "#bcbd22", "#17becf", "#aec7e8", "#ffbb78", "#98df8a", "#ff9896", "#c5b0d5", "#c49c94", "#f7b6d2",
  "#c7c7c7", "#dbdb8d", "#9edae5"];

const state = { extent: [0, 1, 0, 1], unit: 0.05, clicked: null, lastTeaching: null, regions: null,
  lastWhere: null };
// A region is drawn unless it is negligible: less than this share of the home's samples, none taught
// and no place found there.
const NEGLIGIBLE = 0.01;
const $ = (id) => document.getElementById(id);

function el(name, attrs, parent) {
  const node = document.createElementNS(SVG, name);
  for (const [k, v] of Object.entries(attrs || {})) node.setAttribute(k, v);
  if (parent) parent.appendChild(node);
  return node;
}

// map coordinates (metres, y up) -> SVG user units (metres, y down)
const sx = (x) => x - state.extent[0];
const sy = (y) => state.extent[3] - y;

async function api(path, options) {
  const response = await fetch(path, Object.assign({ credentials: "same-origin" }, options || {}));
  const text = await response.text();
  let body;
  try { body = JSON.parse(text); } catch (e) { body = { error: text }; }
  if (!response.ok) throw new Error(body.error || response.statusText);
  return body;
}

function log(kind, text) {
  const item = document.createElement("li");
  item.className = kind;
  item.textContent = new Date().toLocaleTimeString() + " " + text;
  const list = $("log");
  list.insertBefore(item, list.firstChild);
  while (list.children.length > 30) list.removeChild(list.lastChild);
}

function fmt(p) { return (100 * p).toFixed(0) + "%"; }

async function loadRegions() {
  const r = await api("/regions");
  state.regions = r;
  const [x0, x1, y0, y1] = r.map ? r.map.extent : r.extent;
  const pad = 0.07 * Math.max(x1 - x0, y1 - y0);  // room for the axes' labels
  state.extent = [x0 - pad, x1 + pad, y0 - pad, y1 + pad];
  state.unit = Math.max(x1 - x0, y1 - y0) / 60;  // text and marks scale with the map
  const svg = $("map");
  svg.setAttribute("viewBox", `0 0 ${state.extent[1] - state.extent[0]} ${state.extent[3] - state.extent[2]}`);
  $("home-name").textContent = r.home;
  const shown = r.regions.filter((g) => g.weight >= NEGLIGIBLE || g.taught > 0 || g.places.length > 0);
  const hidden = r.regions.length - shown.length;
  $("stats").textContent = `${r.samples.length} samples, ${r.samples.filter((s) => s.sentence).length} taught, ` +
    `${shown.length} regions` + (hidden ? ` (${hidden} of under ${fmt(NEGLIGIBLE)} of the samples not drawn)` : "") +
    `, ${r.teachings} teachings served (seq ${r.seq})`;
  const names = $("known-names");
  names.innerHTML = "";
  for (const n of r.names) { const o = document.createElement("option"); o.value = n; names.appendChild(o); }

  const mapLayer = $("layer-map");
  mapLayer.innerHTML = "";
  if (r.map) {
    const [mx0, mx1, my0, my1] = r.map.extent;
    el("image", { href: r.map.url, x: sx(mx0), y: sy(my1), width: mx1 - mx0, height: my1 - my0,
      preserveAspectRatio: "none", opacity: 0.85 }, mapLayer);
  } else {
    el("rect", { x: sx(x0), y: sy(y1), width: x1 - x0, height: y1 - y0, fill: "none", stroke: "#b0bec5",
      "stroke-width": state.unit * 0.1, "stroke-dasharray": `${state.unit} ${state.unit}` }, mapLayer);
  }
  drawAxes(x0, x1, y0, y1);
  const samples = $("layer-samples");
  samples.innerHTML = "";
  for (const s of r.samples) {
    const dot = el("circle", { cx: sx(s.x), cy: sy(s.y), r: state.unit * (s.sentence ? 0.22 : 0.16),
      class: "sample" + (s.sentence ? " taught" : "") }, samples);
    el("title", {}, dot).textContent = `sample ${s.id}` + (s.sentence ? `: “${s.sentence}”` : "");
  }
  const regions = $("layer-regions");
  const labels = $("layer-labels");
  regions.innerHTML = "";
  labels.innerHTML = "";
  for (const g of shown) {
    const colour = COLOURS[g.concept % COLOURS.length];
    const cx = sx(g.mean[0]), cy = sy(g.mean[1]);
    const shape = el("ellipse", { cx, cy, rx: Math.max(g.ellipse.rx, 1e-3), ry: Math.max(g.ellipse.ry, 1e-3),
      transform: `rotate(${-g.ellipse.angle} ${cx} ${cy})`, fill: colour, stroke: colour, class: "region",
      "data-region": g.region, "data-concept": g.concept }, regions);
    el("title", {}, shape).textContent = `region ${g.region} (concept ${g.concept}, ${g.samples} samples): ` +
      g.names.map((n) => `${n.name} ${fmt(n.p)}`).join(", ") +
      g.places.map((n) => `; where ${n.name}: here, p ${fmt(n.p)}`).join("");
    el("path", { d: `M ${cx - state.unit * 0.4} ${cy} h ${state.unit * 0.8} M ${cx} ${cy - state.unit * 0.4} ` +
      `v ${state.unit * 0.8}`, class: "region-centre" }, regions);
    // a place is labelled where `where` goes for it (its most probable region; p = p(region | name)):
    // the label and the answer to "where is …" are one answer
    if (!g.places.length) continue;
    const label = el("text", { x: cx, y: cy - state.unit * 0.6, "text-anchor": "middle", class: "region-label",
      "font-size": state.unit * 1.1, "stroke-width": state.unit * 0.25, "data-region": g.region,
      "data-places": g.places.map((n) => n.name).join("|") }, labels);
    label.textContent = g.places[0].name + " ";
    const p = el("tspan", { class: "p" }, label);
    p.textContent = fmt(g.places[0].p);
    for (const other of g.places.slice(1)) {
      const more = el("tspan", { x: cx, dy: state.unit * 1.1, class: "p", "font-size": state.unit * 0.9 }, label);
      more.textContent = `${other.name} ${fmt(other.p)}`;
    }
  }
  if (state.clicked) drawClick();
}

// axes in metres along the map's lower and left edges, and a scale bar
function drawAxes(x0, x1, y0, y1) {
  const layer = $("layer-axes");
  layer.innerHTML = "";
  const span = Math.max(x1 - x0, y1 - y0);
  const step = [0.5, 1, 2, 5, 10, 20, 50].find((s) => span / s <= 12) || 100;
  const u = state.unit;
  const tick = { class: "axis", "stroke-width": u * 0.08 };
  const text = { class: "axis-label", "font-size": u * 0.8 };
  el("line", Object.assign({ x1: sx(x0), y1: sy(y0), x2: sx(x1), y2: sy(y0) }, tick), layer);
  el("line", Object.assign({ x1: sx(x0), y1: sy(y0), x2: sx(x0), y2: sy(y1) }, tick), layer);
  for (let x = Math.ceil(x0 / step) * step; x <= x1 + 1e-9; x += step) {
    el("line", Object.assign({ x1: sx(x), y1: sy(y0), x2: sx(x), y2: sy(y0) + u * 0.4 }, tick), layer);
    el("text", Object.assign({ x: sx(x), y: sy(y0) + u * 1.3, "text-anchor": "middle" }, text), layer)
      .textContent = `${+x.toFixed(2)}`;
  }
  for (let y = Math.ceil(y0 / step) * step; y <= y1 + 1e-9; y += step) {
    el("line", Object.assign({ x1: sx(x0), y1: sy(y), x2: sx(x0) - u * 0.4, y2: sy(y) }, tick), layer);
    el("text", Object.assign({ x: sx(x0) - u * 0.6, y: sy(y) + u * 0.3, "text-anchor": "end" }, text), layer)
      .textContent = `${+y.toFixed(2)}`;
  }
  el("text", Object.assign({ x: sx(x1), y: sy(y0) - u * 0.5, "text-anchor": "end" }, text), layer).textContent = "x (m)";
  el("text", Object.assign({ x: sx(x0) + u * 0.5, y: sy(y1) + u * 0.9 }, text), layer).textContent = "y (m)";
  const bar = step, bx = sx(x0) + u, by = sy(y0) - u * 0.8;  // the scale bar, lower left
  el("path", { d: `M ${bx} ${by - u * 0.3} v ${u * 0.3} h ${bar} v ${-u * 0.3}`, class: "scale-bar",
    "stroke-width": u * 0.15, fill: "none" }, layer);
  el("text", Object.assign({ x: bx + bar / 2, y: by - u * 0.5, "text-anchor": "middle" }, text), layer)
    .textContent = `${bar} m`;
}

// after a teaching or an undo, here or by anyone: every panel shows the home as it is now
async function refreshPanels() {
  await loadRegions();
  await askWhat();
  if (state.lastWhere) await showWhere(state.lastWhere);
}

function drawClick() {
  const layer = $("layer-click");
  layer.innerHTML = "";
  const { x, y } = state.clicked;
  el("circle", { cx: sx(x), cy: sy(y), r: state.unit * 0.5, class: "click-mark",
    "stroke-width": state.unit * 0.15 }, layer);
}

function heading() {
  const degrees = parseFloat($("theta").value);
  return (Number.isFinite(degrees) ? degrees : 0) * Math.PI / 180;
}

async function askWhat() {
  if (!state.clicked) return;
  const { x, y } = state.clicked;
  const theta = heading();
  $("point").textContent = `x ${x.toFixed(2)} m, y ${y.toFixed(2)} m, θ ${(theta * 180 / Math.PI).toFixed(0)}°`;
  const list = $("what-names");
  try {
    const answer = await api(`/what?x=${x}&y=${y}&theta=${theta}&top=5`);
    list.innerHTML = "";
    for (const n of answer.names) {
      const item = document.createElement("li");
      item.textContent = `${n.name} — p ${n.probability.toFixed(3)}`;
      list.appendChild(item);
    }
    if (answer.warning) $("point").textContent += " (off the map)";
  } catch (error) {
    list.innerHTML = `<li class="error"></li>`;
    list.firstChild.textContent = error.message;
  }
}

async function askWhere(event) {
  event.preventDefault();
  const name = $("where-input").value.trim();
  if (!name) return;
  state.lastWhere = name;
  await showWhere(name);
}

async function showWhere(name) {
  const layer = $("layer-poses");
  layer.innerHTML = "";
  try {
    const answer = await api(`/where?name=${encodeURIComponent(name)}&n=10`);
    for (const p of answer.positions) {
      const g = el("g", { class: "pose" }, layer);
      const length = state.unit * 1.4;
      el("line", { x1: sx(p.x), y1: sy(p.y), x2: sx(p.x) + length * Math.cos(p.theta),
        y2: sy(p.y) - length * Math.sin(p.theta), "stroke-width": state.unit * 0.22 }, g);
      el("circle", { cx: sx(p.x), cy: sy(p.y), r: state.unit * 0.38, "stroke-width": state.unit * 0.1 }, g);
      el("title", {}, g).textContent = `${answer.name}: (${p.x.toFixed(2)}, ${p.y.toFixed(2)}), p ${p.probability.toFixed(2)}`;
    }
    $("where-result").className = answer.learnt ? "ok" : "";
    $("where-result").textContent = (answer.via ? `${answer.asked} → ` : "") +
      `${answer.name}: ${answer.positions.length} poses in region ${answer.region}` +
      ` (p ${answer.region_probability.toFixed(2)})` + (answer.learnt ? "" : " — not learnt in this home: a guess");
  } catch (error) {
    $("where-result").className = "error";
    $("where-result").textContent = error.message;
  }
}

async function teach(event) {
  event.preventDefault();
  const sentence = $("teach-sentence").value.trim();
  const result = $("teach-result");
  if (!state.clicked) { result.className = "error"; result.textContent = "Click the map where it is first."; return; }
  if (!sentence) { result.className = "error"; result.textContent = "Type what the place is."; return; }
  $("teach-button").disabled = true;
  try {
    const { x, y } = state.clicked;
    const answer = await api("/teach", { method: "POST", headers: { "Content-Type": "application/json" },
      body: JSON.stringify({ x, y, theta: heading(), sentence }) });
    state.lastTeaching = answer.seq;
    $("undo-button").disabled = false;
    result.className = "ok";
    result.textContent = `Taught (seq ${answer.seq}, ${answer.teachings} teachings).` +
      (answer.new_words.length ? ` New words: ${answer.new_words.join(", ")}.` : "") +
      (answer.notes.length ? " " + answer.notes.join(" ") : "");
    $("teach-sentence").value = "";
    await refreshPanels();
  } catch (error) {
    result.className = "error";
    result.textContent = error.message;
  } finally {
    $("teach-button").disabled = false;
  }
}

async function undo() {
  if (state.lastTeaching === null) return;
  try {
    const answer = await api(`/teach/${state.lastTeaching}`, { method: "DELETE" });
    $("teach-result").className = "ok";
    $("teach-result").textContent = `Undone (teaching ${answer.undoes}).`;
    state.lastTeaching = null;
    $("undo-button").disabled = true;
    await refreshPanels();
  } catch (error) {
    $("teach-result").className = "error";
    $("teach-result").textContent = error.message;
  }
}

function onMapClick(event) {
  const svg = $("map");
  const point = svg.createSVGPoint();
  point.x = event.clientX;
  point.y = event.clientY;
  const local = point.matrixTransform(svg.getScreenCTM().inverse());
  state.clicked = { x: local.x + state.extent[0], y: state.extent[3] - local.y };
  drawClick();
  askWhat();
}

function listen() {
  const source = new EventSource("/events");
  source.onopen = () => { $("connection").textContent = "live"; $("connection").className = "online"; };
  source.onerror = () => { $("connection").textContent = "reconnecting…"; $("connection").className = "offline"; };
  let pending = null;
  const refresh = () => { if (!pending) pending = setTimeout(() => { pending = null; refreshPanels(); }, 150); };
  source.addEventListener("taught", (e) => {
    const t = JSON.parse(e.data);
    const where = t.op === "observation" ? ` at (${t.x.toFixed(2)}, ${t.y.toFixed(2)})` : ` for sample ${t.id}`;
    log("taught", `taught #${t.seq}: “${t.sentence || ""}”${where}`);
    refresh();
  });
  source.addEventListener("undone", (e) => {
    const t = JSON.parse(e.data);
    log("undone", `undone #${t.undoes} (seq ${t.seq})`);
    refresh();
  });
  source.addEventListener("answer", (e) => {
    const a = JSON.parse(e.data);
    if (a.kind === "what") {
      log("answer", `what at (${a.pose.x.toFixed(2)}, ${a.pose.y.toFixed(2)}): ` +
        a.names.map((n) => n.name).join(", "));
    } else {
      log("answer", `where ${a.name}`);
    }
  });
}

$("map").addEventListener("click", onMapClick);
$("theta").addEventListener("change", askWhat);
$("where-form").addEventListener("submit", askWhere);
$("teach-form").addEventListener("submit", teach);
$("undo-button").addEventListener("click", undo);
loadRegions().then(listen).catch((error) => {
  $("stats").textContent = "cannot load the home: " + error.message;
  $("stats").className = "error";
});
