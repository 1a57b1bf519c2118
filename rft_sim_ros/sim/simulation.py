"""Simulation: a scene's MuJoCo model, its sand engine and its scenario, stepped together.

This is the ROS-free core that the CLI, the benchmarks and the rclpy node all drive:
build from a SceneConfig, `step()`, read `state()`, change `zeta`, `reset()`.
Sim time is continuous across resets (`time` keeps counting), as ROS tools expect.

Servo commands take one path: every position servo of the model (a MuJoCo `position`
actuator on a joint) is driven by `commands`, a CommandHandler over those joints. External
controllers (the ROS node) and built-in gaits (scenarios) both feed it; it is sampled at the
scene's control rate and held in between (zero-order hold, as a servo bus would).

A diverging run is detected and reported through `diverged` (the reason) instead of stepping
on with garbage: MuJoCo resets a non-finite state (caught every step by sim time going
back) and counts instability warnings; those and a runaway speed are checked at CHECK_RATE
Hz of sim time.
"""
import mujoco
import numpy as np

from ..control.commands import CommandHandler
from ..robot.description import DescriptionError, load_description
from ..sand.engine import LowVelocity, SandEngine
from ..sand.geoms import body_plates
from ..sand.surface import surface_from_settings
from ..sand.zeta_map import zeta_map_from_settings
from ..scenes.scenarios import load_scenario
from ..scenes.config import SceneError
from .state import ActivePlates, LegWrench, SimState
from ..rft.force_law import DynamicTerm

#: Generalised speeds above this (m/s or rad/s) mean the simulation has blown up.
RUNAWAY_SPEED = 1.0e3
#: Hz of sim time at which the state is checked for a runaway speed and MuJoCo's warnings.
CHECK_RATE = 100.0

_INSTABILITY_WARNINGS = np.array([mujoco.mjtWarning.mjWARN_BADQACC,
                                  mujoco.mjtWarning.mjWARN_BADQVEL,
                                  mujoco.mjtWarning.mjWARN_BADQPOS], dtype=int)


def position_servos(model):
    """[(actuator id, joint id)] of MuJoCo `position` actuators acting on a joint: no
    activation dynamics, a fixed gain kp and an affine bias -kp q (what <position> compiles
    to; <intvelocity> differs only by its integrator dynamics), in actuator order."""
    servos = []
    for a in range(model.nu):
        kp = model.actuator_gainprm[a, 0]
        if (model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
                and model.actuator_dyntype[a] == mujoco.mjtDyn.mjDYN_NONE
                and model.actuator_gaintype[a] == mujoco.mjtGain.mjGAIN_FIXED
                and model.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_AFFINE
                and kp != 0 and model.actuator_biasprm[a, 1] == -kp):
            servos.append((a, int(model.actuator_trnid[a, 0])))
    return servos


def can_collide(model):
    """Whether MuJoCo could ever make a rigid contact in `model`: an explicit <pair>, a flex,
    or two geoms whose contype/conaffinity bits let them collide."""
    if model.npair or model.nflex:
        return True
    return bool(np.bitwise_or.reduce(model.geom_contype, initial=0)
                & np.bitwise_or.reduce(model.geom_conaffinity, initial=0))


class SimulationDiverged(RuntimeError):
    """Raised by `step` when the state stops being finite/bounded; message = the reason."""


def _dynamic_term(config):
    if not config:
        return None
    return DynamicTerm(lam=float(config.get('lambda', 1.0)),
                       density=float(config.get('density', 1600.0)))


