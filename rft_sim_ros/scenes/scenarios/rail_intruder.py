"""rail_intruder: a servo on a rail carriage turns an intruder 180 deg through the sand.

The rig of RFT-SiM's "constrained progress" tests (models/rail_intruder.xml): a carriage on a
horizontal rail `rail_height` m above the sand (slide joint 'rail' with Coulomb friction
`rail_friction` N and viscous `rail_damping` N s/m), carrying a velocity servo whose axle
(along y) sits `length - max_depth` m above the sand, so that the intruder's tip (`length`
m from the axle) reaches `max_depth` m deep when it points straight down. The intruder
(`shape` flat or c, rft_sim_ros/scenes/intruders.py) starts horizontal and turns 180 deg at
`speed` rad/s; `direction` +1 starts it along +x and sweeps the tip down and back (-x)
through the sand, driving the carriage towards +x; -1 is the same motion mirrored (starts
along -x, drives the carriage towards -x). With shape c, +1 leads with the convex side
(closed C) and -1 with the hollow (open C): the same leg rotated in opposite directions.

Servo: an integrated-velocity servo, as MuJoCo's <intvelocity> (the paper's choice): a
position servo (torque = `servo_kp` (target - angle), joint armature 0.01 kg m^2 for the
gearbox's reflected rotor inertia, damping 1 N m s/rad) whose target is the integral of the
commanded speed: a constant-speed ramp through 180 deg, sent once as a two-point trajectory
through `sim.commands` (the one servo command path). After the rotation it holds the angle.
(A stiff <velocity> actuator is not used: MuJoCo integrates its gain implicitly while the
sand coupling predicts velocities without it, and the two disagree into chatter.)

Metrics (world frame, x along the rail; SI):
  carriage_displacement_m            carriage travel in the direction the leg drives it
                                     (direction * x), from start to the end of the run;
  carriage_displacement_rotation_m   ... at the moment the rotation ends;
  rotation_deg                       servo rotation achieved;
  peak_thrust_N                      largest sand force on the intruder along the drive;
  peak_sand_torque_Nm                largest sand torque about the axle against the motion;
  max_sinkage_m                      deepest point of the intruder tip below the surface.
The time course (sampled every `observe_interval` steps) is `series()`; the runner also
writes the carriage (base_body) position to timeseries.csv at the publish rate.
"""
import math

import numpy as np

from ...control.commands import TrajectoryCommand, TrajectoryPoint
from ..intruders import SHAPES, add_intruder
from ..config import SceneError
from . import BaseScenario

#: Rotation of one trial, rad.
ROTATION_RAD = math.pi


