"""The plane circle fit's scalar sums equal the per-row normal equations they replace."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from hrtls.calibration.hard_iron import _eliminate, _solve


def reference_normal_equations(p: np.ndarray, keep: np.ndarray
                               ) -> tuple[np.ndarray, np.ndarray]:
    """``[A^T A | A^T b]`` summed row by row (A = [2u, 1], b = |u|^2), as Python floats."""
    dim = p.shape[1]
    rows = [p[i].tolist() for i in range(len(p)) if keep[i]]
    mean = [0.0] * dim
    for r in rows:
        for a in range(dim):
            mean[a] += r[a]
    n = len(rows)
    mean = [v / n for v in mean]
    m = np.zeros((dim + 1, dim + 2))
    for r in rows:
        u = [r[a] - mean[a] for a in range(dim)]
        row = [2.0 * v for v in u] + [1.0]
        bb = 0.0
        for v in u:
            bb += v * v
        for a in range(dim + 1):
            for b in range(a, dim + 1):
                m[a, b] += row[a] * row[b]
            m[a, dim + 1] += row[a] * bb
    for a in range(dim + 1):
        for b in range(a):
            m[a, b] = m[b, a]
    return m, np.array(mean)


@settings(max_examples=100, deadline=None)
@given(p=arrays(np.float64, st.tuples(st.integers(3, 40), st.just(2)),
                elements=st.floats(-80.0, 80.0)),
       drop=st.integers(0, 2))
def test_plane_fit_sums_equal_the_row_by_row_sums(p: np.ndarray, drop: int) -> None:
    keep = np.ones(len(p), dtype=np.bool_)
    keep[:drop] = False
    m, mean = reference_normal_equations(p, keep)
    try:
        c_ref, r2_ref = _eliminate(m.tolist(), mean.tolist())
    except ZeroDivisionError:      # singular (e.g. coincident points): both refuse alike
        with pytest.raises(ZeroDivisionError):
            _solve(p, keep)
        return
    c, r2 = _solve(p, keep)
    assert np.array_equal(c, c_ref, equal_nan=True)
    assert r2 == r2_ref or (np.isnan(r2) and np.isnan(r2_ref))
