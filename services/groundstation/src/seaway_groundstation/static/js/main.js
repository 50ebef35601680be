// The page: live view and replay view over the same store, map and plots.
//
// Live: the WebSocket stream feeds `live.store`; GET /api/vessels (every 2 s) gives what frames do
// not carry (the mission flown in metres, the NED origin's scale, simulated or not, what it dropped:
// fleetnotice.js) and tells when the ground station itself is unreachable; GET .../metrics gives
// the paper's metrics so far.
// Replay: `Player` feeds its own store from the recording's frames at the recording's time.
// Every command goes through `run()`, which asks for the token when needed and shows the answer.

import { ApiError, CLIENT_ID, command, get, getToken, request, setToken, takeTokenFromFragment } from "./api.js";
import { renderFleetNotice } from "./fleetnotice.js";
import { LiveStream } from "./live.js";
import { MapView } from "./map.js";
import { TimePlot } from "./plot.js";
import { Player, liveHistory } from "./replay.js";
import { Store } from "./store.js";
import { $, fmt, fmtDuration, fmtEnergy, markStale, say, setText, stickySay } from "./ui.js";

const POLL_MS = 2000;
const METRICS_MS = 1500;
const VESSEL_KEY = "seaway.groundstation.vessel";

const app = {
  mode: "live",
  config: { stale_after_s: 2, controllers: ["cc-empc", "eo-empc", "nmpc"], tiles_url: null },
  live: new Store(),
  fleet: new Map(),        // vessel -> VesselView from GET /api/vessels
  fleetCounts: null,       // {refused, forgotten, max}: what GET /api/vessels says it dropped
  metrics: null,           // MetricsView of the selected vessel, or null
  linkUp: false,
  apiUp: true,
  selected: sessionStorage.getItem(VESSEL_KEY) || "",
  draft: [],
  lastMissionId: null,
  lastCommands: new Map(), // vessel -> the last command relayed to it, in words
};

// -- setup ----------------------------------------------------------------------------------------

takeTokenFromFragment();

const map = new MapView($("map"), {
  onPick: (name) => selectVessel(name),
  onDraftChange: (draft, done) => {
    app.draft = draft;
    renderDraftTable();
    if (done) map.setDraft(app.draft, coa());
  },
  onReadout: (n, e, ll, gridM) => {
    const pos = `N ${n.toFixed(2)} m  E ${e.toFixed(2)} m`;
    const geo = ll ? `  ${ll[0].toFixed(6)}°, ${ll[1].toFixed(6)}°` : "  (no origin: lat/lon unknown)";
    setText("map-readout", `${pos}${geo}  · grid ${gridM} m`);
  },
});

const plots = {
  thrust: new TimePlot($("plot-thrust"), { title: "Thrust", unit: "N", digits: 1, zeroBased: true,
    lines: [{ key: "port", label: "port", colour: "port" }, { key: "starboard", label: "stbd", colour: "starboard" }] }),
  speed: new TimePlot($("plot-speed"), { title: "Speed", unit: "m/s", digits: 2, zeroBased: true,
    lines: [{ key: "speed", label: "", colour: "vessel" }] }),
  xte: new TimePlot($("plot-xte"), { title: "Cross-track error", unit: "m", digits: 2, zeroBased: true,
    lines: [{ key: "xte", label: "", colour: "pred" }] }),
  energy: new TimePlot($("plot-energy"), { title: "Energy", unit: "J", digits: 0, zeroBased: true, siPrefix: true,
    lines: [{ key: "used", label: "used", colour: "accent" }, { key: "finish", label: "to finish", colour: "draft" },
      { key: "home", label: "to home", colour: "home" }] }),
};

const stream = new LiveStream({
  onFrame: (frame) => {
    noteCommand(frame.vessel, frame.updates?.command?.message);
    const name = app.live.ingest(frame, clockLive());
    if (name && !app.selected) selectVessel(name);
    schedule();
  },
  onLink: (state, why) => {
    app.linkUp = state === "up";
    updateLinkPill();
    if (state === "down") stickySay("link", true, `Link to the ground station lost (${why}); reconnecting…`, "error");
    if (state === "up") stickySay("link", false);
    schedule();
  },
});

const player = new Player({
  onUpdate: () => schedule(),
  onProgress: (f) => { $("load-progress").firstElementChild.style.width = `${(f * 100).toFixed(0)}%`; },
  onState: () => updateTransport(),
});

/** A command another tab or client sent through this ground station (it streams each one it
 *  relays): said in a note and kept in the vehicle panel. The page's own are answered in `run`. */
const LOADED_NS = Date.now() * 1e6;
const commandsSeen = new Set();
function noteCommand(vessel, c) {
  if (!c || !vessel) return;
  const key = `${vessel}|${c.stamp_ns}|${c.request}`;
  if (commandsSeen.has(key)) return;
  commandsSeen.add(key);
  const mine = c.client === CLIENT_ID;
  const when = new Date(c.stamp_ns / 1e6).toISOString().slice(11, 19);
  const answer = c.outcome === "accepted" ? "accepted" : `${c.outcome.replace("_", " ")}${c.reason ? `: ${c.reason}` : ""}`;
  app.lastCommands.set(vessel, `${c.what} — ${answer}, ${when} UTC${mine ? "" : ", from another tab or client"}`);
  if (!mine && c.stamp_ns > LOADED_NS) {
    say(`${vessel}: ${c.what} sent by another tab or client — ${answer}`, c.outcome === "accepted" ? "warn" : "info");
  }
}

const clockLive = () => performance.now() / 1000;
const now = () => (app.mode === "live" ? clockLive() : player.t);
const store = () => (app.mode === "live" ? app.live : player.store);
const coa = () => Number($("coa").value) || 0;

// -- rendering ------------------------------------------------------------------------------------

let scheduled = false;
let lastRender = 0;
function schedule() {
  if (scheduled) return;
  scheduled = true;
  const wait = Math.max(0, 100 - (performance.now() - lastRender)); // at most ten renders a second
  setTimeout(() => requestAnimationFrame(() => {
    scheduled = false;
    lastRender = performance.now();
    render();
  }), wait);
}

function vesselNames() {
  if (app.mode === "replay") return player.detail ? player.detail.vessels : [];
  return [...new Set([...app.fleet.keys(), ...app.live.names()])].sort();
}

