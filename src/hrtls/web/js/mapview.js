// The Leaflet map in local mission metres ([lat, lng] = [y, x]): CRS.Simple, or on a
// web-mercator base map for a georeferenced mission when the service names a tile source.

import * as L from "../vendor/leaflet/leaflet-src.esm.js";
import { ellipseLatLngs, formatAge, headingTip, mercatorFrame, quality } from "./geometry.js";

const PLAN_STYLE = {
  wall: { color: "#c9d1d9", weight: 2, fill: false },
  door: { color: "#3fb950", weight: 3, fill: false },
  room: { color: "#30363d", weight: 1, fillColor: "#161b22", fillOpacity: 0.6 },
  corridor: { color: "#30363d", weight: 1, fillColor: "#1c2430", fillOpacity: 0.6 },
  stairs: { color: "#a371f7", weight: 1, fillColor: "#a371f7", fillOpacity: 0.25 },
  exit: { color: "#3fb950", weight: 2, fillColor: "#3fb950", fillOpacity: 0.3 },
};
const QUALITY_COLOR = { good: "#3fb950", fair: "#d29922", poor: "#f85149", stale: "#6e7681" };
const ROBOT_COLOR = "#58a6ff";

function cssId(id) { return String(id).replace(/[^A-Za-z0-9_-]/g, "_"); }

// A CRS whose coordinates are local metres ([y, x]) and whose pixels are web-mercator pixels.
function localMercatorCrs(georeference) {
  const f = mercatorFrame(georeference);
  return L.Util.extend({}, L.CRS, {
    code: "hrtls:local-mercator",
    projection: {
      project: (ll) => L.point(...f.toEastNorth(ll.lng, ll.lat)),
      unproject: (p) => { const [x, y] = f.fromEastNorth(p.x, p.y); return L.latLng(y, x); },
      bounds: L.bounds([-2e7, -2e7], [2e7, 2e7]),
    },
    transformation: L.transformation(...f.transformation),
    distance: (a, b) => Math.hypot(b.lng - a.lng, b.lat - a.lat),
    infinite: true,
    zoomOffset: f.zoomOffset,
  });
}

export class MapView {
  constructor(element, { onMapClick, onAgentClick }) {
    this.element = element;
    this.onMapClick = onMapClick;
    this.onAgentClick = onAgentClick;
    this.frameKey = null;
    this.build(L.CRS.Simple, null);
  }

  // (Re)create the map in a CRS; Leaflet cannot change the CRS of a map.
  build(crs, basemap) {
    if (this.map) this.map.remove();
    this.zoomOffset = crs.zoomOffset || 0;
    const z = this.zoomOffset;
    this.map = L.map(this.element, {
      crs, minZoom: -4 + z, maxZoom: 7 + z, zoomSnap: 0.25, attributionControl: Boolean(basemap),
    });
    this.map.setView([0, 0], 2 + z);
    if (basemap) {
      this.baseLayer = L.tileLayer(basemap.url, {
        maxNativeZoom: basemap.max_zoom, maxZoom: 7 + z, attribution: basemap.attribution,
        className: "basemap",
      }).addTo(this.map);
    } else {
      this.baseLayer = null;
    }
    L.control.scale({ imperial: false, metric: true }).addTo(this.map);
    this.map.on("click", (e) => this.onMapClick({ x: e.latlng.lng, y: e.latlng.lat }));
    this.planLayer = L.layerGroup().addTo(this.map);
    this.infraLayer = L.layerGroup().addTo(this.map);
    this.nodeLayer = L.layerGroup().addTo(this.map);
    this.waypointLayer = L.layerGroup().addTo(this.map);
    this.trailLayer = L.layerGroup().addTo(this.map);
    this.agentLayer = L.layerGroup().addTo(this.map);
    this.focusLayer = L.layerGroup().addTo(this.map);
    this.agents = new Map();
    this.infraKey = null;
    this.fitted = false;
  }

  // The mission's frame: on the base map when the mission is georeferenced and the service
  // has a tile source, else local metres alone.
  setFrame(georeference, basemap) {
    const onTiles = Boolean(georeference && basemap);
    const key = onTiles ? JSON.stringify([georeference, basemap]) : "simple";
    if (key === this.frameKey) return;
    this.frameKey = key;
    this.build(onTiles ? localMercatorCrs(georeference) : L.CRS.Simple, onTiles ? basemap : null);
  }

  setLayerVisible(name, visible) {
    const layer = { plan: this.planLayer, landmarks: this.infraLayer, nodes: this.nodeLayer,
      waypoints: this.waypointLayer, trails: this.trailLayer }[name];
    if (!layer) return;
    if (visible) layer.addTo(this.map); else layer.remove();
  }

