"""The smoother's named modes: what each sets, and refusals."""

from __future__ import annotations

import pytest

from hrtls.errors import InputError
from hrtls.mission.graph import SmootherParams
from hrtls.mission.smoother_modes import MODES, smoother_mode, smoother_params


def test_modes_round_trip() -> None:
    assert smoother_params("off") is None
    for mode in MODES:
        assert smoother_mode(smoother_params(mode)) == mode
    nodes, feedback = smoother_params("nodes"), smoother_params("feedback")
    assert nodes is not None and feedback is not None
    assert nodes.feedback == "off" and feedback.feedback == "implied"
    assert feedback.feedback_ranges == "smoother"   # the nodes' ranges counted once
    assert nodes.window_s == feedback.window_s == 120.0      # bounded cost in both
    assert feedback.every_s < nodes.every_s


def test_other_parameters_are_custom_and_unknown_modes_refused() -> None:
    assert smoother_mode(SmootherParams()) == "custom"
    with pytest.raises(InputError, match="off, nodes, feedback"):
        smoother_params("fast")


def test_a_snapshot_without_row_covariances_is_refused() -> None:
    from hrtls.errors import FormatError
    from hrtls.mission.smoothing import SmootherState, state_from, state_of

    d = state_of(SmootherState(rows={"R1": [[0.0, 1.0, 2.0, 1.0, 0.0, 0.0, 1.0]]}))
    assert d is not None
    back = state_from(d)
    assert back is not None and back.rows == d["rows"]
    d["rows"] = {"R1": [[0.0, 1.0, 2.0]]}
    with pytest.raises(FormatError, match="older snapshot"):
        state_from(d)


@pytest.mark.parametrize("mode", MODES)
def test_a_mission_ended_again_without_new_data_changes_nothing(mode: str) -> None:
    """The service advances a closed mission on every poll: with no new data nothing changes
    (no node reported, the whole state byte for byte: the smoother does not solve again)."""
    from hrtls.mission.tracker import MissionParams, MissionTracker

    from ._live import short_mission

    sessions, kinds = short_mission(2)
    mt = MissionTracker(sessions, kinds=kinds, params=MissionParams(smoother=smoother_params(mode)))
    assert mt.advance(final=True).changed != ()
    state = mt.snapshot()
    for _ in range(2):
        assert mt.advance(final=True).changed == ()
        assert mt.snapshot() == state