function updatePicker() {
  const pick = $("vessel-picker");
  const names = vesselNames();
  if (app.selected && !names.includes(app.selected) && app.mode === "live") names.push(app.selected);
  const current = [...pick.options].map((o) => o.value).join("|");
  if (current !== names.join("|")) {
    pick.replaceChildren(...names.map((n) => new Option(n, n)));
  }
  if (!names.includes(app.selected) && names.length) selectVessel(names[0]);
  pick.value = app.selected;
}

function selectVessel(name) {
  if (name === app.selected) return;
  app.selected = name;
  app.metrics = null;
  sessionStorage.setItem(VESSEL_KEY, name);
  if (app.mode === "live") pollMetrics();
  schedule();
}

function currentPlan(v, mission) {
  if (app.mode === "live") return app.fleet.get(app.selected)?.active_mission ?? null;
  const missions = player.detail?.missions || [];
  const id = mission?.mission_id;
  return missions.find((m) => m.mission_id === id) || (missions.length === 1 ? missions[0] : null)
    || missions.find((m) => m.mission_id === "") || null;
}

function render() {
  updatePicker();
  const t = now();
  const v = store().vessels.get(app.selected) || null;
  const view = app.mode === "live" ? app.fleet.get(app.selected) : null;
  const staleAll = app.mode === "live" && !(app.linkUp && app.apiUp);
  const stale = (kind) => staleAll || !v || v.stale(kind, t);
  const msg = (kind) => (v ? v.message(kind) : null);
  const state = msg("state"), mission = msg("mission"), vehicle = msg("vehicle"), solve = msg("solve");

  // Vehicle.
  if (app.mode === "live") {
    setText("v-link", vehicle ? (vehicle.link_ok ? "up" : "DOWN") : "–", vehicle ? (vehicle.link_ok ? "good" : "bad") : "");
    setText("v-armed", vehicle ? (vehicle.armed ? "armed" : "disarmed") : "–", vehicle?.armed ? "warn" : "");
    setText("v-mode", vehicle?.mode ?? "–");
    const holdWhy = vehicle?.hold_reason ? `${HOLD_REASONS[vehicle.hold_reason] || vehicle.hold_reason}`
      + (vehicle.hold_reason_detail ? `: ${vehicle.hold_reason_detail}` : "") : "";
    setText("v-failsafe", vehicle ? vehicle.failsafe || holdWhy || "none" : "–", vehicle?.failsafe || holdWhy ? "bad" : "");
    const services = liveServices(app.selected);
    setText("v-services", services.join(", ") || "–");
    renderRecording(services);
    setText("v-last-command", app.lastCommands.get(app.selected) || "–");
    syncModeBox(vehicle);
    markStale("battery", stale("battery") && Boolean(msg("battery")));
    document.querySelector(".sim-only").hidden = !view?.simulated;
    markStale("vehicle", stale("vehicle"));
  } else {
    renderRecording([]);
  }

  renderVesselFacts(msg("battery"), vehicle, msg("gnss"), state);

  // Mission progress.
  const legs = mission ? Math.max(mission.waypoint_count - 1, 0) : 0;
  setText("p-state", mission?.state ?? "–", mission?.state === "complete" ? "good" : mission?.state === "aborted" ? "bad" : "");
  const why = mission && mission.state !== "idle" && mission.state !== "active" ? mission.reason || "" : mission?.reason || "";
  setText("p-reason", why || "–", !why ? "" : mission.state === "aborted" ? "bad" : "warn");
  // The estimator's motion fault (StateEstimate.motion_fault): the vessel does not do what it is told;
  // else a thruster that gives less than commanded (thrust_short_side): the boat goes on, on more energy.
  const short = state?.thrust_short_side;
  const shortPct = Number.isFinite(state?.thrust_short_frac) ? `${Math.round(100 * state.thrust_short_frac)} % ` : "";
  setText("p-motion", !state ? "–" : state.motion_fault
    ? `FAULT ${state.motion_fault}${state.motion_fault_detail ? ` — ${state.motion_fault_detail}` : ""}`
    : short ? `${short.toUpperCase()} THRUSTER ${shortPct}SHORT of its command` : "no fault",
    state?.motion_fault ? "bad" : short ? "warn" : "");
  setText("p-id", mission?.mission_id || "–");
  setText("p-leg", mission && mission.state !== "idle" ? `${mission.active_leg} / ${legs}` : "–");
  setText("p-dist", fmt(mission?.distance_to_waypoint_m, 1, "m"));
  setText("p-xte", fmt(mission?.cross_track_m, 2, "m"));
  setText("p-eta", eta(mission, currentPlan(v, mission), state, msg("gnss")));
  setText("p-dist-est", state ? `surge ${fmt(state.tau_d_surge_n, 2)} N, sway ${fmt(state.tau_d_sway_n, 2)} N, yaw ${fmt(state.tau_d_yaw_nm, 2)} N·m` : "–");
  let frac = 0;
  if (mission?.state === "complete") frac = 1;
  else if (mission && legs > 0) frac = Math.max(0, mission.active_leg - 1) / legs;
  $("p-bar").style.width = `${(frac * 100).toFixed(0)}%`;
  markStale("mission", stale("mission"));
  renderMetrics(mission);
  const budget = v ? v.budget() : null;
  renderEnergy(budget, mission, stale("energy"));

  // Map.
  const plan = currentPlan(v, mission);
  map.tilesUrl = app.config.tiles_url;
  const others = [];
  for (const [name, o] of store().vessels) {
    if (name === app.selected) continue;
    const s = o.message("state"), sv = o.message("solve");
    others.push({ name, state: s, colour: vesselColour(name), trail: o.trail, stale: o.stale("state", t),
      pred: sv ? sv.predicted_x_m.map((x, i) => [x, sv.predicted_y_m[i]]) : [],
      plan: app.mode === "live" ? app.fleet.get(name)?.active_mission ?? null : null });
  }
  map.setModel({
    geo: app.mode === "live" ? view?.geo ?? null : player.detail?.geo?.[app.selected] ?? null,
    plan, activeLeg: mission && mission.state !== "idle" ? mission.active_leg : -1, area: msg("area"),
    trail: v?.trail || [], state, solve, others, budget, name: app.selected, colour: vesselColour(app.selected),
    stale: { state: stale("state"), solve: stale("solve"), energy: stale("energy") },
  });
  $("map-stale").hidden = !(stale("state") && state);
  if (plan && app.lastMissionId !== plan.mission_id && app.mode === "live" && !app.draft.length) {
    app.lastMissionId = plan.mission_id;
    map.fit();
  }

  renderFleet(t);

  // Plots.
  const cursor = null;
  const s = v?.series;
  plots.thrust.draw(s?.thrust, { stale: stale("thrust"), cursorT: cursor });
  plots.speed.draw(s?.speed, { stale: stale("state"), cursorT: cursor });
  plots.xte.draw(s?.xte, { stale: stale("mission"), cursorT: cursor, empty: "no mission yet" });
  plots.energy.draw(v?.energySeries(), { stale: stale("mission"), cursorT: cursor, empty: "no mission yet" });
  if (app.mode === "replay") updateTransport();
}

