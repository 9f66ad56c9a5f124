"""Parameters of the mission's range-SLAM smoother (:mod:`hrtls.mission.graph`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from hrtls.errors import InputError


@dataclass(frozen=True, kw_only=True)
class SmootherParams:
    """Parameters of :func:`smooth` (see module doc).

    Attributes
    ----------
    decimate_s:
        Spacing of the agents' rows kept as poses, s.
    segment_m:
        Distance walked (along the agent's rows) of a scale / heading correction segment, m.
    odo_sigma_m, odo_fraction:
        Noise of one increment between poses: a floor (m) and a part of its length.
    increment_noise:
        ``"length"``: the increment noise from ``odo_sigma_m`` and ``odo_fraction``;
        ``"tracker"``: the tracker's covariance growth between the poses, floor ``odo_sigma_m``
        (:mod:`hrtls.mission.increment_noise`).
    heading_updates:
        In the mission loop, the magnetic heading and tag bearing corrections: ``"factor"``
        (jump removed from the dead reckoning, a position factor), ``"drop"`` (jump removed, no
        factor) or ``"chain"`` (jump kept in the dead reckoning, no factor).
    scale_sigma, scale_walk_sigma:
        Prior 1-sigma of the first segment's scale correction and of its change per segment.
    heading_sigma_rad, heading_walk_rad:
        Prior 1-sigma of the first segment's rotation and of its change per segment, rad.
    height_sigma_m:
        Prior 1-sigma of the antenna-node height difference, m.
    range_correlation_s:
        Ranges of one agent to one node within this window weigh as one, s (0: independent).
    loss, loss_scale:
        Robust loss of the range residuals (``rho`` as in ``scipy.optimize.least_squares``) and
        its scale in whitened units.
    min_ranges:
        Fewest ranges of a node in the problem.
    min_spread_m, localize_spread_m:
        RMS distance of a node's reading positions from their best-fit line, at least, m: of
        a node in the problem, of a localized node.
    max_sigma_m:
        Largest 1-sigma (worst axis) of a localized node, m.
    max_evaluations:
        Cost evaluations per solve at most.
    every_s:
        In the mission loop: solve again after this much mission time, s.
    feedback, feedback_cov_scale:
        In the mission loop: give each rescuer the smoother's estimate of its latest pose
        (``"implied"`` update or ``"replace"``, :mod:`hrtls.mission.feedback`; ``"off"``), its
        covariance times ``feedback_cov_scale``; an implied update whose NIS (2 dof) exceeds
        ``feedback_gate`` is not applied.
    robots:
        In the mission loop, what a robot takes from the mission: ``"nodes"`` (localized nodes
        as range anchors, as a rescuer), ``"feedback"`` (with ``feedback``: the smoother's
        latest pose, as a rescuer, and no node as a range anchor) or ``"alone"`` (neither: its
        odometry EKF alone; its ranges still feed the nodes and the smoother).
    feedback_ranges:
        With feedback, who takes a fed-back rescuer's ranges to the nodes the smoother owns:
        ``"both"`` (its tracker too, widened as any node's) or ``"smoother"`` (only the
        smoother: they reach the tracker through the feedback, counted once;
        :func:`hrtls.mission.smoothing.via_feedback`).
    link_sigma_m, link_sigma_fraction:
        The estimator's noise model of a range between two dropped nodes (no sigma comes
        with them): ``sqrt(link_sigma_m^2 + (link_sigma_fraction r)^2)``, m
        (:mod:`hrtls.mission.graph_links`).
    link_bias_sigma_m:
        Standard deviation of a pair's persistent excess path (NLOS through walls), which
        repeating the pair's ranges does not average away; added in variance to a link's
        sigma, m (0: none).
    link_join_tol_m:
        A node joining through its links (no geometry from its agents' ranges alone) joins
        only when its starting point's median absolute range residual, over its links and
        over its agents' ranges each, is at most this, m
        (:func:`hrtls.mission.graph_links.confirmed`; inf: no check).
    window_s:
        In the mission loop: poses older than this leave the problem as a prior factor
        (:mod:`hrtls.mission.graph_window`), s; None: every pose stays.
    peer_factors:
        In the mission loop, with cooperation: the ranges between agents are factors between
        their poses (:mod:`hrtls.mission.graph_peers`), and an agent the smoother feeds back
        takes none in its tracker (:func:`hrtls.mission.peer_feed.takes_peers`).
    node_cov_scale, link_cov_scale:
        Calibration of the node covariances the smoother reports: every node's block of the
        inverse information (after the residual inflation) times ``node_cov_scale``, a node
        with links (ranges to other dropped nodes) times ``link_cov_scale`` as well; the
        localization check (``max_sigma_m``) reads the block before them. Errors the
        information does not model (docs/mission.md, "Node covariances under the feedback"):
        chosen on the development seeds, 1: none.
    """

    decimate_s: float = 1.0
    segment_m: float = 10.0
    odo_sigma_m: float = 0.15
    odo_fraction: float = 0.10
    increment_noise: str = "length"
    heading_updates: str = "factor"
    scale_sigma: float = 0.08
    scale_walk_sigma: float = 0.02
    heading_sigma_rad: float = 0.02
    heading_walk_rad: float = 0.1
    height_sigma_m: float = 2.0
    range_correlation_s: float = 10.0
    loss: str = "cauchy"
    loss_scale: float = 2.0
    min_ranges: int = 6
    min_spread_m: float = 1.0
    localize_spread_m: float = 1.5
    max_sigma_m: float = 3.0
    max_evaluations: int = 60
    every_s: float = 30.0
    feedback: str = "off"
    feedback_cov_scale: float = 2.0
    feedback_gate: float = 13.8
    robots: str = "nodes"
    feedback_ranges: str = "both"
    window_s: float | None = None
    link_sigma_m: float = 0.15
    link_sigma_fraction: float = 0.03
    link_bias_sigma_m: float = 0.0
    link_join_tol_m: float = 1.0
    peer_factors: bool = False
    node_cov_scale: float = 1.0
    link_cov_scale: float = 1.0

    def __post_init__(self) -> None:
        for name in ("decimate_s", "segment_m", "odo_sigma_m", "scale_sigma",
                     "scale_walk_sigma", "heading_sigma_rad", "heading_walk_rad",
                     "height_sigma_m", "loss_scale", "min_spread_m", "localize_spread_m",
                     "max_sigma_m", "every_s", "feedback_cov_scale", "feedback_gate",
                     "link_sigma_m"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise InputError(f"{name} = {v}", where="SmootherParams", expected="> 0")
        if not self.link_join_tol_m > 0:
            raise InputError(f"link_join_tol_m = {self.link_join_tol_m}", where="SmootherParams",
                             expected="> 0 (inf: no check)")
        for name in ("node_cov_scale", "link_cov_scale"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 1):
                raise InputError(f"{name} = {v}", where="SmootherParams", expected=">= 1")
        for name in ("odo_fraction", "range_correlation_s", "link_sigma_fraction",
                     "link_bias_sigma_m"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise InputError(f"{name} = {getattr(self, name)}", where="SmootherParams",
                                 expected=">= 0")
        if self.min_ranges < 3 or self.max_evaluations < 1:
            raise InputError(f"min_ranges = {self.min_ranges}, max_evaluations = "
                             f"{self.max_evaluations}", where="SmootherParams",
                             expected="min_ranges >= 3, max_evaluations >= 1")
        if self.window_s is not None and not (math.isfinite(self.window_s)
                                              and self.window_s > 0):
            raise InputError(f"window_s = {self.window_s}", where="SmootherParams",
                             expected="> 0 or None")
        for name, allowed in (("feedback", ("off", "implied", "replace")),
                              ("robots", ("nodes", "feedback", "alone")),
                              ("feedback_ranges", ("both", "smoother")),
                              ("increment_noise", ("length", "tracker")),
                              ("heading_updates", ("factor", "drop", "chain")),
                              ("loss", ("linear", "soft_l1", "huber", "cauchy"))):
            if getattr(self, name) not in allowed:
                raise InputError(f"{name} = {getattr(self, name)!r}", where="SmootherParams",
                                 expected=" or ".join(allowed))
        if not isinstance(self.peer_factors, bool):
            raise InputError(f"peer_factors = {self.peer_factors!r}", where="SmootherParams",
                             expected="true or false")
        if self.robots == "feedback" and self.feedback == "off":
            raise InputError("robots = 'feedback' without feedback", where="SmootherParams",
                             expected="feedback implied or replace")
