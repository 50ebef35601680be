// The map: local NED metres (x north up, y east right), drawn as SVG in screen pixels.
//
// Layers, bottom to top: optional tiles, the metric grid, the operating area (keep-in outline,
// keep-out polygons and circles, rally points), the mission flown (path, circles of
// acceptance, the active waypoint), the draft being edited (dashed, draggable handles), the trail,
// the MPC's predicted trajectory, the energy budget's home and point of no return, the other
// vessels (each in its colour: path, trail, prediction, glyph), the chosen vessel with its heading
// and the disturbance estimate as an arrow in its body frame, every vessel's name. Wheel zooms at the cursor, dragging the background pans;
// in "add" mode a click adds a waypoint; dragging a handle moves it, right-click removes it; a
// click on another vessel picks it. Focused, arrow keys pan, + and - zoom, F fits.
//
// Latitude/longitude appear only where the ground station gave the frame's origin and scale
// (`geo`: metres per degree at the origin, computed by the ground station); the page does no
// geodesy of its own beyond that linear scale and the standard web-mercator tile numbering.

const NS = "http://www.w3.org/2000/svg";

function el(name, attrs = {}, parent = null) {
  const e = document.createElementNS(NS, name);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  if (parent) parent.appendChild(e);
  return e;
}

function niceStep(mPerPx, targetPx) {
  const raw = mPerPx * targetPx;
  const p = 10 ** Math.floor(Math.log10(raw));
  for (const m of [1, 2, 5, 10]) if (m * p >= raw) return m * p;
  return 10 * p;
}

// Web-mercator tile numbering (the slippy-map convention tile servers use).
const tileLon = (x, z) => (x / 2 ** z) * 360 - 180;
const tileLat = (y, z) => (Math.atan(Math.sinh(Math.PI * (1 - (2 * y) / 2 ** z))) * 180) / Math.PI;
const lonTile = (lon, z) => Math.floor(((lon + 180) / 360) * 2 ** z);
const latTile = (lat, z) => {
  const r = (lat * Math.PI) / 180;
  return Math.floor(((1 - Math.log(Math.tan(r) + 1 / Math.cos(r)) / Math.PI) / 2) * 2 ** z);
};

export class MapView {
  constructor(svg, { onDraftChange, onReadout, onPick }) {
    this.svg = svg;
    this.onPick = onPick;
    this.onDraftChange = onDraftChange;
    this.onReadout = onReadout;
    this.scale = 8;              // px per metre
    this.center = [9, 9];        // [north, east] at the middle of the view [m]
    this.adding = false;
    this.follow = false;
    this.model = {};
    this.draft = [];             // [{x_m, y_m, lat_deg?, lon_deg?}]
    this.draftCoa = 2;
    this.tilesUrl = null;
    this.dirty = true;
    this.layers = {};
    for (const name of ["tiles", "grid", "area", "mission", "draft", "trail", "pred", "energy", "others", "vessel", "labels", "handles"]) {
      this.layers[name] = el("g", { class: `layer-${name}` }, svg);
    }
    this.bind();
    const loop = () => {
      if (this.dirty) this.render();
      requestAnimationFrame(loop);
    };
    requestAnimationFrame(loop);
    new ResizeObserver(() => this.invalidate()).observe(svg);
  }

  invalidate() { this.dirty = true; }

  size() { return [this.svg.clientWidth || 800, this.svg.clientHeight || 500]; }

  /** World [north, east] metres -> screen [x, y] pixels. */
  toScreen(n, e) {
    const [w, h] = this.size();
    return [w / 2 + (e - this.center[1]) * this.scale, h / 2 - (n - this.center[0]) * this.scale];
  }

  toWorld(sx, sy) {
    const [w, h] = this.size();
    return [this.center[0] - (sy - h / 2) / this.scale, this.center[1] + (sx - w / 2) / this.scale];
  }

  latLon(n, e) {
    const g = this.model.geo;
    return g ? [g.lat0_deg + n / g.north_m_per_deg, g.lon0_deg + e / g.east_m_per_deg] : null;
  }