/** Health tokens that are not the vessel's own work: the ground station's and the launcher's. */
const NOT_THE_VESSELS = new Set(["groundstation", "launcher"]);

/** Whether a health token stands for the vessel's own work: not the page's or the launcher's, nor
 *  a shore computer's own process (its recorder, router, page: app.config.shore_health_prefix),
 *  which the shore hears beside the boat's and which must not stand for them. */
function vesselsOwn(service) {
  const shore = app.config?.shore_health_prefix;
  return !NOT_THE_VESSELS.has(service) && !(shore && service.startsWith(shore));
}

/** A vessel's live health tokens (GET /api/vessels, else its live frames); none in replay. */
function liveServices(name) {
  if (app.mode !== "live") return [];
  return app.fleet.get(name)?.services || store().vessels.get(name)?.services || [];
}

/** Unrecorded: the vessel's services run (vesselsOwn) and none of them is the recorder. The
 *  launcher keeps a real-time run flying when its recorder fails for good, so nothing the vessel
 *  does is recorded until the recorder's token is back. A shore's own recorder does not count: the
 *  boat's recording is the whole one. The one rule for the header's alarm and the fleet table's
 *  marks. */
function unrecorded(services) {
  return services.some(vesselsOwn) && !services.includes("recorder");
}

/** NOT RECORDING in the header while the selected vessel is unrecorded. The header's live region
 *  says it to a screen reader. */
function renderRecording(services) {
  const on = unrecorded(services);
  const el = $("recording-status");
  const text = on ? "NOT RECORDING" : "";
  const title = on ? `${app.selected}'s services run, but no recorder's health token is present: `
    + "nothing it does is being written to a recording" : "";
  if (el.textContent !== text) el.textContent = text; // only a change is said again
  el.className = on ? "alarm-badge" : "";
  el.title = title;
}

/** Each vessel's colour on the map and in the fleet table: by its place in the sorted names, so
 *  every tab and a reload give a vessel the same one. Dark enough for 4.5:1 text on white. */
const VESSEL_COLOURS = ["#0b3d62", "#8a2be2", "#00695c", "#ad1457", "#7a4a00", "#283593", "#4e6b00", "#6d4c41"];
function vesselColour(name) {
  const i = vesselNames().indexOf(name);
  return VESSEL_COLOURS[(i < 0 ? 0 : i) % VESSEL_COLOURS.length];
}

/** The fleet overview: one row per vessel (state, leg, battery, link); its name picks it, and an
 *  unrecorded vessel (the header's rule, live only) has NOT RECORDING by its name. Shown for two
 *  vessels or more, or while the ground station says it dropped some (live only). */
function renderFleet(t) {
  const names = vesselNames();
  const notice = renderFleetNotice($("fleet-notice"), app.mode === "live" ? app.fleetCounts : null);
  $("fleet-panel").hidden = names.length < 2 && !notice;
  $("fleet-table").hidden = !names.length;
  const rows = names.map((name) => {
    const o = store().vessels.get(name);
    const mission = o?.message("mission"), vehicle = o?.message("vehicle"), battery = o?.message("battery");
    const frac = battery?.remaining_frac ?? vehicle?.battery_remaining_frac;
    const legs = mission ? Math.max(mission.waypoint_count - 1, 0) : 0;
    const stale = !o || o.stale("state", t);
    return [name, unrecorded(liveServices(name)), mission?.state ?? "–",
      mission && mission.state !== "idle" ? `${mission.active_leg} / ${legs}` : "–",
      Number.isFinite(frac) ? `${(frac * 100).toFixed(0)} %` : "–",
      vehicle ? (vehicle.link_ok && !stale ? "up" : stale ? "stale" : "DOWN") : "–"];
  });
  const body = $("fleet-table").tBodies[0];
  const key = JSON.stringify([rows, app.selected]);
  if (body.dataset.key === key) return;
  body.dataset.key = key;
  body.replaceChildren(...rows.map(([name, notRecording, ...cells]) => {
    const tr = document.createElement("tr");
    tr.dataset.vessel = name;
    if (name === app.selected) tr.className = "selected";
    const th = document.createElement("th");
    th.scope = "row";
    const b = document.createElement("button");
    b.className = "ghost pick";
    b.style.borderLeft = `6px solid ${vesselColour(name)}`;
    b.textContent = name;
    b.setAttribute("aria-pressed", String(name === app.selected));
    b.onclick = () => selectVessel(name);
    th.append(b);
    if (notRecording) {
      const mark = document.createElement("span");
      mark.className = "alarm-badge compact not-recording";
      mark.textContent = "NOT RECORDING";
      mark.title = `${name}'s services run, but no recorder's health token is present`;
      th.append(" ", mark);
    }
    tr.append(th, ...cells.map((c) => Object.assign(document.createElement("td"), { textContent: c })));
    return tr;
  }));
}

const FIX_TYPES = ["no GPS", "no fix", "2D fix", "3D fix", "DGPS", "RTK float", "RTK fixed", "static", "PPP"];
const BAD_LEVELS = new Set(["critical", "emergency", "failed", "unhealthy"]);

/** Speed over ground [m/s]: the GNSS's velocity when it gives one, else the estimate's. */
function speedOverGround(state, gnss) {
  if (gnss && Number.isFinite(gnss.vel_n_mps) && Number.isFinite(gnss.vel_e_mps)) {
    return Math.hypot(gnss.vel_n_mps, gnss.vel_e_mps);
  }
  return state ? Math.hypot(state.u_mps, state.v_mps) : null;
}

