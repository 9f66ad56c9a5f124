"""The page shell: it loads offline from the package; its pure geometry module is exact."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hrtls.web import LEAFLET_VERSION


def test_page_loads_offline_and_shows_only_the_login(page, page_log, service, screenshot):
    page.goto(service.url + "/")
    page.wait_for_selector("body[data-ready='1']")
    assert page.is_visible("#login-form")
    assert page.is_hidden("#app")
    assert page.is_hidden("#map")
    sheets = page.evaluate(
        "() => [...document.styleSheets].map(s => [s.href, s.cssRules.length])")
    leaflet = [n for href, n in sheets if href.endswith("vendor/leaflet/leaflet.css")]
    assert leaflet and leaflet[0] > 50
    version = page.evaluate(
        "async () => (await import('./vendor/leaflet/leaflet-src.esm.js')).version")
    assert version == LEAFLET_VERSION
    screenshot(page, "shell_login")
    page_log.assert_clean()


def test_quality_levels_hand_computed(geometry):
    # diagonal covariance: 2-sigma radius = 2 * sqrt(max variance)
    cases = geometry.evaluate("""async () => {
        const g = await import('./js/geometry.js');
        return [g.quality(0.25, 0, 1.0), g.quality(4.0, 0, 1.0), g.quality(9.0, 0, 1.0),
                g.ellipseAxes(4.0, 0, 1.0, 2), g.ellipseAxes(1.0, 0, 4.0, 1)];
    }""")
    assert cases[0] == {"radius_m": 2.0, "level": "good"}
    assert cases[1] == {"radius_m": 4.0, "level": "fair"}
    assert cases[2] == {"radius_m": 6.0, "level": "poor"}
    assert cases[3]["a"] == pytest.approx(4.0) and cases[3]["b"] == pytest.approx(2.0)
    assert cases[3]["angle"] == pytest.approx(0.0)
    assert cases[4]["a"] == pytest.approx(2.0)
    assert abs(cases[4]["angle"]) == pytest.approx(math.pi / 2)


covariances = st.tuples(st.floats(1e-4, 100), st.floats(1e-4, 100), st.floats(-0.99, 0.99)).map(
    lambda t: (t[0], t[2] * math.sqrt(t[0] * t[1]), t[1]))


# the page only hosts the pure module; it keeps no state between examples
@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(covariances, min_size=1, max_size=10))
def test_ellipse_matches_numpy_eigendecomposition(geometry, covs):
    out = geometry.evaluate("""async (covs) => {
        const g = await import('./js/geometry.js');
        return covs.map(([vx, cxy, vy]) => [g.ellipseAxes(vx, cxy, vy, 2),
                                            g.ellipseLatLngs(3, -2, vx, cxy, vy, 2, 16)]);
    }""", [list(c) for c in covs])
    for (vx, cxy, vy), (axes, outline) in zip(covs, out, strict=True):
        cov = np.array([[vx, cxy], [cxy, vy]])
        w, v = np.linalg.eigh(cov)
        assert axes["a"] == pytest.approx(2 * math.sqrt(w[1]), rel=1e-6, abs=1e-9)
        assert axes["b"] == pytest.approx(2 * math.sqrt(max(w[0], 0)), rel=1e-5, abs=1e-6)
        major = np.array([math.cos(axes["angle"]), math.sin(axes["angle"])])
        if w[1] - w[0] > 1e-3 * w[1]:  # the major axis is defined
            assert abs(major @ v[:, 1]) == pytest.approx(1.0, abs=1e-4)
        # every outline vertex lies on the Mahalanobis distance-2 contour
        pts = np.array([[p[1] - 3, p[0] + 2] for p in outline])
        d2 = np.einsum("ni,ij,nj->n", pts, np.linalg.inv(cov), pts)
        np.testing.assert_allclose(d2, 4.0, rtol=1e-6)


@settings(max_examples=20, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(lat=st.floats(-70, 70), lon=st.floats(-179, 179), rot=st.floats(-math.pi, math.pi),
       xy=st.lists(st.tuples(st.floats(-300, 300), st.floats(-300, 300)), min_size=1,
                   max_size=8))
def test_mercator_frame_matches_the_exact_geodetic_placement(geometry, lat, lon, rot, xy):
    """Local metres -> web-mercator pixel fraction against pymap3d + the EPSG:3857 formulas."""
    from hrtls.frames import Georeference

    out = geometry.evaluate("""async ([georef, pts]) => {
        const g = await import('./js/geometry.js');
        const f = g.mercatorFrame(georef);
        const [a, b, c, d] = f.transformation;
        return pts.map(([x, y]) => {
          const [e, n] = f.toEastNorth(x, y);
          const back = f.fromEastNorth(e, n);
          return [a * e + b, c * n + d, back[0], back[1]];
        });
    }""", [{"lat_deg": lat, "lon_deg": lon, "rotation_rad": rot}, [list(p) for p in xy]])
    geo = Georeference(lat, lon, 0.0, rot).to_wgs84(np.array(xy))
    phi = np.radians(geo[:, 0])
    want_u = (geo[:, 1] + 180.0) / 360.0
    want_v = (1.0 - np.log(np.tan(phi) + 1.0 / np.cos(phi)) / math.pi) / 2.0
    got = np.array(out)
    # first-order exact: what is left grows with the distance squared (3 cm at 300 m); one pixel
    # at zoom 22 is 2.4e-10 of the world
    dist = np.hypot(*np.array(xy).T) / (2 * math.pi * 6378137 * np.cos(np.radians(lat)))
    np.testing.assert_array_less(np.abs(got[:, 0] - want_u), 2e-4 * dist + 1e-12)
    np.testing.assert_array_less(np.abs(got[:, 1] - want_v), 2e-4 * dist + 1e-12)
    np.testing.assert_allclose(got[:, 2:], np.array(xy), atol=1e-9)
