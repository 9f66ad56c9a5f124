"""Sensor-network self-localization with mobile agents (Inderst thesis Ch. 3.5, 5, 6.4).

Modules: :mod:`~hrtls.wsn.network` (model, JSON, deployments), :mod:`~hrtls.wsn.trilateration`
(TLA), :mod:`~hrtls.wsn.shadow_edge` (SELA), :mod:`~hrtls.wsn.planner` (loose cooperation, Safe
Navigation Algorithm), :mod:`~hrtls.wsn.tight` (tight cooperation, Algorithm 1),
:mod:`~hrtls.wsn.agents` (mobile-agent protocol, robot, rescuer), :mod:`~hrtls.wsn.refine`
(least-squares refinement), :mod:`~hrtls.wsn.experiment` (the studies). Plotting for the CLI is
in :mod:`~hrtls.wsn.plotting`.
"""
