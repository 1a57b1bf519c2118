"""Short trajectories of future gait targets, for a gait publisher driving a robot over ROS.

ROS-free. `GaitTrajectories.command(now)` samples a built-in gait (rft_sim_ros.scenes.gaits)
from sim time `now` over a short horizon into a `TrajectoryCommand`: start time `now`
(the JointTrajectory header stamp), waypoints every `spacing_s` with positions and
velocities (central differences of the gait, so the receiver interpolates with cubic
Hermite segments). Published at a steady rate shorter than the horizon, each trajectory
replaces the previous one as in joint_trajectory_controller, following the same path, so
the targets are continuous; if the publisher stops, the robot holds the last waypoint.

The gait's clock starts at the first `now` seen plus `start_delay_s` (the neutral pose is
held until then, and the gait's own ramp follows). Times in s of sim time.
"""
import math

from rft_sim_ros.control.commands import TrajectoryCommand, TrajectoryPoint

#: Half-width of the central difference that gives waypoint velocities, s.
_DIFFERENCE_S = 1e-4


class GaitTrajectories:
    """Trajectories of `make_gait(start_time_s)` (a callable returning a gait with
    `joint_names` and `targets(t)`) over `horizon_s`, waypoints `spacing_s` apart."""

    def __init__(self, make_gait, *, horizon_s=0.25, spacing_s=0.02, start_delay_s=1.0):
        for name, value in (('horizon_s', horizon_s), ('spacing_s', spacing_s)):
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f'{name} must be a finite number > 0, got {value}')
        if not (math.isfinite(start_delay_s) and start_delay_s >= 0.0):
            raise ValueError(f'start_delay_s must be a finite number >= 0, got {start_delay_s}')
        if spacing_s > horizon_s:
            raise ValueError(f'spacing_s ({spacing_s}) must not exceed horizon_s ({horizon_s})')
        self._make_gait = make_gait
        self._count = int(math.floor(horizon_s / spacing_s + 1e-9)) + 1
        self.spacing_s = float(spacing_s)
        self.start_delay_s = float(start_delay_s)
        self.gait = None

    def command(self, now):
        """The trajectory to send at sim time `now` (s); None before sim time has started
        (now <= 0: no /clock received yet)."""
        if not now > 0.0:
            return None
        if self.gait is None:
            self.gait = self._make_gait(now + self.start_delay_s)
        points = []
        for k in range(self._count):
            offset = k * self.spacing_s
            t = now + offset
            velocity = (self.gait.targets(t + _DIFFERENCE_S)
                        - self.gait.targets(t - _DIFFERENCE_S)) / (2 * _DIFFERENCE_S)
            points.append(TrajectoryPoint(positions=self.gait.targets(t).tolist(),
                                          time_from_start=offset,
                                          velocities=velocity.tolist()))
        return TrajectoryCommand(joint_names=tuple(self.gait.joint_names), points=tuple(points),
                                 start_time=now)
