"""GeoJSON numbers formatted by Arrow: the text of ``json.dumps``, to the character."""

import json
import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

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
