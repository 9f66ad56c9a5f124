// Client of the supervisor's API (docs/service-api.md), mapped to the dashboard's own shapes.
// The browser authenticates with the session cookie set by POST /auth/login (HttpOnly); the
// token itself is never stored by the page.

const BASE = "/api/v1";
const RECONNECT_MS = [250, 500, 1000, 2000, 5000];

export class ApiError extends Error {
  constructor(status, detail, path) {
    super(`${status} ${path}: ${detail}`);
    this.status = status;
    this.detail = detail;
    this.path = path;
  }
}

// Estimate of the API -> {agent, t, x, y, z, floor, var_x, cov_xy, var_y, heading, ...}.
export function estimateOf(e) {
  const c = e.cov_xy;
  return {
    agent: String(e.agent), t: e.t, x: e.x, y: e.y, z: e.z, floor: e.floor,
    var_x: c[0][0], cov_xy: c[0][1], var_y: c[1][1],
    heading: e.heading_rad, activity: e.activity, since_correction_s: e.since_correction_s,
    stale: e.stale, received_t: e.received_t,
  };
}

export function agentOf(a) {
  const s = a.status || {};
  const info = {};
  if (s.battery !== null && s.battery !== undefined) info.battery = `${Math.round(100 * s.battery)} %`;
  if (s.connected !== null && s.connected !== undefined) info.connection = s.connected ? "connected" : "disconnected";
  if (s.missing && s.missing.length) info["missing batches"] = s.missing.map((r) => r.join("–")).join(", ");
  info.tracker = `${a.preset || "-"} (${a.placement || "-"})`;
  if (a.device && Object.keys(a.device).length) info.device = Object.values(a.device).join(" ");
  if (a.sensors) info["sensors in use"] = a.sensors;
  return { id: String(a.id), name: a.name, kind: a.kind, lastDataT: s.last_data_t ?? null,
    checkedIn: a.checked_in, info };
}

export function eventOf(e) {
  return { ...e, id: String(e.id), agent: e.agent === null ? null : String(e.agent) };
}

export function orderOf(o) {
  return { ...o, id: String(o.id), agent: o.agent === null ? null : String(o.agent) };
}

// A node of the mission's sensor network (GET /missions/{m}/network shape) -> the node layer's.
export function networkNodeOf(n) {
  const [x, y] = n.position || [NaN, NaN];
  return { id: String(n.id), localized: Boolean(n.localized), reason: n.reason || "",
    readings: n.readings ?? 0, passes: n.passes ?? 0, t: n.t ?? null, x, y,
    cov: n.covariance_m2 || null, sigma_m: n.sigma_m ?? null, floor: n.floor ?? null,
    declared: n.declared !== false };
}

// A snapshot, replay picture or delta; nodes: null when the picture has none (no network).
export function pictureOf(p) {
  const trails = {};
  for (const [id, pts] of Object.entries(p.trails || {})) trails[String(id)] = pts;
  return {
    t: p.t, agents: (p.agents || []).map(agentOf), estimates: (p.estimates || []).map(estimateOf),
    events: (p.events || []).map(eventOf), orders: (p.orders || []).map(orderOf), trails,
    nodes: Array.isArray(p.nodes) ? p.nodes.map(networkNodeOf) : null,
  };
}

function landmarkOf(l) {
  const [x, y] = l.position || [NaN, NaN];
  return { id: l.id, kind: l.kind, x, y, floor: l.floor ?? 0, accuracy_m: l.accuracy_m,
    message: [l.classification, l.updated].filter(Boolean).join(", ") };
}

// A floor's plan image: its URL and its bounds [[south, west], [north, east]] in local metres
// (CRS.Simple [y, x]) from the lower-left corner and the scale.
function imageOf(i) {
  if (!i) return null;
  const w = i.width_px * i.m_per_px;
  const h = i.height_px * i.m_per_px;
  return { url: i.url, bounds: [[i.origin_y_m, i.origin_x_m], [i.origin_y_m + h, i.origin_x_m + w]] };
}

function waypointsOf(list) {
  const byRobot = new Map();
  for (const w of list) {
    const key = `${w.agent}:${w.floor}`;
    if (!byRobot.has(key)) byRobot.set(key, { robot: String(w.agent), floor: w.floor, points: [] });
    byRobot.get(key).points.push({ x: w.x, y: w.y, order: w.order, status: w.status });
  }
  return [...byRobot.values()];
}

