// Pure geometry and formatting helpers of the dashboard (no DOM, no Leaflet).
// Local mission frame: x east, y north, metres (hrtls/frames.py); Leaflet CRS.Simple takes
// [lat, lng] = [y, x].

// Thresholds of the quality indicator on the 2-sigma radius of the worst axis, metres.
export const QUALITY_GOOD_M = 2.0;
export const QUALITY_FAIR_M = 5.0;

// Semi-axes (m) and orientation (rad from +x, counter-clockwise) of the k-sigma ellipse of the
// 2x2 covariance [[varX, covXY], [covXY, varY]] (m^2): its eigenvalues
// lambda = (varX + varY) / 2 +- sqrt(((varX - varY) / 2)^2 + covXY^2), semi-axes k sqrt(lambda),
// the major axis at 0.5 atan2(2 covXY, varX - varY).
export function ellipseAxes(varX, covXY, varY, k = 2) {
  const mean = (varX + varY) / 2;
  const diff = (varX - varY) / 2;
  const root = Math.sqrt(diff * diff + covXY * covXY);
  const major = Math.max(mean + root, 0);
  const minor = Math.max(mean - root, 0);
  const angle = 0.5 * Math.atan2(2 * covXY, varX - varY);
  return { a: k * Math.sqrt(major), b: k * Math.sqrt(minor), angle };
}

// Scale k of the ellipse holding probability p of a 2-D gaussian: the points d with
// d^T C^-1 d <= k^2 have probability p when k^2 = -2 ln(1 - p) (the chi-square CDF with 2
// degrees of freedom is 1 - exp(-x / 2)); p = 0.95 gives k = 2.4477.
export function chi2Scale2d(p) {
  return Math.sqrt(-2 * Math.log(1 - p));
}

// Semi-axes a >= b (m), orientation of a (rad from +x, counter-clockwise) and scale k of the
// p-probability ellipse of the 2x2 covariance [[xx, xy], [yx, yy]] (m^2, symmetrized).
export function covarianceEllipse(cov, p = 0.95) {
  const k = chi2Scale2d(p);
  return { ...ellipseAxes(cov[0][0], 0.5 * (cov[0][1] + cov[1][0]), cov[1][1], k), k };
}

// Outline of the k-sigma ellipse centred on (x, y) as n [y, x] vertices for Leaflet.
export function ellipseLatLngs(x, y, varX, covXY, varY, k = 2, n = 40) {
  const { a, b, angle } = ellipseAxes(varX, covXY, varY, k);
  const c = Math.cos(angle);
  const s = Math.sin(angle);
  const out = [];
  for (let i = 0; i < n; i += 1) {
    const t = (2 * Math.PI * i) / n;
    const u = a * Math.cos(t);
    const v = b * Math.sin(t);
    out.push([y + s * u + c * v, x + c * u - s * v]);
  }
  return out;
}

// Quality of an estimate from its covariance: the 2-sigma radius of the worst axis and a level.
export function quality(varX, covXY, varY) {
  const { a } = ellipseAxes(varX, covXY, varY, 2);
  let level = "poor";
  if (a <= QUALITY_GOOD_M) level = "good";
  else if (a <= QUALITY_FAIR_M) level = "fair";
  return { radius_m: a, level };
}

// End point of a heading arrow of length_m from (x, y); heading from +x, counter-clockwise.
export function headingTip(x, y, headingRad, lengthM) {
  return [y + lengthM * Math.sin(headingRad), x + lengthM * Math.cos(headingRad)];
}

// "12 s", "3 min 05 s", "1 h 02 min" for an age in seconds; "-" when unknown.
export function formatAge(seconds) {
  if (seconds === null || seconds === undefined || !Number.isFinite(seconds)) return "-";
  const s = Math.max(0, Math.round(seconds));
  if (s < 60) return `${s} s`;
  if (s < 3600) return `${Math.floor(s / 60)} min ${String(s % 60).padStart(2, "0")} s`;
  return `${Math.floor(s / 3600)} h ${String(Math.floor((s % 3600) / 60)).padStart(2, "0")} min`;
}

// Mission time (s) as m:ss.
export function formatClock(seconds) {
  if (!Number.isFinite(seconds)) return "-";
  const s = Math.max(0, Math.floor(seconds));
  return `${Math.floor(s / 60)}:${String(s % 60).padStart(2, "0")}`;
}

// Web mercator (EPSG:3857): sphere radius (WGS-84's semi-major axis), m; WGS-84's e^2.
export const MERCATOR_R_M = 6378137;
const WGS84_E2 = 6.69437999014e-3;

// Local mission metres on web-mercator tiles. The georeference anchors local (0, 0) at
// (lat_deg, lon_deg), with local x rotated rotation_rad counter-clockwise from east
// (hrtls/frames.py). Near the anchor, mercator metres are the anchor's plus kx * east and
// ky * north, from the derivatives of EPSG:3857 on WGS-84 coordinates: kx = R / (N cos(lat)),
// ky = R / (M cos(lat)), N and M the ellipsoid's radii of curvature. Returns the rotation
// local (x, y) <-> (east, north) and the coefficients [a, b, c, d] of the pixel transformation
// pixel = scale(zoom) * (a * east + b, c * north + d), equal to EPSG:3857's at the anchor.
export function mercatorFrame({ lat_deg: lat, lon_deg: lon, rotation_rad: rot = 0 }) {
  const phi = (lat * Math.PI) / 180;
  const x0 = MERCATOR_R_M * ((lon * Math.PI) / 180);
  const y0 = MERCATOR_R_M * Math.log(Math.tan(Math.PI / 4 + phi / 2));
  const w = 1 - WGS84_E2 * Math.sin(phi) ** 2;
  const primeVertical = MERCATOR_R_M / Math.sqrt(w);
  const meridian = (MERCATOR_R_M * (1 - WGS84_E2)) / w ** 1.5;
  const kx = MERCATOR_R_M / (primeVertical * Math.cos(phi));
  const ky = MERCATOR_R_M / (meridian * Math.cos(phi));
  const u = 0.5 / (Math.PI * MERCATOR_R_M);
  const c = Math.cos(rot);
  const s = Math.sin(rot);
  return {
    toEastNorth: (x, y) => [c * x - s * y, s * x + c * y],
    fromEastNorth: (e, n) => [c * e + s * n, -s * e + c * n],
    transformation: [u * kx, u * x0 + 0.5, -u * ky, -u * y0 + 0.5],
    // zoom levels between CRS.Simple (1 px per metre at zoom 0) and this frame
    zoomOffset: -Math.log2(256 * u * kx),
  };
}
