// Replay: a recording's frames (the live stream's frames, cut by the ground station) fed to a Store
// at the recording's time. Play advances that time at a chosen speed; seeking back replays the
// frames from the start into an empty store, so what is drawn at time t is exactly what a live
// client would have had at t.

import { get } from "./api.js";
import { Store } from "./store.js";

const WINDOW_S = 30; // frames fetched per request [s of recorded time]

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
  }

  get duration() {
    return this.detail ? this.detail.duration_s : 0;
  }

  async open(id) {
    const token = ++this.token;
    this.pause();
    this.detail = await get(`/api/recording?id=${encodeURIComponent(id)}`);
    this.frames = [];
    this.loadedTo = 0;
    this.store.clear();
    this.next = 0;
    this.t = 0;
    this.onState?.();
    // The whole span, a window at a time; playing and scrubbing work on what has arrived.
    const end = this.duration + 1;
    for (let start = 0; start < end; start += WINDOW_S) {
      const w = await get(`/api/recording/frames?id=${encodeURIComponent(id)}&start_s=${start}&end_s=${start + WINDOW_S}`);
      if (token !== this.token) return false;
      this.frames.push(...w.frames);
      this.loadedTo = Math.min(end, start + WINDOW_S);
      this.onProgress?.(Math.min(1, this.loadedTo / end));
      if (start === 0) this.seek(0);
    }
    this.loadedTo = Infinity;
    this.onProgress?.(1);
    this.onState?.();
    return true;
  }

  /** Show the recording as it was at `t` [s]. */
  seek(t) {
    t = Math.max(0, Math.min(t, this.duration));
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