/** The vehicle as an operator reads it: battery, energy left, GNSS, position, heading, speed and
 *  the time of the latest state (UTC live; the run's time in a simulation that starts at 0). */
function renderVesselFacts(battery, vehicle, gnss, state) {
  const frac = battery?.remaining_frac ?? vehicle?.battery_remaining_frac;
  const volts = battery?.voltage_v ?? vehicle?.battery_voltage_v;
  const level = battery?.autopilot_level;
  const parts = [];
  if (Number.isFinite(frac)) parts.push(`${(frac * 100).toFixed(0)} %`);
  if (Number.isFinite(volts)) parts.push(`${volts.toFixed(2)} V`);
  if (level && level !== "ok") parts.push(`autopilot: ${level}`);
  const batteryCls = BAD_LEVELS.has(level) || (Number.isFinite(frac) && frac < 0.1) ? "bad"
    : level === "low" || (Number.isFinite(frac) && frac < 0.25) ? "warn" : "";
  setText("v-battery", parts.join(" · ") || "–", batteryCls);
  const left = battery?.remaining_j;
  setText("v-energy-left", Number.isFinite(left)
    ? `${fmtEnergy(left)}${Number.isFinite(battery.reserve_j) ? `, reserve ${fmtEnergy(battery.reserve_j)}` : ""}` : "–");
  if (gnss) {
    const g = [FIX_TYPES[gnss.fix_type] ?? `fix ${gnss.fix_type}`];
    if (Number.isFinite(gnss.satellites)) g.push(`${gnss.satellites} sats`);
    if (Number.isFinite(gnss.horizontal_std_m)) g.push(`±${gnss.horizontal_std_m.toFixed(1)} m`);
    setText("v-gnss", g.join(" · "), gnss.fix_type < 3 ? "bad" : "");
  } else {
    setText("v-gnss", "–", "");
  }
  if (state) {
    const ll = map.latLon(state.x_m, state.y_m);
    setText("v-position", `N ${state.x_m.toFixed(1)} m, E ${state.y_m.toFixed(1)} m`
      + (ll ? ` (${ll[0].toFixed(6)}°, ${ll[1].toFixed(6)}°)` : ""));
    const deg = (((state.psi_rad * 180) / Math.PI) % 360 + 360) % 360;
    setText("v-heading", `${deg.toFixed(0)}°`);
    const sog = speedOverGround(state, gnss);
    setText("v-speed", `${fmt(sog, 2, "m/s")} over ground`);
    // Real time stamps with the Unix clock; a simulation in lockstep from 0.
    const stampS = state.stamp_ns / 1e9;
    setText("v-time", stampS > 1e9 ? `${new Date(stampS * 1000).toISOString().slice(11, 19)} UTC`
      : `t = ${stampS.toFixed(1)} s (simulated)`);
  } else {
    for (const id of ["v-position", "v-heading", "v-speed", "v-time"]) setText(id, "–");
  }
}

/** Time to the last waypoint at the current speed over ground: the rest of the active leg plus the
 *  legs after it. "–" when not flying or too slow to say. */
function eta(mission, plan, state, gnss) {
  if (!mission || mission.state !== "active" || !plan?.waypoints_m?.length) return "–";
  const wps = plan.waypoints_m;
  let rest = Number.isFinite(mission.distance_to_waypoint_m) ? mission.distance_to_waypoint_m : 0;
  for (let i = Math.max(mission.active_leg, 0); i + 1 < wps.length; i++) {
    rest += Math.hypot(wps[i + 1][0] - wps[i][0], wps[i + 1][1] - wps[i][1]);
  }
  const sog = speedOverGround(state, gnss);
  if (!Number.isFinite(sog) || sog < 0.05) return `${rest.toFixed(0)} m to go`;
  return `${fmtDuration(rest / sog)} (${rest.toFixed(0)} m at ${sog.toFixed(2)} m/s)`;
}

/** The mode box shows the autopilot's real mode until the operator types in it: "Set mode" then
 *  sends what is shown, never a stale default (it used to say HOLD whatever the mode was). */
let modeEdited = false;
$("mode-select").addEventListener("input", () => { modeEdited = true; });
function syncModeBox(vehicle) {
  const box = $("mode-select");
  if (!vehicle?.mode || modeEdited || document.activeElement === box) return;
  if (box.value !== vehicle.mode) box.value = vehicle.mode;
}

function renderMetrics(mission) {
  let m = null, source = "";
  if (app.mode === "live") {
    m = app.metrics && mission && app.metrics.mission_id === mission.mission_id ? app.metrics : null;
    source = m ? `From nav/state and ctrl/thrust as heard here, mission ${m.mission_id} (${m.state_samples} states)`
      + (m.energy_j === null ? "; no energy: the vessel's alpha is not known here" : "")
      : mission && mission.state !== "idle" ? "The ground station does not know this mission's waypoints." : "";
  } else if (player.detail?.report?.metrics) {
    m = player.detail.report.metrics;
    source = `From the run's report (${m.energy_source || "report"}), whole run`;
  } else if (player.detail) {
    source = "This recording's run has no report/metrics.json.";
  }
  setText("m-travel-time", fmt(m?.travel_time_s, 1, "s"));
  setText("m-energy", fmtEnergy(m?.energy_j));
  setText("m-xte-avg", fmt(m?.avg_cross_track_m, 3, "m"));
  setText("m-xte-max", fmt(m?.max_cross_track_m, 2, "m"));
  setText("metrics-source", source);
}

/** What took the vessel from Seaway (VehicleStatus.hold_reason), in the operator's words. */
const HOLD_REASONS = {
  gcs_mode_change: "mode changed by another ground station", battery: "battery failsafe",
  fence: "fence breach", radio_loss: "radio (RC) lost", gcs_link_loss: "ground-station link lost",
  other: "autopilot failsafe",
};

const DECISIONS = { warn: ["LOW ENERGY", "warn"], return: ["RETURNING HOME", "bad"], hold: ["HOLDING", "bad"] };

