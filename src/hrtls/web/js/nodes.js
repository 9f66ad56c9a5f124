// The sensor-network layer: the mission estimator's node states (GET /missions/{m}/network
// shape, from the snapshot and the socket's deltas) on the map and in the side panel.
// A localized node is drawn at its estimate with its 95 % ellipse: the points d with
// d^T C^-1 d <= chi2_2(0.95) = 5.991 of its position covariance C (local x east, y north, m^2;
// js/geometry.js). A node without a position (heard but not localized, or declared and never
// heard) is listed in the panel, never hidden.

import * as L from "../vendor/leaflet/leaflet-src.esm.js";
import { covarianceEllipse, ellipseLatLngs, formatClock } from "./geometry.js";

export const NODE_ELLIPSE_P = 0.95;
const STATE_COLOR = { localized: "#3fb950", heard: "#d29922", declared: "#6e7681" };
const STATE_TEXT = { localized: "localized", heard: "heard, not localized", declared: "never heard" };

function cssId(id) { return String(id).replace(/[^A-Za-z0-9_-]/g, "_"); }

// localized (has a position) / heard (readings, no position) / declared (never heard).
export function nodeState(n) {
  if (n.localized && Number.isFinite(n.x) && Number.isFinite(n.y)) return "localized";
  return n.readings > 0 ? "heard" : "declared";
}

// Counts over the network: declared nodes, localized and heard ones (localized included), and
// heard nodes not in the declared list.
export function networkCounts(nodes) {
  const out = { declared: 0, localized: 0, heard: 0, undeclared: 0 };
  for (const n of nodes) {
    if (n.declared) out.declared += 1; else out.undeclared += 1;
    if (nodeState(n) === "localized") out.localized += 1;
    if (n.readings > 0) out.heard += 1;
  }
  return out;
}

export function countText(nodes) {
  if (nodes === null) return "nodes: no sensor network declared";
  const c = networkCounts(nodes);
  return `nodes: ${c.localized} localized of ${c.declared} declared, ${c.heard} heard` +
    (c.undeclared ? ` (${c.undeclared} not declared)` : "");
}

function readingsText(n) {
  return `${n.readings} reading${n.readings === 1 ? "" : "s"} in ${n.passes} pass${n.passes === 1 ? "" : "es"}`;
}

// Tooltip of a localized node: id, 1-sigma of the worst axis, the 95 % semi-axes, readings
// and passes, and the mission time of the estimate.
export function nodeLabel(n) {
  const e = covarianceEllipse(n.cov, NODE_ELLIPSE_P);
  return `node ${n.id}${n.declared ? "" : " (not declared)"}: σ ${n.sigma_m.toFixed(2)} m, ` +
    `95 % ellipse ${e.a.toFixed(2)} × ${e.b.toFixed(2)} m, ${readingsText(n)}, ` +
    `estimated at t ${formatClock(n.t)}`;
}

export class NodeLayer {
  // mapView: the MapView (its nodeLayer group is where the nodes are drawn);
  // count, list: the panel's count line and list of the nodes without a position.
  constructor(mapView, { count, list }) {
    this.mapView = mapView;
    this.count = count;
    this.list = list;
    this.group = null;
    this.key = null;
    this.listKey = null;
  }

  // nodes: [node] of the network, or null without a network; floor: the shown floor.
  render(nodes, floor) {
    this.count.textContent = countText(nodes);
    this.renderList(nodes || []);
    const shown = (nodes || []).filter((n) => nodeState(n) === "localized" && (n.floor ?? 0) === floor);
    const group = this.mapView.nodeLayer;
    const key = JSON.stringify(shown.map((n) => [n.id, n.x, n.y, n.cov, n.t, n.readings, n.passes]));
    if (group === this.group && key === this.key) return;
    this.group = group;
    this.key = key;
    group.clearLayers();
    for (const n of shown) {
      const id = cssId(n.id);
      const color = STATE_COLOR.localized;
      const cov = n.cov;
      const k = covarianceEllipse(cov, NODE_ELLIPSE_P).k;
      L.polygon(ellipseLatLngs(n.x, n.y, cov[0][0], 0.5 * (cov[0][1] + cov[1][0]), cov[1][1], k), {
        color, weight: 1, fillColor: color, fillOpacity: 0.08, interactive: false,
        className: `node-ellipse node-id-${id}`,
      }).addTo(group);
      L.circleMarker([n.y, n.x], { radius: 4, color, weight: 1, fillColor: color, fillOpacity: 0.9,
        className: `node-marker node-localized node-id-${id}` })
        .bindTooltip(nodeLabel(n), { className: "node-tooltip" }).addTo(group);
    }
  }

  // The nodes without a position: heard ones first, then the never heard, by id.
  renderList(nodes) {
    const rows = nodes.filter((n) => nodeState(n) !== "localized")
      .sort((a, b) => (nodeState(a) === nodeState(b) ? String(a.id).localeCompare(String(b.id))
        : (nodeState(a) === "heard" ? -1 : 1)));
    const key = JSON.stringify(rows.map((n) => [n.id, n.readings, n.passes, n.reason, n.t, n.declared]));
    if (key === this.listKey) return;
    this.listKey = key;
    this.list.replaceChildren(...rows.map((n) => {
      const state = nodeState(n);
      const li = document.createElement("li");
      li.dataset.node = n.id;
      li.dataset.state = state;
      const dot = document.createElement("span");
      dot.className = "quality";
      dot.style.background = STATE_COLOR[state];
      const detail = document.createElement("span");
      detail.className = "muted";
      detail.textContent = state === "heard"
        ? ` ${STATE_TEXT.heard}: ${readingsText(n)}${n.reason ? `, ${n.reason}` : ""} (t ${formatClock(n.t)})`
        : ` ${STATE_TEXT.declared}`;
      li.append(dot, `${n.id}${n.declared ? "" : " (not declared)"}`, detail);
      return li;
    }));
  }
}
