"""Mobile agents for sensor-network localization: the interface, a robot and a simple rescuer.

Both kinds of agent (Inderst thesis Sec. 5.3-5.4 and 6.4) do the same three things for the
network algorithms: walk or drive to a target point, report where they think they are (with a
covariance), and report the ranges to the nodes they hear there. :class:`MobileAgent` is that
protocol; the real rescuer filter (PDR with range corrections) can implement it later.

* :class:`RobotAgent` - unicycle (eq. 6.2) driven by the via-point law of eq. 6.3 (holonomic
  velocity projected on the heading, heading steered by ``K_w * beta``, circular arrival region),
  localized by an EKF whose prediction is the discrete unicycle and whose observations are ranges
  to localized nodes (eq. 6.4). The per-step loop is a compiled kernel.
* :class:`RescuerAgent` - a simulated walker: straight steps toward the target, dead-reckoning
  error that grows with distance (heading and step-length noise), and the same range update at
  each correction.

The protocol and the simulated radio are in :mod:`~hrtls.wsn.ranging`, the robot in
:mod:`~hrtls.wsn.robot`, the rescuer in :mod:`~hrtls.wsn.rescuer`; this module gathers them.
Simulation of the radio is :class:`RangeWorld`: true node positions, the link radius ``rho``
(the agent at a way point is a temporary node of the disk graph) and the agent's radio range
``d_r`` (Theorem 2 uses ``d_r = 2 rho``).
"""

from hrtls.wsn.ranging import (
    AgentLeg,
    Landmarks,
    MobileAgent,
    RangeScan,
    RangeWorld,
    range_update,
)
from hrtls.wsn.rescuer import RescuerAgent, RescuerParams
from hrtls.wsn.robot import (
    RobotAgent,
    RobotParams,
    RobotState,
    robot_leg_kernel,
    robot_leg_reference,
)

__all__ = ["AgentLeg", "Landmarks", "MobileAgent", "RangeScan", "RangeWorld", "RescuerAgent",
           "RescuerParams", "RobotAgent", "RobotParams", "RobotState", "range_update",
           "robot_leg_kernel", "robot_leg_reference"]
