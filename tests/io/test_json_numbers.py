"""GeoJSON numbers formatted by Arrow: the text of ``json.dumps``, to the character."""

import json
import math
import warnings

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from hrtls.data import StepEvents, Trajectory
from hrtls.io.geojson import LOCAL_TYPE, geojson_document, write_local_geojson
from hrtls.io.jsonstream import float_text, numbers_text

EDGES = [0.0, -0.0, 1.0, 1e-4, float(np.nextafter(1e-4, 0)), 1e15, 1e16,
         float(np.nextafter(1e16, 0)), 9999999999999998.0, 123456789012345.6, 5e-324, 0.1 + 0.2,
         1e-7, 2.5e-5, 1.7976931348623157e308, math.nan, math.inf, -math.inf]


def _json(x: float) -> str:
    return repr(x) if math.isfinite(x) else "null"


@given(st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=200))
def test_float_text_is_the_text_of_json_dumps(values):
    values = values + EDGES
    assert float_text(np.array(values)).to_pylist() == [_json(v) for v in values]


@given(st.lists(st.floats(min_value=-1e17, max_value=1e17), max_size=200),
       st.integers(-12, 17))
def test_float_text_over_magnitudes(values, exponent):
    scaled = [v * 10.0 ** exponent for v in values]
    scaled = [v for v in scaled if math.isfinite(v)]
    assert float_text(np.array(scaled)).to_pylist() == [_json(v) for v in scaled]


@given(hnp.arrays(np.float64, hnp.array_shapes(min_dims=2, max_dims=2, max_side=40),
                  elements=st.floats(allow_nan=False, allow_infinity=False)))
def test_numbers_text_of_rows_is_json_dumps(values):
    assert numbers_text(values) == json.dumps(values.tolist())[1:-1]
    assert numbers_text(values.ravel()) == json.dumps(values.ravel().tolist())[1:-1]


@settings(max_examples=30, deadline=None)
@given(n=st.integers(1, 60), steps_n=st.integers(0, 20), scale=st.sampled_from([1e-6, 1.0, 1e17]),
       seed=st.integers(0, 2**16))
def test_geojson_text_made_by_arrow_is_json_dumps(n, steps_n, scale, seed, tmp_path_factory):
    rng = np.random.default_rng(seed)
    heading = rng.uniform(-3, 3, n)
    heading[rng.random(n) < 0.3] = np.nan
    xyz = rng.normal(0, 5, (n, 3)) * scale
    xyz[rng.random((n, 3)) < 0.2] = 0.0
    tr = Trajectory.build(t=np.arange(n) * 0.1, xyz=xyz, heading_rad=heading,
                          activity=rng.integers(-1, 5, n))
    t_start = np.sort(rng.uniform(0, n * 0.1, steps_n))
    steps = StepEvents.build(t_start=t_start, t_end=t_start + 0.5,
                             length_m=rng.uniform(0, 1, steps_n) * scale,
                             heading_rad=np.where(rng.random(steps_n) < 0.3, np.nan,
                                                  rng.uniform(-3, 3, steps_n)),
                             activity=rng.choice(["walking", "running"], steps_n).tolist())
    path = tmp_path_factory.mktemp("geo") / "t.json"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        doc = geojson_document(tr, steps=steps if steps_n else None)
        write_local_geojson(tr, path, steps=steps if steps_n else None)
    doc["type"] = LOCAL_TYPE
    assert path.read_text() == json.dumps(doc, allow_nan=False) + "\n"


@settings(max_examples=200)
@given(st.lists(st.floats(min_value=1e-4, max_value=1e9, exclude_max=True), max_size=200),
       st.integers(0, 9), st.booleans())
def test_float_text_without_exponents(values, digits, negative):
    """The range the formatter takes without looking for exponents, rounded numbers too."""
    sign = -1.0 if negative else 1.0
    values = [sign * v for v in values] + [sign * round(v, -digits) for v in values]
    values += [0.0, -0.0, 1e-4, float(np.nextafter(1e9, 0)), 1e8, 999999999.0]
    values = [v for v in values if v == 0.0 or 1e-4 <= abs(v) < 1e9]
    assert float_text(np.array(values)).to_pylist() == [_json(v) for v in values]
