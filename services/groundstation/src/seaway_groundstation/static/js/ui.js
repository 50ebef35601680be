// Small page helpers: messages to the operator, number formatting, element lookup.

export const $ = (id) => document.getElementById(id);

const box = () => $("messages");
const sticky = new Map(); // key -> element, for messages that stay until their cause is gone

/** A message in the corner; kind: info | ok | warn | error. Errors stay until closed. */
export function say(text, kind = "info", { timeoutMs } = {}) {
  const el = document.createElement("div");
  el.className = `msg ${kind}`;
  el.setAttribute("role", kind === "error" ? "alert" : "status");
  const close = document.createElement("button");
  close.className = "close";
  close.textContent = "×";
  close.title = "dismiss";
  close.onclick = () => el.remove();
  el.append(close, document.createTextNode(text));
  box().prepend(el);
  while (box().children.length > 6) box().lastChild.remove();
  const ms = timeoutMs ?? (kind === "error" ? 0 : kind === "warn" ? 8000 : 4000);
  if (ms > 0) setTimeout(() => el.remove(), ms);
  return el;
}

/** A message that stays while `on` is true (e.g. "link lost"), shown once per key. */
export function stickySay(key, on, text, kind = "warn") {
  const el = sticky.get(key);
  if (on && !el) {
    const m = say(text, kind, { timeoutMs: 0 });
    m.dataset.sticky = key;
    sticky.set(key, m);
  } else if (!on && el) {
    el.remove();
    sticky.delete(key);
  } else if (on && el && el.lastChild.textContent !== text) {
    el.lastChild.textContent = text;
  }
}

/** A number with its unit, or an en dash for none. */
export function fmt(value, digits = 1, unit = "") {
  if (value === null || value === undefined || !Number.isFinite(value)) return "–";
  return `${value.toFixed(digits)}${unit ? " " + unit : ""}`;
}

/** An energy [J] in the unit an operator reads: J under 1 kJ, kJ (with Wh) under 1 MJ, else MJ
 *  (with Wh); 3 significant digits at least. */
export function fmtEnergy(j) {
  if (j === null || j === undefined || !Number.isFinite(j)) return "–";
  const a = Math.abs(j);
  if (a < 1e3) return `${j.toFixed(a < 10 ? 2 : a < 100 ? 1 : 0)} J`;
  const wh = j / 3600;
  const whText = Math.abs(wh) < 10 ? wh.toFixed(2) : Math.abs(wh) < 100 ? wh.toFixed(1) : wh.toFixed(0);
  if (a < 1e6) return `${(j / 1e3).toFixed(a < 1e4 ? 2 : a < 1e5 ? 1 : 0)} kJ (${whText} Wh)`;
  return `${(j / 1e6).toFixed(a < 1e7 ? 2 : 1)} MJ (${whText} Wh)`;
}

/** A duration [s] as "1 h 02 min", "4 min 05 s" or "12 s". */
export function fmtDuration(s) {
  if (s === null || s === undefined || !Number.isFinite(s) || s < 0) return "–";
  const t = Math.round(s);
  if (t >= 3600) return `${Math.floor(t / 3600)} h ${String(Math.floor((t % 3600) / 60)).padStart(2, "0")} min`;
  if (t >= 60) return `${Math.floor(t / 60)} min ${String(t % 60).padStart(2, "0")} s`;
  return `${t} s`;
}

export function setText(id, text, cls) {
  const el = $(id);
  if (!el) return;
  el.textContent = text;
  if (cls !== undefined) el.className = cls;
}

/** Show or hide the stale badges of a kind, and dim what they label. */
export function markStale(kind, stale) {
  for (const badge of document.querySelectorAll(`[data-stale="${kind}"]`)) {
    badge.hidden = !stale;
    badge.closest(".panel")?.querySelector("dl")?.classList.toggle("is-stale", stale);
  }
}

/** Read a CSS colour variable (the palette lives in style.css). */
export const colour = (name) => getComputedStyle(document.documentElement).getPropertyValue(`--${name}`).trim();
