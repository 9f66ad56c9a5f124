"""Reference trajectories of every preset on a stored session (``test_golden.py``).

The session is stored (not simulated at test time) so that simulator changes do not move it;
the trajectories were produced by the tracker before its split into components. Regenerate
only for an intended change of the tracker's output, and say so in the commit:
``python tests/pipeline/_golden.py`` (writes ``data/golden_session.zip`` if absent and
``data/golden_tracks.npz``).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

DATA = Path(__file__).parent / "data"
SESSION = DATA / "golden_session.zip"
TRACKS = DATA / "golden_tracks.npz"


def tracks() -> dict[str, np.ndarray]:
    """Trajectory columns of every preset on the stored session (``NAME/column`` keys)."""
    from hrtls.io.session import read_session
    from hrtls.pipeline import PRESETS, Tracker, preset

    s = read_session(SESSION)
    out: dict[str, np.ndarray] = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name in PRESETS:
            res = Tracker(preset(name)).run(s)
            tr = res.trajectory
            out[f"{name}/t"] = tr.t
            out[f"{name}/xyz"] = tr.xyz
            out[f"{name}/heading_rad"] = tr.heading_rad
            out[f"{name}/cov_xy"] = tr.cov_xy
            out[f"{name}/step_length_m"] = res.steps.length_m
    return out


def main() -> None:
    """Write the stored session (once) and the reference trajectories."""
    if not SESSION.exists():
        from hrtls.io.session import write_session
        from hrtls.sim.scenarios import run_scenario

        sim = run_scenario("office_random_walk", 3, duration_s=90.0)
        write_session(sim.session.with_parts(truth=None), SESSION, table_format="parquet")
    np.savez_compressed(TRACKS, **tracks())


if __name__ == "__main__":
    main()
