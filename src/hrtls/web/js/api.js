// Client of the supervisor's HTTP and WebSocket API (docs/service-api.md).

const TOKEN_KEY = "hrtls.token";

export class ApiError extends Error {
  constructor(status, detail, path) {
    super(`${status} ${path}: ${detail}`);
    this.status = status;
    this.detail = detail;
    this.path = path;
  }
}

function errorDetail(body) {
  if (!body) return "";
  if (typeof body.detail === "string") return body.detail;
  if (body.error && typeof body.error === "object") return body.error.message || JSON.stringify(body.error);
  if (typeof body.error === "string") return body.error;
  return JSON.stringify(body.detail ?? body);
}

export class Api {
  constructor(base = "") {
    this.base = base;
    this.token = sessionStorage.getItem(TOKEN_KEY);
  }

  setToken(token) {
    this.token = token;
    if (token) sessionStorage.setItem(TOKEN_KEY, token);
    else sessionStorage.removeItem(TOKEN_KEY);
  }

  async request(method, path, body) {
    const headers = { Accept: "application/json" };
    if (this.token) headers.Authorization = `Bearer ${this.token}`;
    if (body !== undefined) headers["Content-Type"] = "application/json";
    const response = await fetch(this.base + path, {
      method, headers, body: body === undefined ? undefined : JSON.stringify(body),
      credentials: "same-origin",
    });
    const text = await response.text();
    let parsed = null;
    if (text) {
      try { parsed = JSON.parse(text); } catch { parsed = { detail: text }; }
    }
    if (!response.ok) throw new ApiError(response.status, errorDetail(parsed), path);
    return parsed;
  }

  get(path) { return this.request("GET", path); }
  post(path, body) { return this.request("POST", path, body ?? {}); }

  // WebSocket on the same host; the token travels in the first message, not in the URL.
  socketUrl(path) {
    const scheme = location.protocol === "https:" ? "wss:" : "ws:";
    return `${scheme}//${location.host}${this.base}${path}`;
  }
}