  worldOfLatLon(lat, lon) {
    const g = this.model.geo;
    return [(lat - g.lat0_deg) * g.north_m_per_deg, (lon - g.lon0_deg) * g.east_m_per_deg];
  }

  setModel(model) {
    this.model = model;
    if (this.follow && model.state) this.center = [model.state.x_m, model.state.y_m];
    this.invalidate();
  }

  setDraft(draft, coa) {
    this.draft = draft;
    this.draftCoa = coa;
    this.invalidate();
  }

  /** Centre and zoom on everything there is to see (or the origin). */
  fit() {
    const pts = [];
    const m = this.model;
    for (const p of m.plan?.waypoints_m || []) pts.push(p);
    for (const p of this.draft) pts.push([p.x_m, p.y_m]);
    for (const p of m.trail || []) pts.push(p);
    if (m.state) pts.push([m.state.x_m, m.state.y_m]);
    for (const o of m.others || []) if (o.state) pts.push([o.state.x_m, o.state.y_m]);
    if (!pts.length) pts.push([0, 0]);
    let n0 = Infinity, n1 = -Infinity, e0 = Infinity, e1 = -Infinity;
    for (const [n, e] of pts) { n0 = Math.min(n0, n); n1 = Math.max(n1, n); e0 = Math.min(e0, e); e1 = Math.max(e1, e); }
    const pad = 6, minSpan = 40; // [m]: a lone vessel is shown with room around it to plan in
    const [w, h] = this.size();
    this.center = [(n0 + n1) / 2, (e0 + e1) / 2];
    const spanE = Math.max(e1 - e0 + 2 * pad, minSpan), spanN = Math.max(n1 - n0 + 2 * pad, minSpan);
    this.scale = Math.min(w / spanE, h / spanN);
    this.invalidate();
  }

  // -- interaction ---------------------------------------------------------------------------

