"""blade_drag: a vertical blade dragged through sand, stopped mid-stroke, held, restarted.

The servo target moves at `speed` for `move_time`, holds for `hold_time`, then moves again
(one JointTrajectory-like command: linear segments). Metrics (SI): the steady sand force
while moving, what the blade does while held (creep: travel after the first 0.2 s of the
hold; rms speed), and the largest sand force in the first 0.3 s after the restart relative
to the steady value.
"""
import numpy as np

from ...control.commands import TrajectoryCommand, TrajectoryPoint
from . import BaseScenario

#: s after the stop / restart excluded from "held" and counted as "restart".
SETTLE_S = 0.2
RESTART_WINDOW_S = 0.3


class Scenario(BaseScenario):
    constraint_rows = False  # (a free or driven body: no limits, equalities or contacts)

    def __init__(self, scene):
        super().__init__(scene)
        self.depth = self.number('depth', positive=True)
        self.speed = self.number('speed', positive=True)
        self.move_time = self.number('move_time', positive=True)
        self.hold_time = self.number('hold_time', positive=True)
        self.start_time = self.number('start_time', minimum=0.0)

    def edit_model(self, spec):
        half_height = spec.geom('blade_geom').size[2]
        spec.body('blade').pos = [0.0, 0.0, self.scene.surface_height - self.depth + half_height]

    def initialize(self, sim):
        self._sent = False
        self._times, self._positions, self._speeds, self._forces = [], [], [], []

    def control(self, sim):
        if not self._sent and sim.commands is not None:
            stroke = self.speed * self.move_time
            t1 = self.start_time
            times = (t1, t1 + self.move_time, t1 + self.move_time + self.hold_time,
                     t1 + 2 * self.move_time + self.hold_time)
            points = tuple(TrajectoryPoint(positions=[x], time_from_start=t)
                           for t, x in zip(times, (0.0, stroke, stroke, 2 * stroke)))
            result = sim.commands.set_trajectory(
                TrajectoryCommand(joint_names=('drag',), points=points, start_time=sim.time),
                now=sim.time)
            assert result.accepted, result.message
            self._sent = True

    def observe(self, sim):
        joint = sim.data.joint('drag')
        self._times.append(sim.time)
        self._positions.append(float(joint.qpos[0]))
        self._speeds.append(float(joint.qvel[0]))
        self._forces.append(float(sim.engine.body_wrenches[0, 0]))

    def series(self):
        """(time s, blade x m, blade speed m/s, sand force along x N) samples."""
        return (np.array(self._times), np.array(self._positions), np.array(self._speeds),
                np.array(self._forces))

    def metrics(self, sim):
        t, x, v, f = self.series()
        stop = self.start_time + self.move_time
        restart = stop + self.hold_time
        moving = (t > self.start_time + 0.5 * self.move_time) & (t < stop)
        held = (t > stop + SETTLE_S) & (t < restart)
        after = (t >= restart) & (t < restart + RESTART_WINDOW_S)
        steady = float(np.mean(np.abs(f[moving]))) if moving.any() else float('nan')
        peak = float(np.max(np.abs(f[after]))) if after.any() else float('nan')
        return {
            'moving_force_N': steady,
            'hold_creep_m': float(np.ptp(x[held])) if held.any() else float('nan'),
            'hold_rms_speed_mps': float(np.sqrt(np.mean(v[held] ** 2))) if held.any() else float('nan'),
            'hold_force_std_N': float(np.std(f[held])) if held.any() else float('nan'),
            'restart_peak_force_N': peak,
            'restart_peak_over_steady': peak / steady if steady else float('nan'),
            'travel_m': float(x[-1] - x[0]),
        }