class Scenario(BaseScenario):
    constraint_rows = False  # (a free or driven body: no limits, equalities or contacts)

    observe_interval = 5
    #: What `series()` holds, one value per observed step.
    columns = ('time_s', 'angle_rad', 'carriage_x_m', 'servo_torque_Nm', 'sand_torque_Nm',
               'thrust_N', 'tip_sinkage_m')

    #: s after the rotation for the carriage to come to rest (duration: auto)
    coast_time = 0.5

    def duration(self):
        """One rotation at `speed` plus `coast_time`."""
        return ROTATION_RAD / self.speed + self.coast_time

    def __init__(self, scene):
        super().__init__(scene)
        self.shape = self.params.get('shape')
        if self.shape not in SHAPES:
            raise SceneError(f'scene {scene.name}: shape must be one of {SHAPES}, '
                             f'got {self.shape!r}')
        self.direction = self.number('direction')
        if self.direction not in (1.0, -1.0):
            raise SceneError(f'scene {scene.name}: direction must be 1 or -1, '
                             f'got {self.direction!r}')
        self.speed = self.number('speed', positive=True)
        self.length = self.number('length', positive=True)
        self.width = self.number('width', positive=True)
        self.thickness = self.number('thickness', positive=True)
        self.intruder_mass = self.number('intruder_mass', positive=True)
        self.max_depth = self.number('max_depth', positive=True, maximum=self.length)
        self.rail_height = self.number('rail_height', positive=True)
        self.carriage_mass = self.number('carriage_mass', positive=True)
        self.rail_friction = self.number('rail_friction', minimum=0.0)
        self.rail_damping = self.number('rail_damping', minimum=0.0)
        self.servo_kp = self.number('servo_kp', positive=True)
        self.axle_height = self.length - self.max_depth  # above the sand, m
        if self.axle_height >= self.rail_height:
            raise SceneError(f'scene {scene.name}: the axle ({self.axle_height:.3f} m above '
                             f'the sand) must be below the rail ({self.rail_height} m)')
        self.start_angle = 0.0 if self.direction > 0 else math.pi
        self._rows = []

    def edit_model(self, spec):
        carriage = spec.body('carriage')
        carriage.pos = [0.0, 0.0, self.scene.surface_height + self.rail_height]
        spec.geom('carriage').mass = self.carriage_mass
        rail = spec.joint('rail')
        rail.frictionloss = self.rail_friction
        rail.damping = [self.rail_damping, 0.0, 0.0]  # MuJoCo 4: [linear, ...]
        intruder = spec.body('intruder')
        intruder.pos = [0.0, 0.0, self.axle_height - self.rail_height]
        spec.delete(spec.geom('intruder'))
        try:
            add_intruder(spec, intruder, self.shape, self.length, self.width, self.thickness,
                         self.intruder_mass)
        except ValueError as error:
            raise SceneError(f'scene {self.scene.name}: {error}') from None
        spec.actuator('servo').set_to_position(kp=self.servo_kp)

    def initialize(self, sim):
        m = sim.model
        self._servo_q = m.jnt_qposadr[m.joint('servo').id]
        self._actuator = m.actuator('servo').id
        self._intruder = m.body('intruder').id
        self._carriage = m.body('carriage').id
        self._row = sim.engine.body_names.index('intruder')
        sim.data.qpos[self._servo_q] = self.start_angle
        self._rows = []
        self._commanded = False

    def control(self, sim):
        if not self._commanded:  # the whole rotation, once: constant speed from now on
            end = self.start_angle + self.direction * ROTATION_RAD
            sim.commands.set_trajectory(TrajectoryCommand(
                joint_names=('servo',),
                points=(TrajectoryPoint((self.start_angle,), 0.0),
                        TrajectoryPoint((end,), ROTATION_RAD / self.speed))), now=sim.time)
            self._commanded = True

    def observe(self, sim):
        self._rows.append(self._sample(sim))

    def _sample(self, sim):
        """One row of `series()` for the current state."""
        d = sim.data
        wrench = sim.engine.body_wrenches[self._row]
        axle = d.xpos[self._intruder]
        torque_axle = wrench[3:] + np.cross(d.xipos[self._intruder] - axle, wrench[:3])
        tip = axle + d.xmat[self._intruder].reshape(3, 3)[:, 0] * self.length
        return (d.time, d.qpos[self._servo_q], d.xpos[self._carriage, 0],
                self.direction * d.actuator_force[self._actuator],
                -self.direction * torque_axle[1], self.direction * wrench[0],
                self.scene.surface_height - tip[2])

    def series(self):
        """The recorded time course, {column: (n,) array} for `columns`: servo and sand
        torques (N m) about the axle along the motion, thrust (N) along the drive direction,
        tip depth (m) below the surface."""
        rows = np.array(self._rows) if self._rows else np.zeros((0, len(self.columns)))
        return {name: rows[:, i] for i, name in enumerate(self.columns)}

    def metrics(self, sim):
        s = self.series()
        if not len(s['time_s']):
            return {}
        x = self.direction * (s['carriage_x_m'] - s['carriage_x_m'][0])
        rotating = s['time_s'] <= ROTATION_RAD / self.speed
        swept = self.direction * (s['angle_rad'] - self.start_angle)
        return {
            'carriage_displacement_m': float(x[-1]),
            'carriage_displacement_rotation_m': float(x[rotating][-1]),
            'rotation_deg': float(np.degrees(swept[-1])),
            'peak_thrust_N': float(s['thrust_N'].max()),
            'peak_sand_torque_Nm': float(s['sand_torque_Nm'].max()),
            'max_sinkage_m': float(s['tip_sinkage_m'].max()),
        }