  bind() {
    const svg = this.svg;
    let drag = null; // {kind: "pan"|"handle", index, start: [sx, sy], center, moved}
    const local = (ev) => {
      const r = svg.getBoundingClientRect();
      return [ev.clientX - r.left, ev.clientY - r.top];
    };
    svg.addEventListener("wheel", (ev) => {
      ev.preventDefault();
      const [sx, sy] = local(ev);
      const before = this.toWorld(sx, sy);
      this.scale = Math.min(500, Math.max(0.05, this.scale * Math.exp(-ev.deltaY * 0.0015)));
      const after = this.toWorld(sx, sy);
      this.center = [this.center[0] + before[0] - after[0], this.center[1] + before[1] - after[1]];
      this.invalidate();
    }, { passive: false });
    // The keyboard: arrows pan an eighth of the view, + and - zoom about the middle, F fits.
    svg.addEventListener("keydown", (ev) => {
      if (ev.altKey || ev.ctrlKey || ev.metaKey) return;
      const [w, h] = this.size();
      const pan = { ArrowUp: [h / 8, 0], ArrowDown: [-h / 8, 0], ArrowLeft: [0, -w / 8], ArrowRight: [0, w / 8] }[ev.key];
      if (pan) {
        this.follow = false;
        this.center = [this.center[0] + pan[0] / this.scale, this.center[1] + pan[1] / this.scale];
      } else if (ev.key === "+" || ev.key === "=") {
        this.scale = Math.min(500, this.scale * 1.25);
      } else if (ev.key === "-" || ev.key === "_") {
        this.scale = Math.max(0.05, this.scale / 1.25);
      } else if (ev.key === "f" || ev.key === "F") {
        this.fit();
      } else {
        return;
      }
      ev.preventDefault();
      this.invalidate();
    });
    svg.addEventListener("pointerdown", (ev) => {
      if (ev.button !== 0) return;
      const handle = ev.target.closest?.("[data-wp]");
      const p = local(ev);
      drag = handle
        ? { kind: "handle", index: Number(handle.dataset.wp), start: p, moved: false }
        : { kind: "pan", start: p, center: [...this.center], moved: false,
          // (the vessel under the pointer now: once captured, the pointer's events target the svg)
          pick: ev.target.closest?.("[data-vessel]")?.dataset.vessel };
      svg.setPointerCapture(ev.pointerId);
    });
    svg.addEventListener("pointermove", (ev) => {
      const [sx, sy] = local(ev);
      const [n, e] = this.toWorld(sx, sy);
      this.onReadout?.(n, e, this.latLon(n, e), niceStep(1 / this.scale, 80));
      if (!drag) return;
      const dx = sx - drag.start[0], dy = sy - drag.start[1];
      if (Math.hypot(dx, dy) > 4) drag.moved = true;
      if (!drag.moved) return;
      if (drag.kind === "pan") {
        this.follow = false;
        this.center = [drag.center[0] + dy / this.scale, drag.center[1] - dx / this.scale];
      } else {
        // A moved waypoint is in metres from now on (its lat/lon no longer holds); its speed stays.
        const speed = this.draft[drag.index]?.speed_mps;
        this.draft[drag.index] = { x_m: round2(n), y_m: round2(e), ...(Number.isFinite(speed) ? { speed_mps: speed } : {}) };
        this.onDraftChange?.(this.draft, false);
      }
      this.invalidate();
    });
    const end = (ev) => {
      if (!drag) return;
      const d = drag;
      drag = null;
      if (d.kind === "handle" && d.moved) this.onDraftChange?.(this.draft, true);
      if (d.kind === "pan" && !d.moved && !this.adding && d.pick) this.onPick?.(d.pick);
      if (d.kind === "pan" && !d.moved && this.adding) {
        const [n, e] = this.toWorld(...local(ev));
        this.draft.push({ x_m: round2(n), y_m: round2(e) });
        this.onDraftChange?.(this.draft, true);
        this.invalidate();
      }
    };
    svg.addEventListener("pointerup", end);
    svg.addEventListener("pointercancel", () => { drag = null; });
    svg.addEventListener("contextmenu", (ev) => {
      const handle = ev.target.closest?.("[data-wp]");
      if (!handle) return;
      ev.preventDefault();
      this.draft.splice(Number(handle.dataset.wp), 1);
      this.onDraftChange?.(this.draft, true);
      this.invalidate();
    });
  }

  // -- drawing --------------------------------------------------------------------------------

  render() {
    this.dirty = false;
    const m = this.model;
    if (this.follow && m.state) this.center = [m.state.x_m, m.state.y_m];
    this.renderTiles();
    this.renderGrid();
    this.renderArea(m.area);
    this.renderMission(m.plan, m.activeLeg);
    this.renderDraft();
    this.renderPolyline("trail", m.trail || [], "var(--trail)", 1.5, m.stale?.state);
    const pred = m.solve ? m.solve.predicted_x_m.map((x, i) => [x, m.solve.predicted_y_m[i]]) : [];
    this.renderPolyline("pred", pred, "var(--pred)", 2.2, m.stale?.solve, true);
    this.renderEnergy(m.budget, m.stale?.energy);
    this.renderOthers(m.others || []);
    this.renderVessel(m.state, m.stale?.state, m.colour);
    this.renderLabels([...(m.others || []), ...(m.state && m.name ? [{ name: m.name, state: m.state, colour: m.colour || "var(--vessel)", selected: true }] : [])]);
  }

