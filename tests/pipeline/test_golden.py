"""Regression: every preset on a stored session gives the stored reference trajectories.

The references come from the tracker before its split into components (see ``_golden.py``);
a refactor must not move them. Tolerance 1e-9 m / rad (bit-identical on the machine that
produced them; other CPUs may differ in the last bits of vectorised maths).
"""

from __future__ import annotations

import numpy as np
import pytest

from hrtls.pipeline import PRESETS

from ._golden import TRACKS, tracks


@pytest.fixture(scope="module")
def now() -> dict[str, np.ndarray]:
    return tracks()


@pytest.mark.parametrize("name", PRESETS)
def test_preset_reproduces_reference(now: dict[str, np.ndarray], name: str) -> None:
    ref = np.load(TRACKS)
    for col in ("t", "xyz", "heading_rad", "cov_xy", "step_length_m"):
        key = f"{name}/{col}"
        assert now[key].shape == ref[key].shape, key
        np.testing.assert_allclose(now[key], ref[key], rtol=0, atol=1e-9, err_msg=key)
