// What the page knows of each vessel, built from stream frames only. Live frames (the WebSocket) and
// recorded ones (the replay API) are the same frames and go through the same `ingest`; the only
// difference is the clock `now` [s] they are ingested at: the page's clock live, the recording's
// time in replay. Ages and staleness follow from it the same way in both.
//
// A frame: {vessel, services, stale_after_s, updates: {kind: {age_s, stale, message}}}, with kinds
// state, solve, mission, vehicle, origin, thrust, energy, area (the ground station's app.py documents it).

const MAX_POINTS = 20000;   // per series; beyond, every other point is dropped (the shape stays)
const MAX_TRAIL = 8000;
const TRAIL_STEP_M = 0.15;  // a trail point every this many metres
const EPISODE_BACK_S = 1.0; // a state this much older than the last one starts a new episode

function series(...names) {
  const s = { t: [] };
  for (const n of names) s[n] = [];
  return s;
}

function push(s, t, values) {
  const n = s.t.length;
  if (n && t < s.t[n - 1]) return; // late or out of order: plots need time order
  s.t.push(t);
  for (const [k, v] of Object.entries(values)) s[k].push(v ?? NaN);
  if (s.t.length > MAX_POINTS) {
    for (const k of Object.keys(s)) s[k] = s[k].filter((_, i) => i % 2 === 0);
  }
}

export class VesselData {
  constructor(name) {
    this.name = name;
    this.services = [];
    this.latest = {};        // kind -> {message, age0, at}: age when received, and when [s]
    this.staleAfter = 2.0;
    this.missionId = null;   // the mission the histories are of
    this.missionOver = true;
    this.reset();
  }

  /** Forget the histories (a new mission or episode, or a replay seeking back). */
  reset() {
    this.t0 = null;          // stamp [ns] that t = 0 stands for
    this.lastStateStamp = null;
    this.series = {
      thrust: series("port", "starboard"),
      speed: series("speed"),
      xte: series("xte"),
      // Energy: the controller's budget (mission/energy) once it publishes one for the mission;
      // until then the mission status's figures (used, and its energy to finish).
      energy: series("used", "finish", "home"),
      budget: series("used", "finish", "home"),
    };
    this.trail = [];
  }

  t(stampNs) {
    if (this.t0 === null) this.t0 = stampNs;
    return (stampNs - this.t0) / 1e9;
  }

  ingest(frame, now) {
    this.services = frame.services || this.services;
    if (frame.stale_after_s) this.staleAfter = frame.stale_after_s;
    for (const [kind, u] of Object.entries(frame.updates || {})) {
      this.latest[kind] = { message: u.message, age0: u.age_s || 0, at: now };
      this.add(kind, u.message);
    }
  }

  add(kind, m) {
    const s = this.series;
    if (kind === "state") {
      if (this.lastStateStamp !== null && (this.lastStateStamp - m.stamp_ns) / 1e9 > EPISODE_BACK_S) {
        this.reset(); // simulated time went back: a restarted sim or a new scenario
      }
      this.lastStateStamp = m.stamp_ns;
      push(s.speed, this.t(m.stamp_ns), { speed: Math.hypot(m.u_mps, m.v_mps) });
      const last = this.trail[this.trail.length - 1];
      if (!last || Math.hypot(m.x_m - last[0], m.y_m - last[1]) >= TRAIL_STEP_M) {
        this.trail.push([m.x_m, m.y_m]);
        if (this.trail.length > MAX_TRAIL) this.trail = this.trail.filter((_, i) => i % 2 === 0);
      }
    } else if (kind === "thrust") {
      push(s.thrust, this.t(m.stamp_ns), { port: m.thrust_port_n, starboard: m.thrust_starboard_n });
    } else if (kind === "mission" && m.state !== "idle") {
      // Histories start again with each mission (a new one, or the same one started again), so the
      // plots and the trail show the mission flown, from its start.
      if (m.state === "active" && (m.mission_id !== this.missionId || this.missionOver)) {
        const keep = this.latest.state?.message;
        this.reset();
        if (keep) this.add("state", keep);
      }
      this.missionId = m.mission_id;
      this.missionOver = m.state === "complete" || m.state === "aborted";
      const t = this.t(m.stamp_ns);
      push(s.xte, t, { xte: m.cross_track_m });
      push(s.energy, t, { used: m.energy_used_j, finish: m.energy_to_go_j, home: null });
    } else if (kind === "energy" && m.mission_id === this.missionId) {
      push(s.budget, this.t(m.stamp_ns), { used: m.energy_used_j, finish: m.energy_to_go_j,
        home: m.energy_to_home_j });
    }
  }

  /** The energy budget of the mission the status names (null: none published for it). */
  budget() {
    const b = this.message("energy"), m = this.message("mission");
    return b && m && b.mission_id === m.mission_id ? b : null;
  }

  /** The energy series to plot: the budget's once it has any, else the status's. */
  energySeries() {
    return this.series.budget.t.length ? this.series.budget : this.series.energy;
  }

  message(kind) {
    return this.latest[kind]?.message ?? null;
  }

  /** Age of the latest message of `kind` at `now` [s] (Infinity: never received). */
  age(kind, now) {
    const l = this.latest[kind];
    return l ? l.age0 + Math.max(0, now - l.at) : Infinity;
  }

  stale(kind, now) {
    return this.age(kind, now) > this.staleAfter;
  }
}

export class Store {
  constructor() {
    this.vessels = new Map();
    this.log = null;         // [[frame, now]] since keepLog (null: not kept)
  }

  vessel(name) {
    let v = this.vessels.get(name);
    if (!v) {
      v = new VesselData(name);
      this.vessels.set(name, v);
    }
    return v;
  }

  ingest(frame, now) {
    if (!frame || typeof frame.vessel !== "string") return null;
    this.log?.push([frame, now]);
    this.vessel(frame.vessel).ingest(frame, now);
    return frame.vessel;
  }

  /** Keep the frames ingested from now on, to go again over a history (`underlay`). */
  keepLog() {
    this.log = [];
  }

  /** Put recordings' frames (`[{frames: [{t_s, frame}], endT}]`, the last frame of each at `endT`
   *  [s]: at `now` on the store's clock) under what this store has ingested since `keepLog`: the
   *  recorded ones first, then those again (a point older than the last one of its series is left
   *  out: no doubles where they overlap). */
  underlay(recordings, now) {
    const log = this.log || [];
    this.log = null;
    const under = new Store();
    for (const { frames, endT } of recordings) {
      for (const f of frames) under.ingest(f.frame, now - (endT - f.t_s));
    }
    for (const [frame, at] of log) under.ingest(frame, at);
    this.vessels = under.vessels;
  }

  clear() {
    this.vessels.clear();
  }

  names() {
    return [...this.vessels.keys()].sort();
  }
}