  /** The energy budget (mission/energy, local NED like the rest of the map): home, and the point
   *  of no return ahead on the path, where the margin is predicted to reach 0. */
  renderEnergy(budget, stale) {
    const g = this.layers.energy;
    g.replaceChildren();
    if (!budget) return;
    const [hx, hy] = this.toScreen(budget.home_x_m, budget.home_y_m);
    const home = el("g", { id: "home-marker", "data-n": budget.home_x_m, "data-e": budget.home_y_m }, g);
    el("rect", { x: hx - 6, y: hy - 6, width: 12, height: 12, fill: "#fff", stroke: "var(--home)", "stroke-width": 2 }, home);
    el("text", { x: hx, y: hy + 4, "font-size": 9, "font-weight": 700, "text-anchor": "middle", fill: "var(--home)" }, home)
      .textContent = "H";
    if (!Number.isFinite(budget.no_return_x_m) || !Number.isFinite(budget.no_return_y_m)) return;
    const [sx, sy] = this.toScreen(budget.no_return_x_m, budget.no_return_y_m);
    const colour = stale ? "var(--stale)" : "var(--pnr)";
    const pnr = el("g", { id: "no-return-marker", "data-n": budget.no_return_x_m, "data-e": budget.no_return_y_m,
      transform: `translate(${sx},${sy})` }, g);
    const along = Number.isFinite(budget.no_return_along_m) ? `${budget.no_return_along_m.toFixed(1)} m ahead` : "ahead";
    el("title", {}, pnr).textContent = `point of no return: ${along}`;
    el("path", { d: "M0,-9 L9,0 L0,9 L-9,0 Z", fill: colour, stroke: "#fff", "stroke-width": 1.5 }, pnr);
    el("text", { x: 11, y: -8, "font-size": 11, "font-weight": 700, fill: colour }, pnr).textContent = "no return";
  }

  /** The operating area the controller enforces (area/active, local NED metres): the keep-in
   *  polygon as an outline, keep-out polygons and circles shaded, rally points as "R" markers.
   *  Every shape carries its name as a tooltip and data-* attributes of its world coordinates. */
  renderArea(area) {
    const g = this.layers.area;
    g.replaceChildren();
    if (!area) return;
    const points = (zone) => zone.vertices.map((v) => this.toScreen(v.x_m, v.y_m).map((c) => c.toFixed(1)).join(",")).join(" ");
    const world = (zone) => JSON.stringify(zone.vertices.map((v) => [v.x_m, v.y_m]));
    if (area.keep_in) {
      const k = el("polygon", { points: points(area.keep_in), fill: "none", stroke: "var(--keep-in)", "stroke-width": 2.5,
        "stroke-dasharray": "10 5", class: "area-keep-in", "data-world": world(area.keep_in) }, g);
      el("title", {}, k).textContent = `keep in: ${area.keep_in.name || "operating area"}`;
    }
    for (const zone of area.keep_out_polygons || []) {
      const k = el("polygon", { points: points(zone), fill: "var(--keep-out-fill)", stroke: "var(--keep-out)", "stroke-width": 2,
        class: "area-keep-out", "data-world": world(zone) }, g);
      el("title", {}, k).textContent = `keep out: ${zone.name || "area"}`;
    }
    for (const c of area.keep_out_circles || []) {
      const [sx, sy] = this.toScreen(c.x_m, c.y_m);
      const k = el("circle", { cx: sx.toFixed(1), cy: sy.toFixed(1), r: Math.max(c.radius_m * this.scale, 2).toFixed(1),
        fill: "var(--keep-out-fill)", stroke: "var(--keep-out)", "stroke-width": 2, class: "area-keep-out-circle",
        "data-n": c.x_m, "data-e": c.y_m, "data-radius-m": c.radius_m }, g);
      el("title", {}, k).textContent = `keep out: ${c.name || "circle"} (radius ${c.radius_m} m)`;
    }
    for (const r of area.rally_points || []) {
      const [sx, sy] = this.toScreen(r.x_m, r.y_m);
      const k = el("g", { class: "area-rally", "data-n": r.x_m, "data-e": r.y_m, transform: `translate(${sx.toFixed(1)},${sy.toFixed(1)})` }, g);
      el("title", {}, k).textContent = `rally point: ${r.name || ""}`.trim();
      el("circle", { r: 7, fill: "#fff", stroke: "var(--rally)", "stroke-width": 2 }, k);
      el("text", { y: 3.5, "font-size": 9, "font-weight": 700, "text-anchor": "middle", fill: "var(--rally)" }, k).textContent = "R";
    }
  }

