// The dashboard of one mission: state from the supervisor, map, lists, alarms, orders, replay.

import { formatAge, formatClock, quality } from "./geometry.js";
import { MapView } from "./mapview.js";
import { NodeLayer } from "./nodes.js";

const TRAIL_WINDOW_S = 300;
const ALARM_KINDS = new Set(["pass_prealarm", "pass_alarm", "fall", "silent", "uncertainty", "sos"]);
// The banner shows the most urgent open alarm: a rescuer down before a silent link or doubt.
const BANNER_RANK = { sos: 0, pass_alarm: 0, fall: 0, silent: 1, uncertainty: 2, pass_prealarm: 3 };
const EVENT_TEXT = {
  pass_prealarm: "PASS pre-alarm", pass_alarm: "PASS ALARM", fall: "FALL", silent: "silent agent",
  uncertainty: "lost confidence", sos: "SOS", floor_change: "floor change", zone_enter: "entered",
  zone_leave: "left", checkin: "check-in", order_receipt: "order receipt",
};
const ORDER_TEXT = { evacuate: "evacuate", checkin: "check-in", goto: "go to", text: "message" };
const COMPASS = ["N", "NE", "E", "SE", "S", "SW", "W", "NW"];

function el(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "class") node.className = v;
    else if (k === "dataset") Object.assign(node.dataset, v);
    else if (k.startsWith("on")) node.addEventListener(k.slice(2), v);
    else node.setAttribute(k, v);
  }
  for (const c of children) node.append(c instanceof Node ? c : document.createTextNode(String(c)));
  return node;
}

// Replace the children of node only when key changed (keeps buttons stable between renders).
function replaceIf(node, key, build) {
  if (node.dataset.renderKey === key) return;
  node.dataset.renderKey = key;
  node.replaceChildren(...build());
}

function compass(headingRad) {
  if (!Number.isFinite(headingRad)) return "-";
  const bearing = ((90 - (headingRad * 180) / Math.PI) % 360 + 360) % 360;
  return `${Math.round(bearing)}° ${COMPASS[Math.round(bearing / 45) % 8]}`;
}

export class Dashboard {
  constructor(api, who, { onUnauthorized }) {
    this.api = api;
    this.who = who;
    this.onUnauthorized = onUnauthorized;
    this.commander = who.role === "commander";
    this.missionId = null;
    this.mission = null;
    this.floor = 0;
    this.agents = new Map();   // id -> {id, name, kind, est, trail: [], info, lastEvents}
    this.events = new Map();   // id -> event
    this.orders = new Map();   // id -> order
    this.infra = { landmarks: [], waypoints: [] };
    this.network = null;       // id -> node of the sensor network (null: none declared)
    this.selected = null;
    this.pendingGoto = null;
    this.replay = { active: false, playing: false, t: 0, speed: 1, timer: null, start: 0, end: 0 };
    this.renderQueued = false;
    this.closed = false;
    document.getElementById("role").textContent = `${who.label || who.role} (${who.role})`;
    document.querySelectorAll(".commander-only").forEach((n) => { n.hidden = !this.commander; });
    this.map = new MapView(document.getElementById("map"), {
      onMapClick: (p) => this.mapClicked(p),
      onAgentClick: (id) => this.select(id),
    });
    this.nodes = new NodeLayer(this.map, { count: document.getElementById("node-count"),
      list: document.getElementById("node-list") });
    this.bindControls();
  }

  // ---- lifecycle ------------------------------------------------------------------------------

  async start() {
    this.config = await this.api.dashboardConfig();
    const missions = await this.api.missions();
    const select = document.getElementById("mission-select");
    select.replaceChildren(...missions.map((m) => el("option", { value: m.id }, m.name || m.id)));
    const wanted = new URLSearchParams(location.search).get("mission");
    const active = missions.filter((m) => m.status === "active");
    const chosen = missions.find((m) => String(m.id) === wanted) || active[active.length - 1]
      || missions[missions.length - 1];
    if (!chosen) throw new Error("no mission yet");
    select.value = chosen.id;
    await this.openMission(chosen.id);
    if (!this.tick) this.tick = setInterval(() => this.scheduleRender(), 1000);
  }

  close() {
    this.closed = true;
    clearInterval(this.tick);
    clearTimeout(this.infraTimer);
    this.stopReplayTimer();
    if (this.live) this.live.close();
    this.map.map.remove();
  }