  // GeoJSON FeatureCollection in local metres (properties.floor, an int, and properties.kind)
  // and the floors' plan images ({index, image: {url, bounds} | null}).
  setFloorplan(collection, floors = []) {
    this.floorplan = collection;
    this.floorImages = new Map(floors.filter((f) => f.image).map((f) => [f.index, f.image]));
    this.fitted = false;
  }

  drawFloor(floor) {
    this.planLayer.clearLayers();
    const image = this.floorImages?.get(floor);
    if (image) {
      // the browser sends the session cookie with the image request (same origin)
      L.imageOverlay(image.url, image.bounds, { className: "plan-image", opacity: 0.85 })
        .addTo(this.planLayer);
      if (!this.fitted) {
        this.map.fitBounds(image.bounds, { padding: [20, 20] });
        this.fitted = true;
      }
    }
    if (!this.floorplan) return;
    const features = (this.floorplan.features || []).filter(
      (f) => (f.properties?.floor ?? 0) === floor);
    const layer = L.geoJSON({ type: "FeatureCollection", features }, {
      coordsToLatLng: (c) => L.latLng(c[1], c[0]),
      style: (f) => ({ ...(PLAN_STYLE[f.properties?.kind] || PLAN_STYLE.wall),
        className: `plan plan-${f.properties?.kind || "wall"}` }),
      onEachFeature: (f, l) => {
        if (f.properties?.name) l.bindTooltip(f.properties.name, { sticky: true });
      },
    });
    layer.addTo(this.planLayer);
    if (!this.fitted && features.length) {
      this.map.fitBounds(layer.getBounds(), { padding: [20, 20] });
      this.fitted = true;
    }
  }

  fitToPoints(points) {
    if (this.fitted || !points.length) return;
    const bounds = L.latLngBounds(points.map((p) => [p.y, p.x]));
    this.map.fitBounds(bounds.pad(0.5), { maxZoom: 3 + this.zoomOffset });
    this.fitted = true;
  }

  // views: [{id, name, kind, est, trail, stale, ageS, selected}] of the shown floor.
  renderAgents(views) {
    const seen = new Set();
    for (const v of views) {
      seen.add(v.id);
      let g = this.agents.get(v.id);
      if (!g) {
        g = this.createAgent(v);
        this.agents.set(v.id, g);
      }
      this.updateAgent(g, v);
    }
    for (const [id, g] of this.agents) {
      if (!seen.has(id)) {
        for (const layer of [g.ellipse, g.dot, g.arrow, g.trail]) layer.remove();
        this.agents.delete(id);
      }
    }
  }

  createAgent(v) {
    const id = cssId(v.id);
    const g = {
      ellipse: L.polygon([[0, 0]], { weight: 1, fillOpacity: 0.15, interactive: false,
        className: `agent-ellipse agent-${id}` }),
      trail: L.polyline([], { weight: 2, opacity: 0.6, interactive: false,
        className: `agent-trail agent-${id}` }),
      arrow: L.polyline([[0, 0], [0, 0]], { weight: 3, interactive: false,
        className: `agent-heading agent-${id}` }),
      dot: L.circleMarker([0, 0], { radius: v.kind === "robot" ? 7 : 6, weight: 2,
        fillOpacity: 1, className: `agent-dot agent-${id}` }),
    };
    g.dot.bindTooltip(v.name, { permanent: true, direction: "right", offset: [8, 0],
      className: "agent-label" });
    g.dot.on("click", (e) => { L.DomEvent.stopPropagation(e); this.onAgentClick(v.id); });
    g.ellipse.addTo(this.agentLayer);
    g.trail.addTo(this.trailLayer);
    g.arrow.addTo(this.agentLayer);
    g.dot.addTo(this.agentLayer);
    return g;
  }

