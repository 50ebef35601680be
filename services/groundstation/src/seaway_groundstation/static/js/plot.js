// A time-series plot on a canvas: one or more lines against time [s], a title with the latest
// values, automatic "nice" axes, and a stale state (greyed lines and a STALE badge).

import { colour } from "./ui.js";

function niceStep(span, target) {
  const raw = span / Math.max(1, target);
  const p = 10 ** Math.floor(Math.log10(raw));
  for (const m of [1, 2, 5, 10]) if (m * p >= raw) return m * p;
  return 10 * p;
}

export class TimePlot {
  /**
   * canvas: the element; title: text; unit: y unit; lines: [{key, label, colour (CSS variable
   * name)}]; digits: decimals of the readout; zeroBased: keep 0 in the y range; siPrefix: show
   * large values in k or M of the unit (energy in kJ, MJ) so that axis labels stay short.
   */
  constructor(canvas, { title, unit, lines, digits = 1, zeroBased = false, siPrefix = false }) {
    Object.assign(this, { canvas, title, unit, lines, digits, zeroBased, siPrefix });
    this.ctx = canvas.getContext("2d");
    this.canvas.dataset.title = title;
  }

  /** Draw `data` ({t: [...], key: [...]}) ; stale greys it; `cursorT` marks a time (replay). */
  draw(data, { stale = false, cursorT = null, empty = "no data yet" } = {}) {
    const { canvas, ctx } = this;
    const dpr = window.devicePixelRatio || 1;
    const w = canvas.clientWidth, h = canvas.clientHeight;
    if (canvas.width !== Math.round(w * dpr) || canvas.height !== Math.round(h * dpr)) {
      canvas.width = Math.round(w * dpr);
      canvas.height = Math.round(h * dpr);
    }
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.clearRect(0, 0, w, h);
    const ink = colour("ink"), muted = colour("muted"), grid = colour("grid");
    const pad = { l: 46, r: 8, t: 22, b: 20 };
    const pw = w - pad.l - pad.r, ph = h - pad.t - pad.b;

    // The unit's prefix from the largest value shown (k from 10^4, M from 10^6).
    const n = data?.t?.length ?? 0;
    let top = 0;
    if (this.siPrefix) {
      for (const line of this.lines) for (const v of data?.[line.key] || []) if (Number.isFinite(v)) top = Math.max(top, Math.abs(v));
    }
    const [scale, prefix] = top >= 1e6 ? [1e6, "M"] : top >= 1e4 ? [1e3, "k"] : [1, ""];
    const unit = `${prefix}${this.unit}`;
    this.canvas.dataset.unit = unit;
    const digits = scale === 1 ? this.digits : 2;

    // Title and latest values.
    ctx.font = "600 12px system-ui, sans-serif";
    ctx.fillStyle = ink;
    ctx.textBaseline = "top";
    ctx.fillText(`${this.title} [${unit}]`, 4, 3);
    let x = ctx.measureText(`${this.title} [${unit}]`).width + 14;
    ctx.font = "12px system-ui, sans-serif";
    for (const line of this.lines) {
      const v = n ? data[line.key][n - 1] : NaN;
      ctx.fillStyle = stale ? colour("stale") : colour(line.colour);
      const text = `${line.label} ${Number.isFinite(v) ? (v / scale).toFixed(digits) : "–"}`;
      ctx.fillText(text, x, 3);
      x += ctx.measureText(text).width + 10;
    }

    if (!n) {
      ctx.fillStyle = muted;
      ctx.textAlign = "center";
      ctx.fillText(empty, pad.l + pw / 2, pad.t + ph / 2);
      ctx.textAlign = "left";
      this.badge(stale, w);
      return;
    }

    // Ranges.
    const t0 = data.t[0], t1 = Math.max(data.t[n - 1], t0 + 1);
    let lo = Infinity, hi = -Infinity;
    for (const line of this.lines) {
      for (const v of data[line.key]) if (Number.isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
    }
    if (!Number.isFinite(lo)) { lo = 0; hi = 1; }
    if (this.zeroBased) { lo = Math.min(lo, 0); hi = Math.max(hi, 0); }
    if (hi - lo < 1e-9) { hi += 0.5; lo -= 0.5; }
    const m = (hi - lo) * 0.06;
    lo -= m; hi += m;
    const X = (t) => pad.l + ((t - t0) / (t1 - t0)) * pw;
    const Y = (v) => pad.t + (1 - (v - lo) / (hi - lo)) * ph;

    // Grid and axes.
    ctx.strokeStyle = grid;
    ctx.fillStyle = muted;
    ctx.lineWidth = 1;
    ctx.font = "11px system-ui, sans-serif";
    const ys = niceStep(hi - lo, 4);
    ctx.textAlign = "right";
    ctx.textBaseline = "middle";
    for (let v = Math.ceil(lo / ys) * ys; v <= hi; v += ys) {
      ctx.beginPath(); ctx.moveTo(pad.l, Y(v)); ctx.lineTo(pad.l + pw, Y(v)); ctx.stroke();
      ctx.fillText(Math.abs(v) < ys / 1e6 ? "0" : +(v / scale).toPrecision(6) + "", pad.l - 4, Y(v));
    }
    const xs = niceStep(t1 - t0, 5);
    ctx.textAlign = "center";
    ctx.textBaseline = "top";
    for (let t = Math.ceil(t0 / xs) * xs; t <= t1; t += xs) {
      ctx.beginPath(); ctx.moveTo(X(t), pad.t); ctx.lineTo(X(t), pad.t + ph); ctx.stroke();
      ctx.fillText(`${+t.toPrecision(6)} s`, X(t), pad.t + ph + 3);
    }
    ctx.textAlign = "left";

    // Lines (a gap where a value is missing).
    for (const line of this.lines) {
      ctx.strokeStyle = stale ? colour("stale") : colour(line.colour);
      ctx.lineWidth = 1.6;
      ctx.beginPath();
      let pen = false;
      const vs = data[line.key];
      for (let i = 0; i < n; i++) {
        const v = vs[i];
        if (!Number.isFinite(v)) { pen = false; continue; }
        if (pen) ctx.lineTo(X(data.t[i]), Y(v)); else ctx.moveTo(X(data.t[i]), Y(v));
        pen = true;
      }
      ctx.stroke();
    }
    if (cursorT !== null && cursorT >= t0 && cursorT <= t1) {
      ctx.strokeStyle = colour("accent");
      ctx.setLineDash([3, 3]);
      ctx.beginPath(); ctx.moveTo(X(cursorT), pad.t); ctx.lineTo(X(cursorT), pad.t + ph); ctx.stroke();
      ctx.setLineDash([]);
    }
    this.badge(stale, w);
  }

  badge(stale, w) {
    this.canvas.dataset.stale = stale ? "true" : "false";
    if (!stale) return;
    const ctx = this.ctx;
    ctx.font = "600 11px system-ui, sans-serif";
    const text = "STALE";
    const tw = ctx.measureText(text).width;
    ctx.fillStyle = colour("warn");
    ctx.fillRect(w - tw - 16, 2, tw + 12, 16);
    ctx.fillStyle = "#fff";
    ctx.textBaseline = "top";
    ctx.fillText(text, w - tw - 10, 4);
  }
}