  async openMission(id) {
    if (this.live) this.live.close();
    this.missionId = id;
    this.agents.clear(); this.events.clear(); this.orders.clear();
    this.network = null;
    this.mission = await this.api.mission(id);
    this.map.setFrame(this.mission.georeference, this.config.basemap);
    this.map.setFloorplan(this.mission.floorplan, this.mission.floors);
    const floors = this.mission.floors;
    this.floor = floors.length ? floors[0].index : 0;
    this.infra = await this.api.infrastructure(id).catch(() => this.infra);
    this.applySnapshot(await this.api.snapshot(id));
    this.live = this.api.live(id, {
      onPicture: (p) => { if (!this.replay.active) { this.applySnapshot(p); this.scheduleRender(); } },
      onDelta: (d) => { if (!this.replay.active) this.applyDelta(d); },
      onState: (s) => this.setConnection(s),
      onUnauthorized: this.onUnauthorized,
    });
    this.map.drawFloor(this.floor);
    this.scheduleRender();
  }

  // ---- state ----------------------------------------------------------------------------------

  agent(id, meta = {}) {
    let a = this.agents.get(id);
    if (!a) {
      a = { id, name: meta.name || id, kind: meta.kind || "rescuer", est: null, trail: [],
        info: {}, lastDataT: null };
      this.agents.set(id, a);
    }
    if (meta.name) a.name = meta.name;
    if (meta.kind) a.kind = meta.kind;
    if (meta.info) Object.assign(a.info, meta.info);
    if (meta.lastDataT !== undefined && meta.lastDataT !== null) a.lastDataT = meta.lastDataT;
    return a;
  }

  // A whole picture (snapshot, or replay at a time): replaces estimates, trails and events.
  applySnapshot(p, { replay = false } = {}) {
    if (!replay) this.clockOffsetS = p.t - (Date.now() / 1000 - this.mission.t0Unix);
    for (const a of this.agents.values()) { a.est = null; a.trail = []; }
    for (const a of p.agents) this.agent(a.id, a);
    const wall = Date.now() / 1000;
    for (const e of p.estimates) {
      const a = this.agent(e.agent);
      a.est = e;
      if (!replay) a.seenWall = wall - Math.max(0, p.t - e.received_t);
    }
    for (const [id, trail] of Object.entries(p.trails)) this.agent(id).trail = trail.slice();
    this.events.clear();
    for (const ev of p.events) this.events.set(ev.id, ev);
    for (const o of p.orders) this.orders.set(o.id, o);
    if (!replay) {
      this.missionTime = Math.max(this.missionTime ?? 0, p.t);
      this.network = p.nodes === null ? null : new Map(p.nodes.map((n) => [n.id, n]));
    }
  }

  applyDelta(d) {
    for (const a of d.agents) this.agent(a.id, a);
    for (const e of d.estimates) this.applyEstimate(e);
    for (const ev of d.events) this.events.set(ev.id, { ...this.events.get(ev.id), ...ev });
    for (const o of d.orders) this.orders.set(o.id, { ...this.orders.get(o.id), ...o });
    if (d.nodes && d.nodes.length) {
      this.network = this.network || new Map();
      for (const n of d.nodes) this.network.set(n.id, n);
    }
    if (d.orders.length) this.refreshInfrastructure();
    if (Number.isFinite(d.t)) this.missionTime = Math.max(this.missionTime ?? 0, d.t);
    this.scheduleRender();
  }

  applyEstimate(e) {
    const a = this.agent(e.agent);
    if (a.est && e.t < a.est.t) return;
    if (!a.est || e.t > a.est.t) a.seenWall = Date.now() / 1000;
    a.est = e;
    const last = a.trail[a.trail.length - 1];
    if (!last || e.t > last.t) a.trail.push({ t: e.t, x: e.x, y: e.y, floor: e.floor });
    while (a.trail.length && a.trail[0].t < e.t - TRAIL_WINDOW_S) a.trail.shift();
  }

  refreshInfrastructure() {
    clearTimeout(this.infraTimer);
    this.infraTimer = setTimeout(async () => {
      this.infra = await this.api.infrastructure(this.missionId).catch(() => this.infra);
      this.scheduleRender();
    }, 200);
  }

  // Mission time now, on the service's clock.
  missionNow() { return Date.now() / 1000 - this.mission.t0Unix + (this.clockOffsetS || 0); }