/** An energy [J] with its band, "6.79 kJ (1.89 Wh), 6.50–7.10 kJ". */
function withBand(j, low, high) {
  if (!Number.isFinite(j)) return "–";
  const band = Number.isFinite(low) && Number.isFinite(high) && (low !== j || high !== j);
  if (!band) return fmtEnergy(j);
  const [scale, unit] = Math.abs(j) >= 1e6 ? [1e6, "MJ"] : Math.abs(j) >= 1e3 ? [1e3, "kJ"] : [1, "J"];
  const digits = scale === 1 ? 0 : 2;
  return `${fmtEnergy(j)}, ${(low / scale).toFixed(digits)}–${(high / scale).toFixed(digits)} ${unit}`;
}

/** The energy budget's figures (mission/energy; the status's before any), and its decision shown
 *  prominently once taken: on the map and at the top of the energy panel. */
function renderEnergy(b, mission, isStale) {
  setText("e-source", b ? "mission/energy" : mission?.energy_used_j != null ? "mission status" : "");
  // The controller's count either way; the status's goes on to the completion (the budget's stops
  // with the last active period).
  setText("m-energy-used", fmtEnergy(mission?.energy_used_j ?? b?.energy_used_j));
  setText("e-finish", b ? withBand(b.energy_to_go_j, b.energy_to_go_low_j, b.energy_to_go_high_j)
    : fmtEnergy(mission?.energy_to_go_j));
  setText("e-home", b ? withBand(b.energy_to_home_j, b.energy_to_home_low_j, b.energy_to_home_high_j) : "–");
  setText("e-battery", b && b.battery_remaining_j == null ? "not reported" : fmtEnergy(b?.battery_remaining_j));
  setText("e-reserve", fmtEnergy(b?.reserve_j));
  setText("e-margin", fmtEnergy(b?.margin_j), Number.isFinite(b?.margin_j) && b.margin_j <= 0 ? "bad" : "");
  let pnr = "–";
  if (b && Number.isFinite(b.no_return_along_m)) {
    const ll = map.latLon(b.no_return_x_m, b.no_return_y_m);
    pnr = `in ${b.no_return_along_m.toFixed(1)} m, at N ${b.no_return_x_m.toFixed(1)} E ${b.no_return_y_m.toFixed(1)} m`
      + (ll ? ` (${ll[0].toFixed(6)}°, ${ll[1].toFixed(6)}°)` : "");
  } else if (b && b.returning) {
    pnr = "returning home";
  } else if (b && Number.isFinite(b.margin_j) && b.margin_j <= 0) {
    pnr = "reached: the margin is gone";
  } else if (b && b.battery_remaining_j != null) {
    pnr = "not before the end";
  } else if (b) {
    pnr = "no battery report";
  }
  setText("e-pnr", pnr);
  let decided = b && b.decision !== "none" ? DECISIONS[b.decision] : null;
  if (decided && b.decision === "return" && b.returning && mission?.state === "complete") {
    decided = ["RETURNED HOME", "warn"];
  }
  setText("e-decision", b ? (decided ? decided[0] : "none") + (b.policy ? ` (policy: ${b.policy})` : "") : "–",
    decided ? decided[1] : "");
  for (const id of ["map-decision", "e-decision-banner"]) {
    const el = $(id);
    el.hidden = !decided;
    if (!decided) continue;
    el.textContent = `${decided[0]}${b.reason ? ` — ${b.reason}` : ""}`;
    el.classList.toggle("warn", decided[1] === "warn");
  }
  // Budgets come while the mission is active only: after it they are the last, not stale news.
  markStale("energy", Boolean(b) && isStale && mission?.state === "active");
}

/** Operator or read-only: whether this tab holds the operator token (commands need it). */
function updateAccessPill() {
  const pill = $("access");
  const operator = Boolean(getToken());
  pill.textContent = operator ? "operator" : "read-only";
  pill.className = `pill ${operator ? "ok" : "readonly"}`;
}
setInterval(updateAccessPill, 1000);
updateAccessPill();
$("access").addEventListener("click", () => askToken());

function updateLinkPill() {
  const pill = $("link");
  if (app.mode === "replay") {
    pill.textContent = "replay";
    pill.className = "pill";
    return;
  }
  const up = app.linkUp && app.apiUp;
  pill.textContent = up ? "live" : "link lost";
  pill.className = `pill ${up ? "ok" : "bad"}`;
}

// -- polling --------------------------------------------------------------------------------------

async function pollFleet() {
  if (app.mode === "live") {
    try {
      const fleet = await get("/api/vessels");
      app.fleet = new Map(fleet.vessels.map((v) => [v.vessel, v]));
      app.fleetCounts = { refused: fleet.vessels_refused, forgotten: fleet.vessels_forgotten,
        max: fleet.max_vessels };
      if (!app.apiUp) stickySay("api", false);
      app.apiUp = true;
    } catch (err) {
      app.apiUp = false;
      const why = err.status ? `it answers HTTP ${err.status}: ${err.message}` : err.message;
      stickySay("api", true, err.status ? `The ground station's fleet view fails (${why})`
        : why.charAt(0).toUpperCase() + why.slice(1), "error");
    }
    updateLinkPill();
    schedule();
  }
  setTimeout(pollFleet, POLL_MS);
}

async function pollMetrics() {
  const v = app.live.vessels.get(app.selected);
  const mission = v?.message("mission");
  if (app.mode === "live" && app.selected && mission && mission.state !== "idle") {
    try {
      app.metrics = await get(`/api/vessels/${encodeURIComponent(app.selected)}/metrics`);
      schedule();
    } catch {
      /* the fleet poll reports an unreachable ground station */
    }
  }
}
setInterval(pollMetrics, METRICS_MS);
setInterval(() => schedule(), 500); // ages grow without news: staleness shows up by itself

// -- commands -------------------------------------------------------------------------------------

/** Ask for the token in the dialog; resolves true if one was given. */
function askToken(why) {
  const dlg = $("token-dialog");
  if (why) dlg.querySelector("p").dataset.why = why;
  $("token-input").value = getToken();
  dlg.showModal();
  return new Promise((resolve) => {
    dlg.addEventListener("close", () => {
      if (dlg.returnValue === "save") setToken($("token-input").value);
      if (dlg.returnValue === "forget") setToken("");
      resolve(Boolean(getToken()) && dlg.returnValue === "save");
    }, { once: true });
  });
}

