// The live stream: one WebSocket to /api/stream for every vessel, reconnecting with back-off.
// Each frame goes to `onFrame(frame)`; `onLink(state, detail)` says whether the link is up.

export class LiveStream {
  constructor({ onFrame, onLink }) {
    this.onFrame = onFrame;
    this.onLink = onLink;
    this.ws = null;
    this.delayMs = 500;
    this.stopped = true;
    this.timer = null;
  }

  start() {
    this.stopped = false;
    this.connect();
  }

  stop() {
    this.stopped = true;
    clearTimeout(this.timer);
    if (this.ws) this.ws.close(1000, "page left live view");
    this.ws = null;
  }

  connect() {
    if (this.stopped) return;
    const url = `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/api/stream`;
    let ws;
    try {
      ws = new WebSocket(url);
    } catch (err) {
      this.retry(`cannot open ${url}: ${err.message}`);
      return;
    }
    this.ws = ws;
    this.onLink("connecting");
    ws.onopen = () => {
      this.delayMs = 500;
      this.onLink("up");
    };
    ws.onmessage = (ev) => {
      try {
        this.onFrame(JSON.parse(ev.data));
      } catch (err) {
        console.error("bad frame", err);
      }
    };
    ws.onclose = (ev) => {
      if (this.ws !== ws) return;
      this.ws = null;
      this.retry(ev.reason || (ev.code === 1013 ? "the ground station has too many stream clients" : `closed (${ev.code})`));
    };
    ws.onerror = () => {}; // onclose follows and says it
  }

  retry(why) {
    if (this.stopped) return;
    this.onLink("down", why);
    clearTimeout(this.timer);
    this.timer = setTimeout(() => this.connect(), this.delayMs);
    this.delayMs = Math.min(this.delayMs * 2, 5000);
  }
}