  // Age of an agent's last data, s: since its estimate last advanced (wall clock; a replayed
  // agent at 10x has mission times ahead of the clock), or before the replay time.
  ageOf(a) {
    if (!a.est) return Infinity;
    if (this.replay.active) return Math.max(0, this.replay.t - a.est.t);
    return Math.max(0, Date.now() / 1000 - (a.seenWall ?? Date.now() / 1000));
  }

  isStale(a) {
    if (!a.est) return true;
    if (!this.replay.active && a.est.stale) return true;
    return this.ageOf(a) > (this.mission?.staleAfterS ?? 10);
  }

  // ---- rendering ------------------------------------------------------------------------------

  scheduleRender() {
    if (this.renderQueued || this.closed) return;
    this.renderQueued = true;
    requestAnimationFrame(() => { this.renderQueued = false; this.render(); });
  }

  render() {
    const shown = [...this.agents.values()].filter((a) => a.est);
    const onFloor = shown.filter((a) => a.est.floor === this.floor);
    this.map.renderAgents(onFloor.map((a) => ({
      id: a.id, name: a.name, kind: a.kind, est: a.est, stale: this.isStale(a),
      ageS: this.ageOf(a), selected: a.id === this.selected,
      trail: a.trail.filter((p) => p.floor === this.floor),
    })));
    this.map.fitToPoints(onFloor.map((a) => a.est));
    this.renderFloors(shown);
    this.renderAgentList(shown);
    this.renderAlarms();
    this.renderOrders();
    this.renderDetails();
    this.renderReplayBar();
    this.renderInfrastructure();
    const t = this.replay.active ? this.replay.t : this.missionTime;
    document.getElementById("mission-clock").textContent =
      `${this.mission?.name || ""} t = ${formatClock(t)}`;
  }

  renderFloors(shown) {
    const box = document.getElementById("floors");
    const counts = new Map();
    for (const a of shown) counts.set(a.est.floor, (counts.get(a.est.floor) || 0) + 1);
    const floors = this.mission.floors.length ? this.mission.floors
      : [...new Set([0, ...counts.keys()])].sort().map((i) => ({ index: i, name: `Floor ${i}` }));
    const key = JSON.stringify([this.floor, floors.map((f) => [f.index, f.name, counts.get(f.index) || 0])]);
    replaceIf(box, key, () => floors.map((f) => el("button", {
      type: "button", "aria-pressed": String(f.index === this.floor),
      dataset: { floor: f.index, count: counts.get(f.index) || 0 },
      onclick: () => this.setFloor(f.index),
    }, `${f.name} `, el("span", { class: "badge" }, counts.get(f.index) || 0))));
  }

  setFloor(index) {
    this.floor = index;
    this.map.drawFloor(index);
    this.scheduleRender();
  }

  renderAgentList(shown) {
    const list = document.getElementById("agents");
    const sorted = [...this.agents.values()].sort((a, b) => a.name.localeCompare(b.name));
    // one stable <li> per agent: only the content of a changed one is rebuilt (keeps it clickable)
    this.agentItems = this.agentItems || new Map();
    const rows = sorted.map((a) => {
      const stale = this.isStale(a);
      const q = a.est ? quality(a.est.var_x, a.est.cov_xy, a.est.var_y) : null;
      const level = stale ? "stale" : q?.level || "stale";
      let li = this.agentItems.get(a.id);
      if (!li) {
        li = el("li", { dataset: { agent: a.id }, onclick: () => this.select(a.id) });
        this.agentItems.set(a.id, li);
      }
      const text = a.est
        ? `F${a.est.floor} · ${a.est.activity || "-"}${stale ? ` · ${formatAge(this.ageOf(a))} old` : ""}`
        : "no data";
      const title = q ? `±${q.radius_m.toFixed(1)} m (2σ)` : "";
      const key = [a.name, level, title, text].join("|");
      if (li.dataset.renderKey !== key) {
        li.dataset.renderKey = key;
        li.className = stale ? "stale" : "";
        li.replaceChildren(el("span", { class: `quality ${level}`, title }), `${a.name} `,
          el("span", { class: "muted" }, text));
      }
      return li;
    });
    if (rows.length !== list.children.length || rows.some((li, i) => list.children[i] !== li)) {
      list.replaceChildren(...rows);
    }
    void shown;
  }

  alarmEvents() {
    return [...this.events.values()].filter((e) => ALARM_KINDS.has(e.kind))
      .sort((a, b) => (b.t ?? 0) - (a.t ?? 0));
  }