  renderTiles() {
    const g = this.layers.tiles;
    const geo = this.model.geo;
    if (!this.tilesUrl || !geo) { g.replaceChildren(); this.tileKey = null; return; }
    const [w, h] = this.size();
    const [nTop, eLeft] = this.toWorld(0, 0), [nBot, eRight] = this.toWorld(w, h);
    const [latN, lonW] = this.latLon(nTop, eLeft), [latS, lonE] = this.latLon(nBot, eRight);
    const mPerPx = 1 / this.scale;
    const z = Math.max(0, Math.min(20, Math.round(Math.log2((156543.034 * Math.cos((geo.lat0_deg * Math.PI) / 180)) / mPerPx))));
    const x0 = lonTile(lonW, z), x1 = lonTile(lonE, z), y0 = latTile(latN, z), y1 = latTile(latS, z);
    if ((x1 - x0 + 1) * (y1 - y0 + 1) > 80) { g.replaceChildren(); return; } // zoomed too far out
    const key = `${z}/${x0}-${x1}/${y0}-${y1}/${this.scale.toFixed(4)}/${this.center}`;
    if (key === this.tileKey) return;
    this.tileKey = key;
    g.replaceChildren();
    for (let x = x0; x <= x1; x++) {
      for (let y = y0; y <= y1; y++) {
        const [n0, e0] = this.worldOfLatLon(tileLat(y, z), tileLon(x, z));
        const [n1, e1] = this.worldOfLatLon(tileLat(y + 1, z), tileLon(x + 1, z));
        const [sx0, sy0] = this.toScreen(n0, e0), [sx1, sy1] = this.toScreen(n1, e1);
        const href = this.tilesUrl.replace("{z}", z).replace("{x}", x).replace("{y}", y);
        el("image", { href, x: sx0, y: sy0, width: sx1 - sx0, height: sy1 - sy0, preserveAspectRatio: "none",
          opacity: 0.85 }, g);
      }
    }
  }

  renderGrid() {
    const g = this.layers.grid;
    g.replaceChildren();
    const [w, h] = this.size();
    const step = niceStep(1 / this.scale, 80);
    const [nTop, eLeft] = this.toWorld(0, 0), [nBot, eRight] = this.toWorld(w, h);
    for (let e = Math.ceil(eLeft / step) * step; e <= eRight; e += step) {
      const [sx] = this.toScreen(0, e);
      el("line", { x1: sx, y1: 0, x2: sx, y2: h, stroke: Math.abs(e) < step / 2 ? "#c5ced8" : "var(--grid)" }, g);
      el("text", { x: sx + 3, y: 12, "font-size": 10, fill: "var(--muted)" }, g)
        .textContent = `${+e.toPrecision(6)} m E`;
    }
    for (let n = Math.ceil(nBot / step) * step; n <= nTop; n += step) {
      const [, sy] = this.toScreen(n, 0);
      el("line", { x1: 0, y1: sy, x2: w, y2: sy, stroke: Math.abs(n) < step / 2 ? "#c5ced8" : "var(--grid)" }, g);
      if (sy > 20) el("text", { x: 3, y: sy - 3, "font-size": 10, fill: "var(--muted)" }, g).textContent = `${+n.toPrecision(6)} m N`;
    }
    // North arrow.
    const a = el("g", { transform: `translate(${w - 24},30)` }, g);
    el("path", { d: "M0,-14 L6,6 L0,2 L-6,6 Z", fill: "var(--muted)" }, a);
    el("text", { x: -4, y: 20, "font-size": 11, fill: "var(--muted)" }, a).textContent = "N";
  }

