"""Hypothesis strategies and small fixtures shared by the writer tests."""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st

from hrtls.data import Activity, Landmark, StepEvents, Trajectory
from hrtls.frames import Georeference

GEO = Georeference(49.4478, 11.0839, 310.0, 0.3)


def simple_trajectory(n: int = 5) -> Trajectory:
    t = np.arange(n) * 0.5
    xyz = np.column_stack([np.arange(n) * 1.0, np.arange(n) * -0.5, np.zeros(n)])
    heading = np.full(n, 0.25)
    heading[1] = np.nan
    activity = np.full(n, int(Activity.WALKING))
    activity[0] = int(Activity.STANDING)
    return Trajectory.build(t=t, xyz=xyz, heading_rad=heading, activity=activity)


def simple_steps() -> StepEvents:
    return StepEvents.build(t_start=[0.0, 0.5], t_end=[0.5, 1.0], length_m=[0.7, 0.72],
                            heading_rad=[0.1, np.nan])


def simple_landmarks() -> dict[str, Landmark]:
    return {
        "BLE1": Landmark(id="BLE1", kind="beacon", position=(1.0, 2.0, 3.0), floor=0),
        "TAG7": Landmark(id="TAG7", kind="rfid", position=(-4.0, 0.5, 0.0),
                         bearings_rad=(0.5, -1.0), accuracy_m=0.8),
    }


@st.composite
def trajectories(draw: st.DrawFn, *, min_size: int = 1, max_size: int = 25) -> Trajectory:
    n = draw(st.integers(min_value=min_size, max_value=max_size))
    dts = draw(st.lists(st.floats(min_value=1e-3, max_value=50.0), min_size=n, max_size=n))
    t0 = draw(st.floats(min_value=-100.0, max_value=1e5))
    t = t0 + np.cumsum(dts) - dts[0]
    coord = st.floats(min_value=-2000.0, max_value=2000.0, allow_nan=False)
    xyz = np.array(draw(st.lists(st.tuples(coord, coord, st.floats(-50.0, 50.0)),
                                 min_size=n, max_size=n)))
    heading = np.array(draw(st.lists(st.one_of(st.just(float("nan")),
                                               st.floats(-np.pi, np.pi)),
                                     min_size=n, max_size=n)))
    return Trajectory.build(t=t, xyz=xyz.reshape(n, 3), heading_rad=heading)


georeferences = st.builds(
    Georeference,
    st.floats(min_value=-80.0, max_value=80.0),
    st.floats(min_value=-179.0, max_value=179.0),
    st.floats(min_value=-100.0, max_value=3000.0),
    st.floats(min_value=-np.pi, max_value=np.pi),
)