  renderAlarms() {
    const alarms = this.alarmEvents();
    const open = alarms.filter((e) => e.acknowledged_at === null && e.cleared_t === null);
    const count = document.getElementById("alarm-count");
    count.textContent = String(open.length);
    count.classList.toggle("active", open.length > 0);
    const alarmKey = JSON.stringify([this.commander, alarms.map((e) => [e.id, e.acknowledged_at, e.cleared_t, e.floor])]);
    replaceIf(document.getElementById("alarms"), alarmKey, () => alarms.map((e) => {
      const a = this.agents.get(e.agent);
      const acked = e.acknowledged_at !== null;
      const cls = `${e.severity}${acked ? " acknowledged" : ""}${e.cleared_t !== null ? " cleared" : ""}`;
      const place = Number.isFinite(e.x) ? ` at (${e.x.toFixed(1)}, ${e.y.toFixed(1)}) F${e.floor ?? "?"}` : "";
      const item = el("li", { class: cls, dataset: { event: e.id, kind: e.kind },
        onclick: () => this.focusEvent(e) },
      el("strong", {}, EVENT_TEXT[e.kind] || e.kind), ` ${a?.name || e.agent || ""} `,
      el("span", { class: "muted" }, `t ${formatClock(e.t)}${place}`));
      if (e.cleared_t !== null) item.append(el("div", { class: "muted" }, `cleared at ${formatClock(e.cleared_t)}`));
      if (acked) {
        item.append(el("div", { class: "muted ack-by" },
          `acknowledged by ${e.acknowledged_by} at ${formatClock(e.acknowledged_at)}`));
      } else if (this.commander) {
        item.append(el("button", { type: "button", class: "ack",
          onclick: (ev) => { ev.stopPropagation(); this.acknowledge(e); } }, "Acknowledge"));
      }
      return item;
    }));
    const banner = document.getElementById("alarm-banner");
    if (!open.length) { banner.hidden = true; return; }
    const top = open.reduce((best, e) => (BANNER_RANK[e.kind] < BANNER_RANK[best.kind] ? e : best));
    const a = this.agents.get(top.agent);
    banner.hidden = false;
    banner.classList.toggle("pre", top.kind === "pass_prealarm");
    banner.dataset.event = top.id;
    replaceIf(banner, JSON.stringify([top.id, open.length, top.floor]), () => [
      el("span", {}, `${EVENT_TEXT[top.kind] || top.kind}: ${a?.name || top.agent}` +
        `${Number.isFinite(top.floor) ? ` on floor ${top.floor}` : ""}` +
        `${open.length > 1 ? ` (+${open.length - 1} more)` : ""}`),
      el("button", { type: "button", onclick: () => this.focusEvent(top) }, "Show"),
      ...(this.commander ? [el("button", { type: "button", class: "ack",
        onclick: () => this.acknowledge(top) }, "Acknowledge")] : [])]);
  }

  renderOrders() {
    const list = document.getElementById("orders");
    const orders = [...this.orders.values()].sort((a, b) => Number(b.id) - Number(a.id));
    const orderKey = JSON.stringify(orders.slice(0, 30).map((o) => [o.id, o.status, o.answer_text]));
    replaceIf(list, orderKey, () => orders.slice(0, 30).map((o) => {
      const when = o.answered_at ?? o.delivered_at;
      return el("li", { dataset: { order: o.id, status: o.status, agent: o.agent } },
        `${formatClock(o.created_at)} ${ORDER_TEXT[o.kind] || o.kind}`,
        o.waypoint ? ` (${o.waypoint.x.toFixed(1)}, ${o.waypoint.y.toFixed(1)})` : "",
        ` → ${this.agents.get(o.agent)?.name || o.agent}: `, el("strong", {}, o.status),
        when !== null ? el("span", { class: "muted" }, ` at ${formatClock(when)}`) : "",
        o.answer_text ? el("span", { class: "muted" }, ` "${o.answer_text}"`) : "");
    }));
  }

  renderInfrastructure() {
    const f = this.floor;
    this.map.renderInfrastructure({
      landmarks: this.infra.landmarks.filter((l) => (l.floor ?? 0) === f),
      waypoints: this.infra.waypoints.filter((w) => (w.floor ?? 0) === f),
    });
    this.nodes.render(this.network ? [...this.network.values()] : null, f);
  }

