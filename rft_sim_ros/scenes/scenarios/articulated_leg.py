"""articulated_leg: a 3-DOF leg on the rail carriage steps in the sand and pulls the carriage.

RFT-SiM's third baseline (models/rail_leg.xml): the rail is `rail_height` m above the sand;
a coxa-femur-tibia leg with three position servos traces a 3D stepping path
(rft_sim_ros/scenes/stepping_leg.py) with its scoop-like end effector (a half-cylinder shell,
`scoop_diameter` x `scoop_height` x `scoop_thickness` m, hollow facing backward, -x): it
plunges `depth` m into the sand at the front of a `stroke` m stroke, sweeps straight back
`reach` m out from the coxa axis, lifts out to `clearance` m above the sand and returns with
an outward excursion of `abduction` m. `steps` steps of `step_period` s; the whole path is
sent once as a joint trajectory (waypoints every 10 ms, from the leg's inverse kinematics)
through `sim.commands`, the one servo command path.

Metrics (SI; x along the rail, +x = forward):
  carriage_displacement_per_step_m  carriage travel over the completed steps / their number;
  carriage_displacement_m           total carriage travel over the run;
  carriage_displacement_step_<k>_m  travel during step k (k = 1..steps);
  stroke_m                          the commanded foot stroke (the no-slip travel per step);
  max_foot_sinkage_m                deepest foot point below the sand surface;
  peak_servo_torque_Nm              largest |servo torque| of the three servos.
`series()` has the time course (time, carriage x, foot depth).
"""
import mujoco
import numpy as np

from ...control.commands import TrajectoryCommand, TrajectoryPoint
from ..intruders import add_arc_mesh
from ..config import SceneError
from ..stepping_leg import LegGeometry, SteppingPath
from . import BaseScenario

JOINTS = ('coxa', 'femur', 'tibia')

#: Spacing of the trajectory's waypoints, s.
WAYPOINT_INTERVAL = 0.01

#: Scoop mesh axes in the scoop body frame (columns): the arc's chord runs inward (-y),
#: its width along the tibia (+z), its bulge forward (+x), so the hollow faces -x.
_SCOOP_AXES = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