/** Run one command: token first, then the request; say what the vessel answered. */
async function run(label, path, body) {
  if (!app.selected) {
    say(`${label}: no vessel selected`, "error");
    return null;
  }
  if (!getToken() && !(await askToken())) {
    say(`${label}: not sent — commands need the operator token`, "warn");
    return null;
  }
  try {
    const reply = await command(path, body);
    say(`${label}: accepted${reply.reason ? ` — ${reply.reason}` : ""}`, "ok");
    return reply;
  } catch (err) {
    if (!(err instanceof ApiError)) throw err;
    if (err.status === 401 || err.status === 403) {
      if (err.status === 403) setToken("");
      say(`${label}: ${err.status === 403 ? "wrong operator token" : "the operator token is needed"} — enter it and try again`, "error");
      askToken();
    } else if (err.status === 409) {
      say(`${label} refused by ${app.selected}: ${err.message}`, "error");
    } else if (err.status === 0) {
      say(`${label}: ${err.message}`, "error");
    } else {
      say(`${label} failed (HTTP ${err.status}): ${err.message}`, "error");
    }
    return null;
  }
}

const vpath = (suffix) => `/api/vessels/${encodeURIComponent(app.selected)}/${suffix}`;

/** Ask before an action that moves or stops the vessel (a misclick on a boat is not undone). */
const sure = (what) => confirm(`${what} — ${app.selected}?`);

const COMMANDS = {
  arm: () => sure("Arm: the thrusters may turn") && run("Arm", vpath("arm"), { force: false }),
  disarm: () => sure("Disarm: the thrusters stop") && run("Disarm", vpath("disarm"), { force: false }),
  mode: () => sure(`Set the autopilot's mode to ${$("mode-select").value.trim()}`)
    && run(`Mode ${$("mode-select").value}`, vpath("mode"), { mode: $("mode-select").value.trim() }),
  scenario: () => sure(`Load scenario ${$("scenario-name").value.trim()} (the simulated vessel moves)`)
    && run(`Scenario ${$("scenario-name").value}`, vpath("scenario"), { name: $("scenario-name").value.trim() }),
  restart: () => sure("Restart the simulation") && run("Restart the simulation", vpath("scenario"), { restart: true }),
  pause: () => sure("Pause the mission (the vessel holds)") && run("Pause", vpath("mission/pause")),
  resume: () => sure("Resume the mission (the vessel moves)") && run("Resume", vpath("mission/resume")),
  abort: () => sure("Abort the mission") && run("Abort", vpath("mission/abort")),
  start: () => sure("Start the last mission again from P0 (the vessel moves)") && run("Start again", vpath("mission/start")),
};
// One request per click: the button stays disabled until the vessel answered (a double click on a
// command used to send it twice).
for (const b of document.querySelectorAll("[data-cmd]")) {
  b.addEventListener("click", async () => {
    if (b.disabled) return;
    b.disabled = true;
    try {
      await COMMANDS[b.dataset.cmd]();
    } finally {
      b.disabled = false;
      if (b.dataset.cmd === "mode") modeEdited = false;
    }
  });
}

// -- the mission editor ---------------------------------------------------------------------------

function renderDraftTable() {
  const body = $("wp-table").tBodies[0];
  body.replaceChildren(...app.draft.map((p, i) => {
    const tr = document.createElement("tr");
    tr.innerHTML = `<td>${i}</td><td><input type="number" step="0.1" aria-label="north ${i}"></td>`
      + `<td><input type="number" step="0.1" aria-label="east ${i}"></td>`
      + `<td><input type="number" step="0.1" min="0.1" max="50" placeholder="–" aria-label="speed ${i} in metres per second"></td>`
      + `<td><button title="remove" aria-label="remove waypoint ${i}">×</button></td>`;
    const [n, e, v] = tr.querySelectorAll("input");
    n.value = p.x_m.toFixed(2);
    e.value = p.y_m.toFixed(2);
    v.value = Number.isFinite(p.speed_mps) ? String(p.speed_mps) : "";
    const edit = () => {
      // Moved in metres: its lat/lon no longer holds; the speed stays the waypoint's.
      const speed = v.value === "" ? undefined : Number(v.value);
      if (speed !== undefined && !(speed > 0 && speed <= 50)) {
        say(`Waypoint ${i}: speed ${v.value} m/s is not in (0, 50]`, "warn");
        v.value = Number.isFinite(p.speed_mps) ? String(p.speed_mps) : "";
        return;
      }
      const moved = Number(n.value) !== p.x_m || Number(e.value) !== p.y_m;
      app.draft[i] = moved ? { x_m: Number(n.value), y_m: Number(e.value) } : { ...p };
      if (speed === undefined) delete app.draft[i].speed_mps;
      else app.draft[i].speed_mps = speed;
      map.setDraft(app.draft, coa());
    };
    n.onchange = edit;
    e.onchange = edit;
    v.onchange = edit;
    tr.querySelector("button").onclick = () => {
      app.draft.splice(i, 1);
      renderDraftTable();
      map.setDraft(app.draft, coa());
    };
    return tr;
  }));
  setText("draft-count", app.draft.length ? `${app.draft.length} waypoint(s)` : "click “Add waypoints”, then the map");
}

function draftBody() {
  const id = $("mission-id").value.trim()
    || `gs-${new Date().toISOString().replace(/[-:]/g, "").replace("T", "-").slice(0, 15)}`;
  return {
    mission_id: id,
    waypoints: app.draft.map((p) => (p.lat_deg !== undefined && p.lon_deg !== undefined
      ? { lat_deg: p.lat_deg, lon_deg: p.lon_deg } : { x_m: p.x_m, y_m: p.y_m })),
    coa_radius_m: coa(),
    task_power_w: Number($("task-power").value),
    controller: $("controller").value,
    predict_disturbance: $("predict").checked,
    // One cruise hint per mission: the controller has no per-waypoint speed.
    ...(speedHint() !== undefined ? { speed_hint_mps: speedHint() } : {}),
  };
}

/** The mission's speed hint [m/s]: the first waypoint speed given in the editor, if any. */
const speedHint = () => app.draft.find((p) => Number.isFinite(p.speed_mps))?.speed_mps;

/** The controller's own check of the draft (POST /api/missions/check, nothing sent), shown under
 *  the editor; the check's answer, or null when the ground station could not check. */