  renderDetails() {
    const box = document.getElementById("details");
    const a = this.selected ? this.agents.get(this.selected) : null;
    if (!a) { box.hidden = true; box.dataset.agent = ""; return; }
    box.hidden = false;
    const e = a.est;
    const q = e ? quality(e.var_x, e.cov_xy, e.var_y) : null;
    const rows = [
      ["kind", a.kind],
      ["floor", e ? e.floor : "-"],
      ["activity", e?.activity || "-"],
      ["position", e ? `(${e.x.toFixed(1)}, ${e.y.toFixed(1)}) m ± ${q.radius_m.toFixed(1)} m (2σ)` : "-"],
      ["quality", q ? q.level : "-"],
      ["heading", e ? compass(e.heading) : "-"],
      ["since absolute correction", e ? formatAge(e.since_correction_s) : "-"],
      ["last data", `${formatAge(this.ageOf(a))} ago${this.isStale(a) ? " (stale)" : ""}`],
    ];
    for (const [k, v] of Object.entries(a.info)) rows.push([k, Array.isArray(v) ? v.join(", ") : v]);
    const recent = [...this.events.values()].filter((ev) => ev.agent === a.id)
      .sort((x, y) => (y.t ?? 0) - (x.t ?? 0)).slice(0, 5);
    const actions = [];
    if (this.commander) {
      actions.push(el("button", { type: "button", class: "danger",
        onclick: () => this.order({ kind: "evacuate", agents: [a.id] }) }, "Evacuate"));
      actions.push(el("button", { type: "button",
        onclick: () => this.order({ kind: "checkin", agents: [a.id] }) }, "Check-in request"));
      if (a.kind === "robot") {
        actions.push(el("button", { type: "button", id: "goto-start",
          onclick: () => this.startGoto(a.id) }, "Send to point…"));
      }
    }
    if (box.dataset.agent !== a.id) {
      box.dataset.agent = a.id;
      box.replaceChildren(el("h3", {}, a.name), el("table", { class: "facts" }),
        el("h4", {}, "last events"), el("ol", { class: "alarms recent" }),
        el("div", { class: "actions" }, ...actions,
          el("button", { type: "button", onclick: () => this.select(null) }, "Close")));
    }
    replaceIf(box.querySelector("table.facts"), JSON.stringify(rows),
      () => rows.map(([k, v]) => el("tr", {}, el("td", {}, k), el("td", {}, v))));
    replaceIf(box.querySelector("ol.recent"), JSON.stringify(recent.map((ev) => ev.id)),
      () => (recent.length ? recent.map((ev) => el("li", {},
        `${formatClock(ev.t)} ${EVENT_TEXT[ev.kind] || ev.kind}`)) : [el("li", { class: "muted" }, "none")]));
  }

  // ---- interaction ----------------------------------------------------------------------------

  select(id) {
    this.selected = id;
    this.map.clearFocus();
    const a = id ? this.agents.get(id) : null;
    if (a?.est) {
      if (a.est.floor !== this.floor) this.setFloor(a.est.floor);
      this.map.focus(a.est, null);
    }
    this.scheduleRender();
  }

  async focusEvent(e) {
    const a = this.agents.get(e.agent);
    if (!a) return;
    this.selected = a.id;
    const floor = a.est?.floor ?? e.floor;
    if (Number.isFinite(floor) && floor !== this.floor) this.setFloor(floor);
    const path = await this.api.trail(this.missionId, a.id).catch(() => a.trail);
    this.map.focus(a.est, path.filter((p) => p.floor === this.floor));
    this.scheduleRender();
  }

  async acknowledge(e) {
    try {
      const updated = await this.api.acknowledge(this.missionId, e.id);
      this.events.set(e.id, { ...e, ...updated });
    } catch (err) {
      this.flash(`acknowledge failed: ${err.message}`);
    }
    this.scheduleRender();
  }

  async order(body) {
    try {
      for (const created of await this.api.order(this.missionId, body)) {
        this.orders.set(created.id, created);
      }
      if (body.kind === "goto") this.refreshInfrastructure();
    } catch (err) {
      this.flash(`order refused: ${err.message}`);
    }
    this.scheduleRender();
  }

  startGoto(robotId) {
    this.pendingGoto = robotId;
    const hint = document.getElementById("map-hint");
    hint.textContent = `Click the map where ${this.agents.get(robotId)?.name || robotId} should go (Esc cancels)`;
    hint.hidden = false;
  }

  mapClicked(p) {
    if (!this.pendingGoto) return;
    const robot = this.pendingGoto;
    this.pendingGoto = null;
    document.getElementById("map-hint").hidden = true;
    this.map.pendingTarget(p);
    this.order({ kind: "goto", agents: [robot], waypoint: { x: p.x, y: p.y, floor: this.floor } });
  }