class Simulation:
    """One scene, ready to step. Attributes: model, data, engine, scenario, scene."""

    def __init__(self, scene):
        self.scene = scene
        self.scenario = load_scenario(scene)
        robot = scene.robot or {}
        try:
            self.description = load_description(
                scene.model_path, package_paths=robot.get('package_paths'),
                xacro_args=robot.get('xacro_args'), base=robot.get('base', 'floating'))
        except DescriptionError as error:
            raise SceneError(f'scene {scene.name}: {error}') from None
        spec = self.description.spec
        self.scenario.edit_model(spec)
        try:
            self.model = spec.compile()
        except Exception as error:
            raise SceneError(f'scene {scene.name}: model does not compile: {error}') from None
        self.model.opt.timestep = scene.timestep
        try:
            surface = surface_from_settings(scene.surface, scene.surface_height, self.model)
            zeta_map = zeta_map_from_settings(scene.zeta_map)
        except ValueError as error:
            raise SceneError(f'scene {scene.name}: {error}') from None
        if scene.surface.get('type') == 'hfield':  # the sand carries bodies there, not MuJoCo
            geom = self.model.geom(scene.surface['geom'])
            geom.contype[0] = geom.conaffinity[0] = 0
        if not can_collide(self.model):  # sand alone: skip MuJoCo's (empty) collision pass
            self.model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
        self.data = mujoco.MjData(self.model)
        known = {self.model.body(i).name for i in range(self.model.nbody)}
        # the body /odom follows: the scene's, else the first body under the world
        self.base_body = scene.base_body or self.model.body(min(1, self.model.nbody - 1)).name
        for body in (*scene.sand_bodies, self.base_body):
            if body not in known:
                raise SceneError(f'scene {scene.name}: body {body!r} is not in the model '
                                 f'{scene.model_path.name}')
        plates = {}
        for body in scene.sand_bodies:
            count = scene.plates_by_body.get(body, scene.plates_per_body)
            plates[body] = body_plates(
                self.model, self.model.body(body).id, count=count,
                density_per_mm2=None if count is not None else scene.plate_density_per_mm2)
        try:
            self.engine = SandEngine(self.model, self.data, plates, scene.zeta,
                                     surface_height=scene.surface_height, surface=surface,
                                     zeta_map=zeta_map,
                                     normalisation=scene.normalisation,
                                     dynamic=_dynamic_term(scene.dynamic),
                                     low_velocity=LowVelocity(**scene.low_velocity))
        except (TypeError, ValueError) as error:
            raise SceneError(f'scene {scene.name}: rft: {error}') from None
        self._base_id = self.model.body(self.base_body).id
        self._joints = [j for j in range(self.model.njnt)
                        if mujoco.mjtJoint(int(self.model.jnt_type[j]))
                        in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE)]
        self.joint_names = tuple(self.model.joint(j).name for j in self._joints)
        self._qpos_adr = self.model.jnt_qposadr[self._joints]
        self._dof_adr = self.model.jnt_dofadr[self._joints]
        self._leg_names = tuple(scene.legs)
        self._leg_feet = np.array([self.model.body(bodies[-1]).id
                                   for bodies in scene.legs.values()], dtype=int)
        # rows: the engine's body index of every (leg, sand body) pair; membership: (legs, rows)
        # 0/1 matrix that sums the rows of each leg
        self._leg_rows = np.array([self.engine.body_names.index(b)
                                   for bodies in scene.legs.values() for b in bodies], dtype=int)
        leg_of_row = np.repeat(np.arange(len(scene.legs)),
                               [len(bodies) for bodies in scene.legs.values()])
        self._leg_of_row = leg_of_row
        self._leg_membership = (leg_of_row == np.arange(len(scene.legs))[:, None]).astype(float)
        self._servos = position_servos(self.model)
        if scene.servo_kp is not None:  # stiffness of every position servo, N m/rad or N/m
            for actuator, _ in self._servos:
                self.model.actuator_gainprm[actuator, 0] = scene.servo_kp
                self.model.actuator_biasprm[actuator, 1] = -scene.servo_kp
        self.servo_joint_names = tuple(self.model.joint(j).name for _, j in self._servos)
        self._servo_ctrl = np.array([a for a, _ in self._servos], dtype=int)
        self._control_every = max(1, int(round(1.0 / (scene.control_rate * scene.timestep))))
        # runaway checks at ~CHECK_RATE Hz of sim time (MuJoCo's own resets: every step)
        self._check_every = max(1, int(round(
            1.0 / (CHECK_RATE * self._control_every * scene.timestep))))
        self._ticks = 0
        self._ctrl = self.data.ctrl
        self._time_offset = 0.0
        self.steps = 0
        self._start()

    def _start(self):
        """Initial state, fresh command handler, cleared divergence flags."""
        self.diverged = None
        self._warnings = self._warning_count()
        self.scenario.initialize(self)
        mujoco.mj_forward(self.model, self.data)
        self.commands = None
        if self._servos:
            initial = [self.data.qpos[self.model.jnt_qposadr[j]] for _, j in self._servos]
            self.commands = CommandHandler(self.servo_joint_names, initial)

    @property
    def timestep(self):
        """Integration timestep, s."""
        return self.model.opt.timestep

    @property
    def time(self):
        """Sim time, s, continuous across resets."""
        return self._time_offset + self.data.time

    @property
    def zeta(self):
        """Sand stiffness, N/cm^3; setting validates it and applies from the next step."""
        return self.engine.zeta

    @zeta.setter
    def zeta(self, value):
        self.engine.zeta = value

    def _warning_count(self):
        return int(self.data.warning.number[_INSTABILITY_WARNINGS].sum())

    def step(self, count=1):
        """Advance `count` steps: at control ticks the scenario's control and the servo
        targets, then sand + MuJoCo. Raises SimulationDiverged, and keeps `diverged` set,
        once the state blows up."""
        if self.diverged:
            raise SimulationDiverged(self.diverged)
        scenario, engine, data = self.scenario, self.engine, self.data
        observe_every = scenario.observe_interval
        for _ in range(count):
            if self.steps % self._control_every == 0:
                self._control_tick()
            before = data.time
            engine.step()
            self.steps += 1
            if data.time <= before:  # MuJoCo reset a non-finite state
                self._diverge(self._check() or 'MuJoCo reset an unstable state',
                              self._time_offset + before)
            if self.steps % observe_every == 0:
                scenario.observe(self)

    def _control_tick(self):
        self._ticks += 1
        if self._ticks % self._check_every == 0:
            problem = self._check()
            if problem:
                self._diverge(problem)
        self.scenario.control(self)
        if self.commands is not None:
            self._ctrl[self._servo_ctrl] = self.commands.sample(self.time).positions

    def _diverge(self, problem, at_time=None):
        at_time = self.time if at_time is None else at_time
        self.diverged = f'at t = {at_time:.4f} s: {problem}'
        raise SimulationDiverged(self.diverged)

    def _check(self):
        """Why the current state is unusable, or None."""
        warnings = self._warning_count()
        if warnings != self._warnings:
            self._warnings = warnings
            return 'MuJoCo reported an unstable (non-finite or huge) state'
        qvel = self.data.qvel
        peak = np.max(np.abs(qvel)) if qvel.size else 0.0
        if not peak <= RUNAWAY_SPEED:  # also catches NaN
            return f'runaway speed {peak:.3g} (> {RUNAWAY_SPEED:g} m/s or rad/s)'
        return None

    def reset(self):
        """Back to the scene's initial state; sim time keeps counting forward."""
        self._time_offset += self.data.time
        mujoco.mj_resetData(self.model, self.data)
        self._start()

    def leg_wrenches(self):
        """Per-leg summed sand wrenches (LegWrench, world axes; see state.py)."""
        wrenches = self.engine.body_wrenches[self._leg_rows]
        points = self.data.xpos[self._leg_feet]
        levers = self.data.xipos[self.engine.body_ids[self._leg_rows]] - points[self._leg_of_row]
        forces = self._leg_membership @ wrenches[:, :3]
        torques = self._leg_membership @ (wrenches[:, 3:] + np.cross(levers, wrenches[:, :3]))
        return tuple(LegWrench(name, force, torque, point) for name, force, torque, point
                     in zip(self._leg_names, forces, torques, points))

    def state(self, with_plates=False):
        """A SimState snapshot of the current state."""
        d = self.data
        velocity = np.zeros(6)
        mujoco.mj_objectVelocity(self.model, d, mujoco.mjtObj.mjOBJ_XBODY, self._base_id,
                                 velocity, 1)  # base_link frame origin, base_link axes
        plates = None
        if with_plates:
            positions, forces, areas = self.engine.active_plates()
            plates = ActivePlates(positions, forces, areas)
        return SimState(
            time=self.time,
            joint_names=self.joint_names,
            joint_positions=d.qpos[self._qpos_adr].copy(),
            joint_velocities=d.qvel[self._dof_adr].copy(),
            joint_efforts=d.qfrc_actuator[self._dof_adr].copy(),
            base_position=d.xpos[self._base_id].copy(),
            base_quaternion_wxyz=d.xquat[self._base_id].copy(),
            base_linear_velocity=velocity[3:].copy(),
            base_angular_velocity=velocity[:3].copy(),
            legs=self.leg_wrenches(),
            zeta=self.engine.zeta,
            plates_active=int(self.engine.plates_active),
            active_plates=plates,
        )