async function checkDraft(body) {
  const vessel = app.selected ? `?vessel=${encodeURIComponent(app.selected)}` : "";
  let out;
  try {
    out = await request("POST", `/api/missions/check${vessel}`, { body });
  } catch (err) {
    say(`Check: ${err.message}`, "error");
    return null;
  }
  $("check-result").hidden = false;
  const ok = out.verdict === "ok";
  setText("check-verdict", ok ? `Check: ok${out.live ? " (against the vessel's live state)" : " (at the desk)"}`
    : "Check: REFUSED", ok ? "good" : "bad");
  setText("check-length", fmt(out.path_length_m, 0, "m"));
  setText("check-time", out.predicted_time_s == null ? "–"
    : `${fmtDuration(out.predicted_time_s)}${Number.isFinite(out.cruise_speed_mps) ? ` at ${out.cruise_speed_mps.toFixed(2)} m/s` : ""}`);
  setText("check-energy", fmtEnergy(out.energy_mission_j));
  setText("check-home", fmtEnergy(out.energy_home_from_last_j));
  setText("check-battery", out.battery_after_j == null ? "battery not known"
    : `${fmtEnergy(out.battery_after_j)}${out.reserve_j != null ? ` (reserve ${fmtEnergy(out.reserve_j)})` : ""}`,
  out.battery_after_j != null && out.reserve_j != null && out.battery_after_j < out.reserve_j ? "bad" : "");
  setText("check-area", out.area, out.area === "refused" ? "bad" : "");
  $("check-reasons").replaceChildren(...[...out.reasons, ...out.notes].map((text) => {
    const li = document.createElement("li");
    li.textContent = text;
    return li;
  }));
  return out;
}

$("check-mission").onclick = async () => {
  if (app.draft.length < 2) {
    say("A mission needs at least two waypoints: click “Add waypoints”, then the map.", "warn");
    return;
  }
  const button = $("check-mission");
  if (button.disabled) return;
  button.disabled = true;
  try {
    await checkDraft(draftBody());
  } finally {
    button.disabled = false;
  }
};

$("send-mission").onclick = async () => {
  if (app.draft.length < 2) {
    say("A mission needs at least two waypoints: click “Add waypoints”, then the map.", "warn");
    return;
  }
  const button = $("send-mission");
  if (button.disabled) return;
  const body = draftBody();
  button.disabled = true; // one request per click, as the other commands
  let reply;
  try {
    // The check first, on the page: a mission it refuses goes only if the operator forces it.
    const checked = await checkDraft(body);
    if (checked && checked.verdict !== "ok") {
      if (!sure(`The check refuses mission ${body.mission_id}: ${checked.reasons.join("; ")}. Send it anyway (forced)`)) return;
      body.force = true;
    } else if (!sure(`Send mission ${body.mission_id} (${body.waypoints.length} waypoints; it starts at once)`)) {
      return;
    }
    reply = await run(`Mission ${body.mission_id}`, vpath("mission"), body);
  } finally {
    button.disabled = false;
  }
  if (reply) {
    $("mission-id").value = "";
    app.draft = [];
    renderDraftTable();
    map.setDraft(app.draft, coa());
    setAdding(false);
    setTimeout(pollFleet, 200);
  }
};
$("clear-draft").onclick = () => {
  app.draft = [];
  renderDraftTable();
  map.setDraft(app.draft, coa());
};
$("draft-from-active").onclick = () => {
  const plan = app.fleet.get(app.selected)?.active_mission;
  if (!plan) {
    say("The ground station does not know the waypoints of the mission this vessel flies.", "warn");
    return;
  }
  app.draft = plan.waypoints_m.map(([x, y]) => ({ x_m: x, y_m: y }));
  $("coa").value = plan.coa_radius_m;
  $("task-power").value = plan.task_power_w;
  renderDraftTable();
  map.setDraft(app.draft, coa());
};
$("coa").oninput = () => map.setDraft(app.draft, coa());

function setAdding(on) {
  map.adding = on;
  $("add-mode").setAttribute("aria-pressed", String(on));
  $("map").classList.toggle("adding", on);
}
$("add-mode").onclick = () => setAdding(!map.adding);
$("fit").onclick = () => map.fit();
$("follow").onchange = (ev) => { map.follow = ev.target.checked; map.invalidate(); };

$("import-file").onchange = async (ev) => {
  const file = ev.target.files[0];
  ev.target.value = "";
  if (!file) return;
  let doc;
  try {
    doc = JSON.parse(await file.text());
  } catch (err) {
    say(`${file.name} is not JSON: ${err.message}`, "error");
    return;
  }
  try {
    const q = app.selected ? `?vessel=${encodeURIComponent(app.selected)}` : "";
    const parsed = await request("POST", `/api/missions/parse${q}`, { body: { document: doc, skip_unsupported: true } });
    if (!parsed.waypoints_m) {
      say(`${file.name}: read, but no NED origin is known for ${app.selected || "any vessel"} to place it on the map`, "error");
      return;
    }
    // Keep the file's latitude/longitude (sent as they are); metres are for drawing and editing.
    app.draft = parsed.waypoints_m.map((p, i) => ({ ...p, ...parsed.waypoints[i],
      ...(Number.isFinite(parsed.speeds_mps?.[i]) ? { speed_mps: parsed.speeds_mps[i] } : {}) }));
    if (!parsed.speeds_mps?.length && parsed.hints?.speed_hint_mps && app.draft.length) {
      app.draft[0].speed_mps = parsed.hints.speed_hint_mps;
    }
    if (parsed.hints?.coa_radius_m) $("coa").value = parsed.hints.coa_radius_m;
    if (parsed.hints?.task_power_w !== undefined) $("task-power").value = parsed.hints.task_power_w;
    renderDraftTable();
    map.setDraft(app.draft, coa());
    map.fit();
    say(`${file.name}: ${parsed.waypoints.length} waypoints (${parsed.source})`
      + (parsed.skipped.length ? `; left out: ${parsed.skipped.join(", ")}` : ""), "ok");
  } catch (err) {
    say(`${file.name}: ${err.message}`, "error");
  }
};

