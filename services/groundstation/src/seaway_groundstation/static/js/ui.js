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