  renderMission(plan, activeLeg) {
    const g = this.layers.mission;
    g.replaceChildren();
    if (!plan || !plan.waypoints_m?.length) return;
    const pts = plan.waypoints_m.map(([n, e]) => this.toScreen(n, e));
    el("polyline", { points: pts.map((p) => p.join(",")).join(" "), fill: "none", stroke: "var(--path)",
      "stroke-width": 2 }, g);
    const r = plan.coa_radius_m * this.scale;
    pts.forEach(([sx, sy], i) => {
      const active = i === activeLeg;
      el("circle", { cx: sx, cy: sy, r: Math.max(r, 2), fill: active ? "rgba(23,105,170,.12)" : "rgba(23,105,170,.05)",
        stroke: "var(--path)", "stroke-width": active ? 2 : 1, "data-coa": i }, g);
      el("circle", { cx: sx, cy: sy, r: 3, fill: "var(--path)" }, g);
      el("text", { x: sx + 6, y: sy - 6, "font-size": 11, fill: "var(--path)", "font-weight": active ? 700 : 400 }, g)
        .textContent = `P${i}`;
    });
  }

  renderDraft() {
    const g = this.layers.draft, hg = this.layers.handles;
    g.replaceChildren();
    hg.replaceChildren();
    if (!this.draft.length) return;
    const pts = this.draft.map((p) => this.toScreen(p.x_m, p.y_m));
    el("polyline", { points: pts.map((p) => p.join(",")).join(" "), fill: "none", stroke: "var(--draft)",
      "stroke-width": 2, "stroke-dasharray": "6 4" }, g);
    const r = this.draftCoa * this.scale;
    pts.forEach(([sx, sy], i) => {
      el("circle", { cx: sx, cy: sy, r: Math.max(r, 2), fill: "none", stroke: "var(--draft)", "stroke-dasharray": "3 3" }, g);
      const h = el("g", { "data-wp": i, class: "handle", style: "cursor: grab" }, hg);
      el("circle", { cx: sx, cy: sy, r: 7, fill: "#fff", stroke: "var(--draft)", "stroke-width": 2 }, h);
      el("text", { x: sx, y: sy + 3.5, "font-size": 9, "text-anchor": "middle", fill: "var(--draft)",
        "font-weight": 700 }, h).textContent = i;
    });
  }

  renderPolyline(layer, points, stroke, width, stale, dots = false) {
    const g = this.layers[layer];
    g.replaceChildren();
    if (points.length < 2) return;
    const pts = points.map(([n, e]) => this.toScreen(n, e).map((v) => v.toFixed(1)).join(",")).join(" ");
    el("polyline", { points: pts, fill: "none", stroke: stale ? "var(--stale)" : stroke, "stroke-width": width,
      "stroke-linejoin": "round", opacity: stale ? 0.6 : 1 }, g);
    if (dots) {
      for (const [n, e] of points.filter((_, i) => i % 5 === 0)) {
        const [sx, sy] = this.toScreen(n, e);
        el("circle", { cx: sx, cy: sy, r: 1.8, fill: stale ? "var(--stale)" : stroke }, g);
      }
    }
  }

  /** Every vessel but the chosen one, in its own colour: its mission path (thin, dashed), trail,
   *  MPC prediction and glyph, each glyph a button that picks the vessel. */
  renderOthers(others) {
    const g = this.layers.others;
    g.replaceChildren();
    for (const o of others) {
      const colour = o.stale ? "var(--stale)" : o.colour;
      const line = (points, attrs) => {
        if (points.length < 2) return;
        el("polyline", { points: points.map(([n, e]) => this.toScreen(n, e).map((v) => v.toFixed(1)).join(",")).join(" "),
          fill: "none", stroke: colour, "stroke-linejoin": "round", ...attrs }, g);
      };
      line(o.plan?.waypoints_m || [], { "stroke-width": 1.5, "stroke-dasharray": "8 4", opacity: 0.8,
        class: "other-path", "data-vessel": o.name });
      line(o.trail || [], { "stroke-width": 1.5, opacity: 0.6, class: "other-trail", "data-vessel": o.name });
      line(o.pred || [], { "stroke-width": 2, opacity: 0.9, class: "other-pred", "data-vessel": o.name });
      if (!o.state) continue;
      const [sx, sy] = this.toScreen(o.state.x_m, o.state.y_m);
      const v = el("g", { transform: `translate(${sx},${sy}) rotate(${(o.state.psi_rad * 180) / Math.PI})`,
        class: "vessel-glyph other", "data-vessel": o.name, style: "cursor: pointer" }, g);
      el("title", {}, v).textContent = `${o.name}: click to pick`;
      el("path", { d: "M0,-12 L7,8 L0,4 L-7,8 Z", fill: colour, stroke: "#fff", "stroke-width": 1.5 }, v);
    }
  }

