"""Simulation: a scene's MuJoCo model, its sand engine and its scenario, stepped together.

This is the ROS-free core that the CLI, the benchmarks and the rclpy node all drive:
build from a SceneConfig, `step()`, read `state()`, change `zeta`, `reset()`.
Sim time is continuous across resets (`time` keeps counting), as ROS tools expect.
A diverging run (non-finite or runaway state, or MuJoCo's own instability warnings) is
detected after the step that caused it and reported through `diverged` (the reason) instead
of stepping on with garbage.
"""
import mujoco
import numpy as np

from .engine import LowVelocity, SandEngine
from .geoms import body_plates
from .scenarios import load_scenario
from .scene import SceneError
from .state import ActivePlates, LegWrench, SimState
from ..rft.force_law import DynamicTerm

#: Generalised speeds above this (m/s or rad/s) mean the simulation has blown up.
RUNAWAY_SPEED = 1.0e3

_INSTABILITY_WARNINGS = (mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQVEL,
                         mujoco.mjtWarning.mjWARN_BADQPOS)


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
        try:
            spec = mujoco.MjSpec.from_file(str(scene.model_path))
        except Exception as error:  # MuJoCo reports parse errors as plain exceptions
            raise SceneError(f'scene {scene.name}: cannot load {scene.model_path}: {error}') from None
        self.scenario.edit_model(spec)
        try:
            self.model = spec.compile()
        except Exception as error:
            raise SceneError(f'scene {scene.name}: model does not compile: {error}') from None
        self.model.opt.timestep = scene.timestep
        self.data = mujoco.MjData(self.model)
        known = {self.model.body(i).name for i in range(self.model.nbody)}
        for body in (*scene.sand_bodies, scene.base_body):
            if body not in known:
                raise SceneError(f'scene {scene.name}: body {body!r} is not in the model '
                                 f'{scene.model_path.name}')
        plates = {}
        for body in scene.sand_bodies:
            plates[body] = body_plates(self.model, self.model.body(body).id,
                                       count=scene.plates_per_body,
                                       density_per_mm2=scene.plate_density_per_mm2)
        try:
            self.engine = SandEngine(self.model, self.data, plates, scene.zeta,
                                     surface_height=scene.surface_height,
                                     normalisation=scene.normalisation,
                                     dynamic=_dynamic_term(scene.dynamic),
                                     low_velocity=LowVelocity(**scene.low_velocity))
        except (TypeError, ValueError) as error:
            raise SceneError(f'scene {scene.name}: rft: {error}') from None
        self._base_id = self.model.body(scene.base_body).id
        self._joints = [j for j in range(self.model.njnt)
                        if self.model.jnt_type[j] in (mujoco.mjtJoint.mjJNT_HINGE,
                                                      mujoco.mjtJoint.mjJNT_SLIDE)]
        self.joint_names = tuple(self.model.joint(j).name for j in self._joints)
        self._qpos_adr = self.model.jnt_qposadr[self._joints]
        self._dof_adr = self.model.jnt_dofadr[self._joints]
        self._legs = [(name, [self.engine.body_names.index(b) for b in bodies],
                       self.model.body(bodies[-1]).id) for name, bodies in scene.legs.items()]
        self._time_offset = 0.0
        self.diverged = None
        self.steps = 0
        self._warnings = self._warning_count()
        self.scenario.initialize(self)
        mujoco.mj_forward(self.model, self.data)

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
        return sum(self.data.warning[w].number for w in _INSTABILITY_WARNINGS)

    def step(self, count=1):
        """Advance `count` steps (scenario control, sand, MuJoCo, scenario observation).
        Raises SimulationDiverged, and keeps `diverged` set, once the state blows up."""
        if self.diverged:
            raise SimulationDiverged(self.diverged)
        scenario = self.scenario
        for _ in range(count):
            scenario.control(self)
            self.engine.step()
            self.steps += 1
            problem = self._check()
            if problem:
                self.diverged = f'at t = {self.time:.4f} s: {problem}'
                raise SimulationDiverged(self.diverged)
            if self.steps % scenario.observe_interval == 0:
                scenario.observe(self)

    def _check(self):
        warnings = self._warning_count()
        if warnings != self._warnings:
            self._warnings = warnings
            return 'MuJoCo reported an unstable (non-finite or huge) state'
        qvel = self.data.qvel
        if not np.all(np.isfinite(qvel)) or not np.all(np.isfinite(self.data.qpos)):
            return 'state is not finite'
        peak = np.max(np.abs(qvel)) if qvel.size else 0.0
        if peak > RUNAWAY_SPEED:
            return f'runaway speed {peak:.3g} (> {RUNAWAY_SPEED:g} m/s or rad/s)'
        return None

    def reset(self):
        """Back to the scene's initial state; sim time keeps counting forward."""
        self._time_offset += self.data.time
        mujoco.mj_resetData(self.model, self.data)
        self.diverged = None
        self._warnings = self._warning_count()
        self.scenario.initialize(self)
        mujoco.mj_forward(self.model, self.data)

    def leg_wrenches(self):
        """Per-leg summed sand wrenches (LegWrench, world axes; see state.py)."""
        wrenches = self.engine.body_wrenches
        xipos = self.data.xipos
        legs = []
        for name, indices, foot in self._legs:
            point = self.data.xpos[foot].copy()
            force = np.zeros(3)
            torque = np.zeros(3)
            for i in indices:
                f, t = wrenches[i, :3], wrenches[i, 3:]
                force += f
                torque += t + np.cross(xipos[self.engine.body_ids[i]] - point, f)
            legs.append(LegWrench(name, force, torque, point))
        return tuple(legs)

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