  // Redraws only what changed since the agent's last update (300 agents re-render every delta).
  updateAgent(g, v) {
    const e = v.est;
    const trail = v.trail || [];
    const lastTrail = trail[trail.length - 1];
    const label = v.stale ? `${v.name} (${formatAge(v.ageS)} old)` : v.name;
    const key = [e.t, e.x, e.y, e.var_x, e.cov_xy, e.var_y, e.heading, v.stale, v.selected,
      trail.length, lastTrail?.t, trail[0]?.t, label].join("|");
    if (g.key === key) return;
    g.key = key;
    const q = quality(e.var_x, e.cov_xy, e.var_y);
    const color = v.stale ? QUALITY_COLOR.stale
      : (v.kind === "robot" ? ROBOT_COLOR : QUALITY_COLOR[q.level]);
    const style = [color, v.stale, v.selected].join("|");
    g.ellipse.setLatLngs(ellipseLatLngs(e.x, e.y, e.var_x, e.cov_xy, e.var_y, 2));
    g.dot.setLatLng([e.y, e.x]);
    const heading = Number.isFinite(e.heading) ? e.heading : 0;
    g.arrow.setLatLngs([[e.y, e.x], headingTip(e.x, e.y, heading, 1.5)]);
    g.trail.setLatLngs(trail.map((p) => [p.y, p.x]));
    if (g.style !== style || g.headingShown !== Number.isFinite(e.heading)) {
      g.style = style;
      g.headingShown = Number.isFinite(e.heading);
      g.ellipse.setStyle({ color, fillColor: color, dashArray: v.stale ? "4 4" : null });
      g.dot.setStyle({ color: v.selected ? "#ffffff" : color, fillColor: color });
      g.arrow.setStyle({ color, opacity: g.headingShown ? 1 : 0 });
      g.trail.setStyle({ color });
    }
    if (g.label !== label) {
      g.label = label;
      g.dot.setTooltipContent(label);
      const tip = g.dot.getTooltip()?.getElement();
      if (tip) tip.classList.toggle("stale", Boolean(v.stale));
    }
    g.dotElement = g.dot.getElement();
    if (g.dotElement) {
      g.dotElement.dataset.agent = v.id;
      g.dotElement.dataset.x = e.x.toFixed(3);
      g.dotElement.dataset.y = e.y.toFixed(3);
      g.dotElement.dataset.stale = v.stale ? "1" : "0";
      g.dotElement.dataset.quality = q.level;
      g.dotElement.dataset.radius = q.radius_m.toFixed(3);
    }
  }

  // Landmarks [{id, kind, x, y, floor, message}] and way points [{robot, points: [{x, y}]}],
  // of the shown floor (the sensor nodes: js/nodes.js, in nodeLayer).
  renderInfrastructure({ landmarks, waypoints }) {
    const key = JSON.stringify([landmarks, waypoints]);
    if (key === this.infraKey) return;
    this.infraKey = key;
    this.infraLayer.clearLayers();
    this.waypointLayer.clearLayers();
    for (const lm of landmarks) {
      const isTag = lm.kind === "rfid";
      const color = isTag ? "#f0883e" : "#db61a2";
      if (lm.accuracy_m) {
        L.circle([lm.y, lm.x], { radius: lm.accuracy_m, weight: 1, color, opacity: 0.5,
          dashArray: "2 4", fill: false, interactive: false }).addTo(this.infraLayer);
      }
      const h = 0.35;
      const m = L.polygon([[lm.y + h, lm.x], [lm.y, lm.x + h], [lm.y - h, lm.x], [lm.y, lm.x - h]], {
        weight: 2, color, fillColor: color, fillOpacity: 0.9,
        className: `landmark landmark-${cssId(lm.id)}`,
      });
      m.bindTooltip(`${isTag ? "RFID tag" : lm.kind} ${lm.id}${lm.message ? `: ${lm.message}` : ""}`);
      m.addTo(this.infraLayer);
    }
    for (const w of waypoints) {
      const pts = w.points.map((p) => [p.y, p.x]);
      L.polyline(pts, { color: ROBOT_COLOR, weight: 1, dashArray: "6 4",
        className: "robot-plan" }).addTo(this.waypointLayer);
      for (const p of pts) {
        L.circleMarker(p, { radius: 3, color: ROBOT_COLOR, weight: 1, fillOpacity: 0.4,
          className: "robot-waypoint" }).addTo(this.waypointLayer);
      }
    }
  }

  // Centre on an agent with its walked path (the way to reach it) highlighted.
  focus(est, path) {
    this.focusLayer.clearLayers();
    if (path && path.length > 1) {
      L.polyline(path.map((p) => [p.y, p.x]), { color: "#ffffff", weight: 4, opacity: 0.8,
        dashArray: "2 6", className: "focus-path" }).addTo(this.focusLayer);
    }
    if (est) {
      L.polygon(ellipseLatLngs(est.x, est.y, est.var_x, est.cov_xy, est.var_y, 2), {
        color: "#ffffff", weight: 2, fill: false, className: "focus-ellipse" }).addTo(this.focusLayer);
      this.map.setView([est.y, est.x], Math.max(this.map.getZoom(), 3 + this.zoomOffset));
    }
  }

  clearFocus() { this.focusLayer.clearLayers(); }

  pendingTarget(point) {
    this.focusLayer.clearLayers();
    if (point) {
      L.circleMarker([point.y, point.x], { radius: 8, color: ROBOT_COLOR, weight: 2,
        className: "goto-target" }).addTo(this.focusLayer);
    }
  }
}
