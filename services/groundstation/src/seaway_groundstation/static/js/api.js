// The ground station's HTTP API as the page uses it: JSON in and out, the operator token on
// commands, and every refusal turned into one readable sentence (the API's own reason).

const TOKEN_KEY = "seaway.groundstation.token";
/** This page's own id (new at each load), sent with its commands: the ground station streams every
 *  command it relays with the sender's id, so each page tells another's commands from its own. */
export const CLIENT_ID = (crypto.randomUUID?.() || `${Date.now().toString(36)}-${Math.random().toString(36).slice(2)}`);

/** The operator token: from the URL fragment (#token=...) once, then from sessionStorage. */
export function takeTokenFromFragment() {
  const m = /(?:^#|&)token=([^&]+)/.exec(location.hash);
  if (m) {
    setToken(decodeURIComponent(m[1]));
    // Out of the address bar, so the token is not copied along with the page's address.
    history.replaceState(null, "", location.pathname + location.search);
  }
}
export const getToken = () => sessionStorage.getItem(TOKEN_KEY) || "";
export function setToken(token) {
  if (token) sessionStorage.setItem(TOKEN_KEY, token.trim());
  else sessionStorage.removeItem(TOKEN_KEY);
}

/** An API answer that is not a success: HTTP status and the reason to show. */
export class ApiError extends Error {
  constructor(status, reason, body) {
    super(reason);
    this.status = status;
    this.body = body;
  }
}

/** FastAPI's 422 lists the fields at fault; anything else has a "detail" or a vessel's "reason". */
export function reasonOf(status, body) {
  if (body && typeof body === "object") {
    if (typeof body.reason === "string" && body.reason) return body.reason;
    if (typeof body.detail === "string") return body.detail;
    if (Array.isArray(body.detail)) {
      return body.detail.map((e) => `${(e.loc || []).filter((p) => p !== "body").join(".") || "body"}: ${e.msg}`)
        .join("; ");
    }
  }
  if (typeof body === "string" && body) return body.slice(0, 300);
  return `HTTP ${status}`;
}

async function readBody(resp) {
  const text = await resp.text();
  try { return JSON.parse(text); } catch { return text; }
}

/**
 * One request. `command: true` adds the operator token. Resolves with the parsed body on 2xx;
 * rejects with ApiError (status, reason) otherwise, and with status 0 when the server is unreachable.
 */
export async function request(method, path, { body, command = false, raw = false, headers = {} } = {}) {
  const h = { ...headers };
  if (body !== undefined && !raw) h["Content-Type"] = "application/json";
  if (command) {
    h["X-Seaway-Client"] = CLIENT_ID;
    const token = getToken();
    if (token) h.Authorization = `Bearer ${token}`;
  }
  let resp;
  try {
    resp = await fetch(path, { method, headers: h, body: raw ? body : body === undefined ? undefined : JSON.stringify(body) });
  } catch (err) {
    throw new ApiError(0, `the ground station does not answer (${err.message})`, null);
  }
  const data = await readBody(resp);
  if (!resp.ok) throw new ApiError(resp.status, reasonOf(resp.status, data), data);
  return data;
}

export const get = (path) => request("GET", path);
export const command = (path, body) => request("POST", path, { body, command: true });
