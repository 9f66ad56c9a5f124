"""The mission smoother's named modes, as the CLI and the service offer them.

``off``: the per-node estimator alone (:mod:`hrtls.mission.nodes`); ``nodes``: the range-SLAM
smoother (:mod:`hrtls.mission.graph`) localizes the nodes it can, on a sliding window of
:data:`WINDOW_S`; ``feedback``: the same, solved every :data:`FEEDBACK_EVERY_S` of mission time,
and each rescuer's tracker takes the smoother's estimate of its latest pose
(:mod:`hrtls.mission.feedback`) and no range to the smoother's nodes (those reach it through
the feedback: ``feedback_ranges="smoother"``); a robot keeps its odometry EKF's own estimate
(``robots="alone"``: on dev seeds better than with the nodes or the feedback, docs/mission.md);
the ranges between agents are factors of the smoother and reach a fed-back rescuer through the
feedback only (``peer_factors``, :mod:`hrtls.mission.peer_feed`);
its nodes' covariances are reported calibrated (:data:`FEEDBACK_NODE_COV_SCALE`,
:data:`FEEDBACK_LINK_COV_SCALE`). The window keeps a solve's cost bounded over the mission.
"""

from __future__ import annotations

from hrtls.errors import InputError
from hrtls.mission.graph import SmootherParams

WINDOW_S = 120.0
"""Poses older than this leave the problem (marginalized), s."""

FEEDBACK_EVERY_S = 10.0
"""Solve cadence of the ``feedback`` mode, s of mission time."""

FEEDBACK_NODE_COV_SCALE = 1.35
"""The ``feedback`` mode's calibration of its nodes' covariances
(``SmootherParams.node_cov_scale``): chosen on the development seeds 0-9, where it brings the
mean NEES of the smoother's own nodes to 2 (docs/mission.md)."""

FEEDBACK_LINK_COV_SCALE = 1.6
"""The ``feedback`` mode's further calibration of a node with links
(``SmootherParams.link_cov_scale``; the nodes ranging each other): chosen on the development
seeds 0-9 with node ranges, the same way."""

MODES = ("off", "nodes", "feedback")

DEFAULT_MODE = "feedback"
"""The mode of :class:`hrtls.mission.tracker.MissionParams` by default."""


def smoother_params(mode: str) -> SmootherParams | None:
    """The smoother of ``mode`` (one of :data:`MODES`); None for ``off``."""
    if mode == "off":
        return None
    if mode == "nodes":
        return SmootherParams(window_s=WINDOW_S)
    if mode == "feedback":
        return SmootherParams(window_s=WINDOW_S, every_s=FEEDBACK_EVERY_S, feedback="implied",
                              robots="alone", feedback_ranges="smoother", peer_factors=True,
                              node_cov_scale=FEEDBACK_NODE_COV_SCALE,
                              link_cov_scale=FEEDBACK_LINK_COV_SCALE)
    raise InputError(f"smoother mode {mode!r}", where="smoother", expected=", ".join(MODES))


def default_smoother() -> SmootherParams | None:
    """The smoother of :data:`DEFAULT_MODE`."""
    return smoother_params(DEFAULT_MODE)


def smoother_mode(params: SmootherParams | None) -> str:
    """The mode whose parameters ``params`` are, or ``custom``."""
    for mode in MODES:
        if smoother_params(mode) == params:
            return mode
    return "custom"