class Scenario(BaseScenario):
    observe_interval = 10

    def duration(self):
        """`steps` stepping periods plus 0.5 s for the carriage to stop."""
        return self.steps * self.period + 0.5

    def __init__(self, scene):
        super().__init__(scene)
        n = self.number
        self.steps = int(n('steps', positive=True))
        self.period = n('step_period', positive=True)
        self.stroke = n('stroke', positive=True)
        self.rail_height = n('rail_height', positive=True)
        self.depth = n('depth', positive=True)
        self.scoop = (n('scoop_diameter', positive=True), n('scoop_height', positive=True),
                      n('scoop_thickness', positive=True))
        self.carriage_mass = n('carriage_mass', positive=True)
        self.rail_friction = n('rail_friction', minimum=0.0)
        self.rail_damping = n('rail_damping', minimum=0.0)
        self.leg = LegGeometry()
        try:
            self.path = SteppingPath(
                stroke=self.stroke, reach=n('reach', positive=True),
                stance_z=-(self.rail_height + self.depth),
                lift_z=n('clearance', minimum=0.0) - self.rail_height,
                abduction=n('abduction', minimum=0.0), period=self.period,
                stance_fraction=n('stance_fraction', positive=True),
                plunge_fraction=n('plunge_fraction', positive=True))
            times = np.arange(0.0, self.steps * self.period + 1e-9, WAYPOINT_INTERVAL)
            self._times = times
            self._angles = self.leg.inverse(self.path.foot(times))
        except ValueError as error:
            raise SceneError(f'scene {scene.name}: {error}') from None
        self._rows = []

    def edit_model(self, spec):
        spec.body('carriage').pos = [0.0, 0.0, self.scene.surface_height + self.rail_height]
        spec.geom('carriage').mass = self.carriage_mass
        rail = spec.joint('rail')
        rail.frictionloss = self.rail_friction
        rail.damping = [self.rail_damping, 0.0, 0.0]  # MuJoCo 4: [linear, ...]
        diameter, height, thickness = self.scoop
        if not 0.0 < thickness < diameter / 2:
            raise SceneError(f'scene {self.scene.name}: scoop_thickness must be in '
                             f'(0, scoop_diameter / 2)')
        spec.delete(spec.geom('scoop'))
        add_arc_mesh(spec, 'scoop_mesh', diameter, height, thickness)
        geom = spec.body('scoop').add_geom()
        geom.name = 'scoop'
        geom.type = mujoco.mjtGeom.mjGEOM_MESH
        geom.meshname = 'scoop_mesh'
        geom.mass = 0.02
        geom.contype = geom.conaffinity = 0
        geom.rgba = [0.85, 0.45, 0.15, 1.0]
        geom.pos = [0.0, diameter / 2, 0.0]
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, _SCOOP_AXES.ravel())
        geom.quat = quat

    def initialize(self, sim):
        m = sim.model
        self._qpos = np.array([m.jnt_qposadr[m.joint(j).id] for j in JOINTS])
        self._actuators = np.array([m.actuator(j).id for j in JOINTS])
        self._carriage = m.body('carriage').id
        self._tibia = m.body('tibia').id
        sim.data.qpos[self._qpos] = self._angles[0]
        self._rows = []
        self._commanded = False

    def control(self, sim):
        if self._commanded:
            return
        order = [sim.servo_joint_names.index(j) for j in JOINTS]
        points = []
        for t, q in zip(self._times, self._angles):
            full = np.empty(3)
            full[order] = q
            points.append(TrajectoryPoint(tuple(full), float(t)))
        result = sim.commands.set_trajectory(
            TrajectoryCommand(sim.servo_joint_names, points), now=sim.time)
        if not result.accepted:
            raise SceneError(f'scene {self.scene.name}: stepping trajectory rejected: '
                             f'{result.message}')
        self._commanded = True

    def observe(self, sim):
        d = sim.data
        # the foot point: the tibia's lower end, tibia length below its axis along -z_tibia
        foot = d.xpos[self._tibia, 2] - self.leg.tibia * d.xmat[self._tibia, 8]
        self._rows.append((d.time, d.xpos[self._carriage, 0],
                           self.scene.surface_height - foot,
                           np.abs(d.actuator_force[self._actuators]).max()))

    def series(self):
        """{'time_s', 'carriage_x_m', 'foot_sinkage_m', 'servo_torque_Nm'}: (n,) arrays."""
        rows = np.array(self._rows) if self._rows else np.zeros((0, 4))
        return {name: rows[:, i] for i, name in enumerate(
            ('time_s', 'carriage_x_m', 'foot_sinkage_m', 'servo_torque_Nm'))}

    def metrics(self, sim):
        s = self.series()
        if not len(s['time_s']):
            return {}
        t, x = s['time_s'], s['carriage_x_m'] - s['carriage_x_m'][0]
        done = min(self.steps, int((t[-1] + 1e-6) // self.period))
        at_step_ends = np.interp(np.arange(done + 1) * self.period, t, x)
        metrics = {'carriage_displacement_m': float(x[-1]),
                   'carriage_displacement_per_step_m': (float(at_step_ends[-1] / done)
                                                        if done else 0.0)}
        for k, travel in enumerate(np.diff(at_step_ends), start=1):
            metrics[f'carriage_displacement_step_{k}_m'] = float(travel)
        metrics.update({
            'steps_completed': done,
            'stroke_m': self.stroke,
            'max_foot_sinkage_m': float(s['foot_sinkage_m'].max()),
            'peak_servo_torque_Nm': float(s['servo_torque_Nm'].max()),
        })
        return metrics
