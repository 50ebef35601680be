// The fleet's refusals, under the fleet table: messages the ground station dropped because their
// vessel name is not valid or because it already keeps its most vessels (`vessels_refused`,
// `max_vessels`), and silent vessels it forgot to make room for new names (`vessels_forgotten`),
// all from GET /api/vessels. Shown only while one of them is not 0: a crew then knows a boat's
// messages may be going unheard, or that vessels are being made up under many names.

function line(id, count, text) {
  const p = document.createElement("p");
  const n = document.createElement("strong");
  n.id = id;
  n.textContent = String(count);
  p.append(n, ` ${text}`);
  return p;
}

/** Fill the notice `el` from the fleet view's counts (null: none read yet); true if it shows. */
export function renderFleetNotice(el, counts) {
  const refused = counts?.refused || 0, forgotten = counts?.forgotten || 0, max = counts?.max || 0;
  const shown = refused > 0 || forgotten > 0;
  const key = shown ? `${refused}|${forgotten}|${max}` : "";
  if (el.dataset.key === key) return shown;
  el.dataset.key = key;
  const lines = [];
  if (refused > 0) {
    lines.push(line("fleet-refused", refused, `${refused === 1 ? "message" : "messages"} from unknown or `
      + `extra vessels dropped (the ground station keeps at most ${max} ${max === 1 ? "vessel" : "vessels"})`));
  }
  if (forgotten > 0) {
    lines.push(line("fleet-forgotten", forgotten, `silent ${forgotten === 1 ? "vessel" : "vessels"} `
      + "forgotten to make room for new ones"));
  }
  el.replaceChildren(...lines);
  el.hidden = !shown;
  return shown;
}