  flash(text) {
    const hint = document.getElementById("map-hint");
    hint.textContent = text;
    hint.hidden = false;
    setTimeout(() => { hint.hidden = true; }, 4000);
  }

  setConnection(state, text) {
    const node = document.getElementById("connection");
    node.dataset.state = state;
    node.textContent = text || state;
  }

  bindControls() {
    const layers = { "layer-plan": "plan", "layer-landmarks": "landmarks", "layer-nodes": "nodes",
      "layer-waypoints": "waypoints", "layer-trails": "trails" };
    for (const [id, name] of Object.entries(layers)) {
      document.getElementById(id).onchange = (ev) => this.map.setLayerVisible(name, ev.target.checked);
    }
    document.getElementById("mission-select").onchange = (ev) => this.openMission(ev.target.value);
    document.getElementById("order-evacuate-all").onclick = () => this.order({ kind: "evacuate" });
    document.getElementById("order-evacuate-floor").onclick = () => this.order({ kind: "evacuate", floor: this.floor });
    document.getElementById("order-checkin-all").onclick = () => this.order({ kind: "checkin" });
    document.addEventListener("keydown", (ev) => {
      if (ev.key === "Escape" && this.pendingGoto) {
        this.pendingGoto = null;
        document.getElementById("map-hint").hidden = true;
      }
    });
    const slider = document.getElementById("replay-time");
    slider.oninput = () => this.seek(Number(slider.value));
    document.getElementById("replay-toggle").onclick = () => this.togglePlay();
    document.getElementById("replay-speed").onchange = (ev) => { this.replay.speed = Number(ev.target.value); };
    document.getElementById("replay-live").onclick = () => this.goLive();
    document.getElementById("replay-events").onchange = (ev) => {
      if (ev.target.value !== "") this.seek(Number(ev.target.value));
      ev.target.value = "";
    };
  }

  // ---- replay ---------------------------------------------------------------------------------

  renderReplayBar() {
    const slider = document.getElementById("replay-time");
    const end = this.replay.active ? this.replay.end : Math.max(this.missionTime ?? 0, 0);
    slider.max = String(end);
    if (!this.replay.active) slider.value = String(end);
    document.getElementById("replay-label").textContent = this.replay.active
      ? `replay ${formatClock(this.replay.t)} / ${formatClock(end)}` : "live";
    document.getElementById("replay-toggle").textContent = this.replay.playing ? "⏸" : "▶";
    const select = document.getElementById("replay-events");
    const events = [...this.events.values()].sort((a, b) => a.t - b.t);
    if (!this.replay.active && select.options.length !== events.length + 1) {
      select.replaceChildren(el("option", { value: "" }, "jump to event…"), ...events.map((e) =>
        el("option", { value: String(e.t) }, `${formatClock(e.t)} ${EVENT_TEXT[e.kind] || e.kind} ${this.agents.get(e.agent)?.name || ""}`)));
    }
  }

  async seek(t) {
    if (!this.replay.active) {
      this.replay.active = true;
      this.replay.end = this.missionNow();
      this.setConnection("replay", "replay");
    }
    this.replay.t = t;
    this.replay.pending = (this.replay.pending || 0) + 1;
    try {
      const picture = await this.api.replayAt(this.missionId, t);
      if (!this.replay.active || this.replay.t !== t) return;
      this.applySnapshot(picture, { replay: true });
      this.replay.shownT = t;
      this.scheduleRender();
    } finally {
      this.replay.pending -= 1;
    }
  }

  togglePlay() {
    if (this.replay.playing) { this.stopReplayTimer(); this.scheduleRender(); return; }
    if (!this.replay.active) this.seek(0);
    this.replay.playing = true;
    let last = performance.now();
    const stepMs = 250;
    this.replay.timer = setInterval(() => {
      if (this.replay.pending) return;
      const now = performance.now();
      const t = Math.min(this.replay.t + ((now - last) / 1000) * this.replay.speed, this.replay.end);
      last = now;
      this.seek(t);
      if (t >= this.replay.end) this.stopReplayTimer();
    }, stepMs);
    this.scheduleRender();
  }

  stopReplayTimer() {
    this.replay.playing = false;
    clearInterval(this.replay.timer);
    this.replay.timer = null;
  }

  async goLive() {
    this.stopReplayTimer();
    this.replay.active = false;
    this.applySnapshot(await this.api.snapshot(this.missionId));
    this.setConnection("live");
    this.scheduleRender();
  }
}
