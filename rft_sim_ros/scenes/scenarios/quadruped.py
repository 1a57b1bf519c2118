"""quadruped: the bundled 12-DOF quadruped (models/quadruped/quadruped.urdf.xacro) standing
in sand from its ros2_control initial pose, then trotting (rft_sim_ros.scenes.quadruped).

After `settle_time` s the built-in trot starts (`gait: trot`, with the scene's frequency,
stance fraction, step length and lift), sent through the same position command interface
that external controllers use (`sim.commands`); `gait: none` leaves the robot holding its
pose for external commands (the `trot_gait` node sends the same trot over ROS). The
generic metrics (base displacement and speed, stance depth, per-leg forces) describe the run.
"""
import numpy as np

from ..config import SceneError
from ..quadruped import TrotGait
from . import BaseScenario

GAIT_NAMES = ('none', 'trot')


class Scenario(BaseScenario):

    def __init__(self, scene):
        super().__init__(scene)
        self.settle_time = self.number('settle_time', minimum=0.0)
        self.cycles = self.number('cycles', positive=True)
        self.gait = None
        if self.choice('gait', GAIT_NAMES) == 'trot':
            self.gait = self.walking_gait(TrotGait)
        self._order = None

    def duration(self):
        """Settling plus the trot cycles."""
        return self.settle_time + self.cycles / self.number('frequency', positive=True)

    def _command_order(self, sim):
        """Command slot of each gait joint (the gait's targets go there; other commanded
        joints keep the targets they had when the gait took over)."""
        if sim.commands is None:
            raise SceneError(f'scene {self.scene.name}: the model has no position command '
                             'interface for the gait')
        names = list(sim.servo_joint_names)
        missing = [name for name in self.gait.joint_names if name not in names]
        if missing:
            raise SceneError(f'scene {self.scene.name}: the gait drives joints the model '
                             f'lacks: {missing}')
        return np.array([names.index(name) for name in self.gait.joint_names])

    def control(self, sim):
        # the gait's clock is the time since this run (or reset) started: sim.data.time
        if self.gait is None:
            return
        if self._order is None:
            self._order = self._command_order(sim)
            self._targets = sim.commands.sample(sim.time).positions.copy()
        self._targets[self._order] = self.gait.targets(sim.data.time)
        sim.commands.set_positions(self._targets, now=sim.time)
