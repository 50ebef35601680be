// Replay: a recording's frames (the live stream's frames, cut by the ground station) fed to a Store
// at the recording's time. Play advances that time at a chosen speed; seeking back replays the
// frames from the start into an empty store, so what is drawn at time t is exactly what a live
// client would have had at t. The ground station cuts the frames as it reads the recording: the first
// request is short, so the first frame shows at once; each answer says up to when it is whole
// (`loaded_to_s`) and the next takes up there. The replay's time never goes past what has arrived:
// a seek beyond it waits at the loaded edge (frames as they were then, not old ones aged as if
// current) and goes on to the time asked for once the frames are there.

import { get } from "./api.js";
import { Store } from "./store.js";

const FIRST_WINDOW_S = 2; // the first request [s of recorded time]: the first frame at once
const WINDOW_S = 120;     // each request after it [s]

export class Player {
  constructor({ onUpdate, onProgress, onState }) {
    this.store = new Store();
    this.onUpdate = onUpdate;
    this.onProgress = onProgress;
    this.onState = onState;
    this.detail = null;
    this.frames = [];      // [{t_s, frame}] in time order
    this.loadedTo = 0;     // frames are complete up to this time [s]
    this.next = 0;         // index of the first frame not yet ingested
    this.t = 0;            // the replay's time [s since the recording's start]
    this.playing = false;
    this.speed = 5;
    this.token = 0;        // bumps on every open, so a stale load stops
    this.wanted = null;    // a time asked for beyond the loaded part [s], reached once loaded
    this.error = null;     // why the frames stop before the recording's end (a damaged chunk)
  }

  get duration() {
    return this.detail ? this.detail.duration_s : 0;
  }

  async open(id) {
    const token = ++this.token;
    this.pause();
    this.detail = await get(`/api/recording?id=${encodeURIComponent(id)}`);
    this.error = null;
    this.frames = [];
    this.loadedTo = 0;
    this.store.clear();
    this.next = 0;
    this.t = 0;
    this.onState?.();
    this.wanted = null;
    // The whole span, a window at a time; playing and scrubbing work on what has arrived.
    const end = this.duration + 1;
    let requests = 0;
    let shown = false;
    while (this.loadedTo < end) {
      const start = this.loadedTo;
      const span = requests++ ? WINDOW_S : FIRST_WINDOW_S;
      const w = await get(`/api/recording/frames?id=${encodeURIComponent(id)}&start_s=${start}&end_s=${start + span}`);
      if (token !== this.token) return false;
      for (const f of w.frames) this.frames.push(f);
      this.loadedTo = Math.max(start, w.loaded_to_s);
      if (w.error && !this.error) this.error = w.error; // found as the recording is cut: said once
      this.onProgress?.(Math.min(1, this.loadedTo / end));
      if (!shown && this.frames.length) {
        shown = true;
        this.seek(this.wanted ?? this.frames[0].t_s); // the first frame, or the time asked for
      } else if (this.wanted !== null && this.wanted <= this.loadedTo) {
        const t = this.wanted;
        this.wanted = null;
        this.seek(t);
      } else if (!this.playing) {
        this.onState?.();
      }
    }
    this.loadedTo = Infinity;
    if (this.wanted !== null) {
      const t = this.wanted;
      this.wanted = null;
      this.seek(t);
    }
    this.onProgress?.(1);
    this.onState?.();
    return true;
  }

  /** Whether the frames up to `t` [s] have arrived. */
  loaded(t) {
    return t <= this.loadedTo;
  }

  /** Show the recording as it was at `t` [s]. */
  seek(t) {
    t = Math.max(0, Math.min(t, this.duration));
    if (t > this.loadedTo) {
      this.wanted = t; // shown once the frames up to it are here; until then the loaded edge
      t = this.loadedTo;
    } else {
      this.wanted = null;
    }
    if (t < this.t || this.next === 0) {
      this.store.clear();
      this.next = 0;
    }
    while (this.next < this.frames.length && this.frames[this.next].t_s <= t) {
      const f = this.frames[this.next++];
      this.store.ingest(f.frame, f.t_s);
    }
    this.t = t;
    this.onUpdate?.();
  }

  play() {
    if (!this.detail || this.playing) return;
    if (this.t >= this.duration) this.seek(0);
    this.playing = true;
    let last = performance.now();
    const tick = (now) => {
      if (!this.playing) return;
      const dt = ((now - last) / 1000) * this.speed;
      last = now;
      const target = Math.min(this.t + dt, this.duration, this.loadedTo);
      this.seek(target);
      if (this.t >= this.duration) this.pause();
      else requestAnimationFrame(tick);
    };
    requestAnimationFrame(tick);
    this.onState?.();
  }

  pause() {
    this.playing = false;
    this.onState?.();
  }
}

/** A recording's frames, all of them, as the player loads them: [{t_s, frame}]. */
export async function recordedFrames(id) {
  const q = encodeURIComponent(id);
  const detail = await get(`/api/recording?id=${q}`);
  const end = detail.duration_s + 1;
  const frames = [];
  let loaded = 0;
  while (loaded < end) {
    const w = await get(`/api/recording/frames?id=${q}&start_s=${loaded}&end_s=${loaded + WINDOW_S}`);
    for (const f of w.frames) frames.push(f);
    loaded = Math.max(loaded, w.loaded_to_s);
  }
  return frames;
}

/** The live store's history from the live run's recordings (`ids`): the plots and the trail as
 *  they were before the page was (re)loaded. Live frames that arrive meanwhile are kept and go
 *  again over the history. `clock`: the live store's clock [s]. */
export async function liveHistory(store, ids, clock) {
  if (!ids.length) return;
  store.keepLog();
  try {
    const recordings = [];
    for (const id of ids) {
      const frames = await recordedFrames(id);
      if (frames.length) recordings.push({ frames, endT: frames[frames.length - 1].t_s });
    }
    if (recordings.length) store.underlay(recordings, clock());
  } finally {
    store.log = null;
  }
}