  /** Every vessel's name beside its glyph, in its colour. Vessels close together on screen (two
   *  started on one spot) get their labels stacked with a leader line instead of on top of each
   *  other. */
  renderLabels(labelled) {
    const g = this.layers.labels;
    g.replaceChildren();
    const placed = [];
    const items = labelled.filter((o) => o.state)
      .map((o) => ({ ...o, at: this.toScreen(o.state.x_m, o.state.y_m) }))
      .sort((a, b) => a.at[1] - b.at[1] || a.name.localeCompare(b.name));
    for (const o of items) {
      const [sx, sy] = o.at;
      let lx = sx + 14, ly = sy - 10;
      const width = 10 + 7.5 * o.name.length, height = 16, gap = 5; // [px], 12 px type
      while (placed.some(([px, py, pw]) => lx < px + pw + gap && px < lx + width + gap && Math.abs(ly - py) < height + gap)) {
        ly += height + gap;
      }
      placed.push([lx, ly, width]);
      const label = el("g", { class: "vessel-label", "data-vessel": o.name, "data-n": o.state.x_m, "data-e": o.state.y_m }, g);
      if (Math.hypot(lx - sx, ly - sy) > 20) {
        el("line", { x1: sx, y1: sy, x2: lx, y2: ly, stroke: o.colour, "stroke-width": 1 }, label);
      }
      el("rect", { x: lx - 3, y: ly - 12, width, height, rx: 3, fill: "#fff", opacity: 0.9,
        stroke: o.colour, "stroke-width": o.selected ? 2 : 1 }, label);
      el("text", { x: lx + 1, y: ly, "font-size": 12, "font-weight": o.selected ? 700 : 500, fill: o.colour }, label)
        .textContent = o.name;
    }
  }

  renderVessel(state, stale, colour) {
    const g = this.layers.vessel;
    g.replaceChildren();
    if (!state) return;
    const [sx, sy] = this.toScreen(state.x_m, state.y_m);
    const deg = (state.psi_rad * 180) / Math.PI; // clockwise from north, as SVG rotates on screen
    const v = el("g", { transform: `translate(${sx},${sy}) rotate(${deg})`, id: "vessel-glyph" }, g);
    // The disturbance estimate, drawn in the body frame (surge ahead = up, sway to starboard =
    // right) inside the rotated glyph: the arrow points where the estimated force pushes.
    const fx = state.tau_d_sway_n || 0, fy = -(state.tau_d_surge_n || 0);
    const mag = Math.hypot(fx, fy);
    if (mag > 1e-3) {
      const len = 70 * Math.tanh(mag / 10) + 8;
      const ux = fx / mag, uy = fy / mag;
      const ex = ux * len, ey = uy * len;
      el("line", { x1: 0, y1: 0, x2: ex, y2: ey, stroke: "var(--dist)", "stroke-width": 2.5 }, v);
      el("path", { d: `M${ex},${ey} L${ex - 8 * ux + 4 * uy},${ey - 8 * uy - 4 * ux} L${ex - 8 * ux - 4 * uy},${ey - 8 * uy + 4 * ux} Z`,
        fill: "var(--dist)", id: "disturbance-arrow" }, v);
    }
    el("path", { d: "M0,-15 L8,9 L0,5 L-8,9 Z", fill: stale ? "var(--stale)" : colour || "var(--vessel)", stroke: "#fff",
      "stroke-width": 1.5 }, v);
  }
}

const round2 = (v) => Math.round(v * 100) / 100;