async function exportDraft(format) {
  const useDraft = app.draft.length >= 2;
  const q = `format=${format}${app.selected ? `&vessel=${encodeURIComponent(app.selected)}` : ""}`;
  const url = useDraft ? `/api/missions/export?${q}` : `${vpath("mission/export")}?format=${format}`;
  const resp = await fetch(url, useDraft
    ? { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(draftBody()) }
    : {});
  if (!resp.ok) {
    let reason = `HTTP ${resp.status}`;
    try { reason = (await resp.json()).detail; } catch { /* keep the status */ }
    say(`Export: ${typeof reason === "string" ? reason : JSON.stringify(reason)}`, "error");
    return;
  }
  const name = /filename="([^"]+)"/.exec(resp.headers.get("Content-Disposition") || "")?.[1] || `mission.${format}`;
  const a = document.createElement("a");
  a.href = URL.createObjectURL(await resp.blob());
  a.download = name;
  a.click();
  setTimeout(() => URL.revokeObjectURL(a.href), 1000);
}
$("export-plan").onclick = () => exportDraft("plan");
$("export-geojson").onclick = () => exportDraft("geojson");

// -- replay ---------------------------------------------------------------------------------------

async function loadRecordings(select) {
  try {
    const list = await get("/api/recordings");
    setText("runs-dir", list.runs_dir);
    const sel = $("recording-select");
    sel.replaceChildren(...list.recordings.map((r) => new Option(
      `${r.name}  (${(r.size_bytes / 1e6).toFixed(1)} MB${r.has_report ? ", report" : ""})`, r.id)));
    if (!list.recordings.length) sel.replaceChildren(new Option("no recordings in the runs folder", ""));
    if (select) sel.value = select;
  } catch (err) {
    say(`Recordings: ${err.message}`, "error");
  }
}

async function openRecording(id) {
  if (!id) return;
  setText("recording-info", "opening…");
  try {
    const done = player.open(id);
    await waitFor(() => player.detail);
    const d = player.detail;
    setText("recording-info", `${d.name}: ${d.duration_s.toFixed(1)} s, ${d.vessels.join(", ") || "no vessel"}, `
      + `${d.message_count} messages, ${d.frame_count} frames`
      + (d.notes.length ? ` — ${d.notes.join("; ")}` : ""));
    if (d.vessels.length && !d.vessels.includes(app.selected)) selectVessel(d.vessels[0]);
    setTimeout(() => map.fit(), 300);
    await done;
    // A damaged chunk is found only as the frames are cut, after the detail above was shown.
    if (player.error && player.detail === d) {
      setText("recording-info", `${$("recording-info").textContent} — ${player.error}`);
      say(player.error, "error");
    }
  } catch (err) {
    setText("recording-info", "");
    say(`Recording ${id}: ${err.message}`, "error");
  }
}

function waitFor(pred) {
  return new Promise((resolve) => {
    const check = () => (pred() ? resolve() : setTimeout(check, 30));
    check();
  });
}

function updateTransport() {
  const d = player.detail;
  $("play").disabled = !d;
  $("scrub").disabled = !d;
  $("play").textContent = player.playing ? "❚❚ Pause" : "▶ Play";
  if (d) {
    $("scrub").max = d.duration_s.toFixed(2);
    if (document.activeElement !== $("scrub")) $("scrub").value = player.t;
    const waiting = player.wanted === null ? "" : ` (loading to ${player.wanted.toFixed(1)} s…)`;
    setText("replay-time", `${player.t.toFixed(1)} / ${d.duration_s.toFixed(1)} s${waiting}`);
  }
}

$("recording-open").onclick = () => openRecording($("recording-select").value);
$("recording-refresh").onclick = () => loadRecordings($("recording-select").value);
$("play").onclick = () => (player.playing ? player.pause() : player.play());
$("speed").onchange = (ev) => { player.speed = Number(ev.target.value); };
$("scrub").oninput = (ev) => player.seek(Number(ev.target.value));
$("recording-upload").onchange = async (ev) => {
  const file = ev.target.files[0];
  ev.target.value = "";
  if (!file) return;
  if (file.size > app.config.max_upload_bytes) {
    say(`${file.name} is larger than the ground station accepts (${(app.config.max_upload_bytes / 2 ** 20).toFixed(0)} MiB)`, "error");
    return;
  }
  if (!getToken() && !(await askToken())) return;
  setText("recording-info", `uploading ${file.name}…`);
  try {
    const entry = await request("POST", `/api/recordings/upload?name=${encodeURIComponent(file.name)}`,
      { body: file, raw: true, command: true, headers: { "Content-Type": "application/octet-stream" } });
    await loadRecordings(entry.id);
    await openRecording(entry.id);
  } catch (err) {
    setText("recording-info", "");
    say(`Upload ${file.name}: ${err.message}`, "error");
  }
};

// -- modes and start ------------------------------------------------------------------------------

function setMode(mode) {
  app.mode = mode;
  document.body.classList.toggle("replay", mode === "replay");
  $("replay-panel").hidden = mode !== "replay";
  for (const [id, m] of [["mode-live", "live"], ["mode-replay", "replay"]]) {
    $(id).classList.toggle("active", m === mode);
    $(id).setAttribute("aria-selected", String(m === mode));
  }
  setText("metrics-title", "");
  $("metrics-title").innerHTML = mode === "live"
    ? "Paper's metrics <small>(as <code>seaway report</code> computes them, live)</small>"
    : "Run's report <small>(<code>seaway report</code>)</small>";
  if (mode === "replay") {
    player.pause();
    loadRecordings($("recording-select").value);
  } else {
    player.pause();
  }
  updateLinkPill();
  schedule();
}
$("mode-live").onclick = () => setMode("live");
$("mode-replay").onclick = () => setMode("replay");
$("vessel-picker").onchange = (ev) => selectVessel(ev.target.value);
$("token-button").onclick = () => askToken();

async function start() {
  try {
    app.config = await get("/api/config");
  } catch (err) {
    say(`Cannot read the ground station's settings: ${err.message}`, "error");
  }
  $("controller").replaceChildren(...app.config.controllers.map((c) => new Option(c, c)));
  renderDraftTable();
  // The legend starts open where it leaves room for the vessel, folded on a phone.
  $("map-legend").open = window.matchMedia("(min-width: 900px)").matches;
  setMode(new URLSearchParams(location.search).get("view") === "replay" ? "replay" : "live");
  // Plots keep their history across a reload: the live run's recording under the live frames.
  liveHistory(app.live, app.config.live_recordings || [], clockLive).then(schedule)
    .catch((err) => say(`The plots' history from the recording: ${err.message}`, "error"));
  stream.start();
  pollFleet();
  map.fit();
}
start();

// For tests and the curious: the page's state, read-only by convention.
window.seaway = { app, map, player, plots };