export class Api {
  async request(method, path, body) {
    const headers = { Accept: "application/json" };
    if (body !== undefined) headers["Content-Type"] = "application/json";
    const response = await fetch(BASE + path, {
      method, headers, credentials: "same-origin",
      body: body === undefined ? undefined : JSON.stringify(body),
    });
    if (response.status === 204) return null;
    const text = await response.text();
    let parsed = null;
    if (text) {
      try { parsed = JSON.parse(text); } catch { parsed = { detail: text }; }
    }
    if (!response.ok) {
      const detail = typeof parsed?.detail === "string" ? parsed.detail : JSON.stringify(parsed);
      throw new ApiError(response.status, detail, path);
    }
    return parsed;
  }

  login(token) { return this.request("POST", "/auth/login", { token }); }
  logout() { return this.request("POST", "/auth/logout"); }
  whoami() { return this.request("GET", "/auth/whoami"); }

  missions() { return this.request("GET", "/missions"); }
  dashboardConfig() { return this.request("GET", "/dashboard/config"); }

  async mission(id) {
    const m = await this.request("GET", `/missions/${id}`);
    const features = [];
    for (const f of m.floors || []) {
      for (const feat of f.plan?.features || []) {
        features.push({ ...feat, properties: { ...(feat.properties || {}), floor: f.index } });
      }
    }
    return { id: m.id, name: m.name, t0Unix: m.t0_unix, nowT: m.now_t,
      staleAfterS: m.stale_after_s, georeference: m.georeference,
      floors: (m.floors || []).map((f) => ({ index: f.index, name: f.name, image: imageOf(f.image) })),
      floorplan: { type: "FeatureCollection", features } };
  }

  async infrastructure(id) {
    const i = await this.request("GET", `/missions/${id}/infrastructure`);
    // the sensor nodes come with the snapshot and the deltas (js/nodes.js)
    return { landmarks: i.landmarks.filter((l) => l.position).map(landmarkOf),
      waypoints: waypointsOf(i.waypoints) };
  }

  async snapshot(id) { return pictureOf(await this.request("GET", `/missions/${id}/snapshot?trail_s=300`)); }
  async replayAt(id, t) { return pictureOf(await this.request("GET", `/missions/${id}/replay?t=${t}&trail_s=300`)); }
  async trail(id, agent) { return this.request("GET", `/missions/${id}/agents/${agent}/trail?max_points=2000`); }
  async orders(id) { return (await this.request("GET", `/missions/${id}/orders`)).map(orderOf); }
  async acknowledge(id, eventId) { return eventOf(await this.request("POST", `/missions/${id}/events/${eventId}/ack`)); }

  // body: {kind, agents?: [id], floor?: int, text?, waypoint?: {x, y, floor}}
  async order(id, body) {
    const created = await this.request("POST", `/missions/${id}/orders`, {
      kind: body.kind, agents: body.agents ? body.agents.map(Number) : null,
      floor: body.floor ?? null, ...(body.text ? { text: body.text } : {}),
      ...(body.waypoint ? { waypoint: body.waypoint } : {}),
    });
    return created.map(orderOf);
  }

  // Live socket with reconnection; callbacks: onPicture (snapshot), onDelta, onState, onUnauthorized.
  live(id, { onPicture, onDelta, onState, onUnauthorized }) {
    let socket = null;
    let attempt = 0;
    let closed = false;
    let timer = null;
    const scheme = location.protocol === "https:" ? "wss:" : "ws:";
    const url = `${scheme}//${location.host}${BASE}/missions/${id}/ws`;
    const connect = () => {
      socket = new WebSocket(url);
      socket.onopen = () => { attempt = 0; };
      socket.onmessage = (msg) => {
        const m = JSON.parse(msg.data);
        if (m.type === "hello") onState("live");
        else if (m.type === "snapshot") onPicture(pictureOf(m));
        else if (m.type === "delta") onDelta(pictureOf(m));
      };
      socket.onclose = (ev) => {
        if (closed) return;
        if (ev.code === 4401 || ev.code === 4403) { onUnauthorized(); return; }
        onState("offline", "reconnecting");
        timer = setTimeout(connect, RECONNECT_MS[Math.min(attempt, RECONNECT_MS.length - 1)]);
        attempt += 1;
      };
    };
    connect();
    return {
      close() { closed = true; clearTimeout(timer); if (socket) socket.close(); },
    };
  }
}
