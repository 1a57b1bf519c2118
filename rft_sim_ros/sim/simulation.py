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
import traceback

import mujoco
import numpy as np

from ..control.commands import CommandHandler
from ..robot.description import DescriptionError, load_description
from ..robot.joints import (JointInterfaces, add_joint_interfaces, movable_joints,
                            position_servos)
from ..robot.pose import (DEFAULT_KEYFRAMES, REST_HOLD_S, REST_SPEED, SETTLE_LIMIT_S, align_to,
                          initial_keyframe, keyframe_label, lift_to, parse_spawn,
                          set_initial_pose)
from ..robot.sand_bodies import (AUTO, free_root_joint, keep_sand_visuals, legs_from_tree,
                                 other_bodies, resolve_sand_bodies)
from ..sand.engine import LowVelocity, SandEngine, cold_start_estimate, kernels_cached
from ..sand.geoms import body_plates
from ..sand.deformable import DeformableSand
from ..sand.surface import (CHECKED_SLOPE_DEG, GRID, SURFACE_KINDS, Surface, hfield_geom,
                            hfield_label, surface_from_settings)
from ..sand.zeta_map import zeta_map_from_settings
from ..scenes.scenarios import failure_line, load_scenario, scenario_files
from ..scenes.config import SceneError
from .caveats import caveats, first_few
from .hybrid_drive import HybridDrive
from .outcome import TILT_LIMIT_DEG, OutcomeWatch
from .sand_entry import SandEntryWatch
from .sensors import Sensors, scene_settings
from .state import ActivePlates, LegWrench, SimState
from ..rft.force_law import DynamicTerm

#: Generalised speeds above this (m/s or rad/s) mean the simulation has blown up.
RUNAWAY_SPEED = 1.0e3
#: Hz of sim time at which the state is checked for a runaway speed and MuJoCo's warnings.
CHECK_RATE = 100.0
#: Hz of sim time at which the outcome (sim/outcome.py) looks at the robot: its tilt, and how
#: deep its geoms near the surface are.
OUTCOME_RATE = 25.0
#: s of sim time between the looks for bodies without plates in the sand (`sand_entry`), and
#: for a fall while spawn rest settles the robot.
ENTRY_CHECK_S = 0.1
#: deg: spawn rest counts the robot fallen when its base has come to rest turned this far from
#: how it was set down (a quadruped on its side, a humanoid on its back; standing robots
#: settle within a few degrees): the outcome's limit (sim/outcome.py).
FALL_TILT_DEG = TILT_LIMIT_DEG

_INSTABILITY_WARNINGS = np.array([mujoco.mjtWarning.mjWARN_BADQACC,
                                  mujoco.mjtWarning.mjWARN_BADQVEL,
                                  mujoco.mjtWarning.mjWARN_BADQPOS], dtype=int)


def can_collide(model):
    """Whether MuJoCo could ever make a rigid contact in `model`: an explicit <pair>, a flex,
    or two geoms whose contype/conaffinity bits let them collide."""
    if model.npair or model.nflex:
        return True
    return bool(np.bitwise_or.reduce(model.geom_contype, initial=0)
                & np.bitwise_or.reduce(model.geom_conaffinity, initial=0))


#: A plane whose upward normal is within this angle of +z is a floor (steeper: a wall).
FLOOR_TILT_DEG = 45.0


def world_ground(model, geom_type):
    """Ids of the geoms of `geom_type` (mjtGeom) fixed to the world (their body welded to
    it) that can collide with a geom of a moving body (contype/conaffinity bits)."""
    moving = model.body_weldid[model.geom_bodyid] != 0
    contype = np.bitwise_or.reduce(model.geom_contype[moving], initial=0)
    conaffinity = np.bitwise_or.reduce(model.geom_conaffinity[moving], initial=0)
    return [int(g) for g in np.flatnonzero((model.geom_type == geom_type) & ~moving)
            if model.geom_contype[g] & conaffinity or model.geom_conaffinity[g] & contype]


def floor_planes(model):
    """Ids of the floor planes of a model: planes of its `world_ground`, facing up (within
    FLOOR_TILT_DEG of +z; a wall is not a floor)."""
    planes = world_ground(model, mujoco.mjtGeom.mjGEOM_PLANE)
    if not planes:
        return []
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)  # the poses of geoms fixed to the world
    up = data.geom_xmat[planes, 8]  # z of each plane's normal (its local z axis)
    return [g for g, z in zip(planes, up) if z >= np.cos(np.radians(FLOOR_TILT_DEG))]


def kernel_key(scene):
    """(low-velocity kernels, surface kind code, deformable): what selects the compiled sand
    kernels a `scene` (SceneConfig) steps with (`engine.kernels_cached`), and nothing else:
    'implicit' or 'explicit' (the 'ema' and 'none' methods share one set); deformable sand
    has one gather kernel whatever surface its bed lies on (GRID)."""
    deformable = bool(scene.deformable.get('enabled'))
    kind = GRID if deformable else SURFACE_KINDS[scene.surface.get('type', 'plane')]
    method = 'implicit' if scene.low_velocity['method'] == 'implicit' else 'explicit'
    return method, kind, deformable


def compile_notice(scene):
    """The line to show before building `scene` (SceneConfig) when its sand kernels are not
    in numba's cache yet: 'compiling kernels, first run only', with ', ~N s as here last
    time' where a start that compiled the same kernels with this cache measured it
    (`engine.cold_start_estimate`; a first run after install has no such measure, and a
    figure from another machine would be a promise); None when cached."""
    key = kernel_key(scene)
    if kernels_cached(*key):
        return None
    seconds = cold_start_estimate(*key)
    return 'compiling kernels, first run only' + (
        '' if seconds is None else f', ~{seconds:.0f} s as here last time')


#: Columns (y, z, x) and (z, x, y) of a vector: a x b = a[NEXT] b[LAST] - a[LAST] b[NEXT].
_NEXT, _LAST = np.array([1, 2, 0]), np.array([2, 0, 1])


def _cross(a, b):
    """Row-wise cross products of two (n, 3) arrays (np.cross costs ~50 us of axis handling
    per call, at every published state; this ~5 us)."""
    return a[:, _NEXT] * b[:, _LAST] - a[:, _LAST] * b[:, _NEXT]


class SimulationDiverged(RuntimeError):
    """Raised by `step` when the state stops being finite/bounded; message = the reason."""


class ScenarioFailed(SimulationDiverged):
    """Raised by `step` when the scenario's code raised: the run ends as a divergence does.
    message: 'at t = T s: the scenario raised at FILE:LINE: Type: message'; `details`: the
    whole traceback (text)."""

    def __init__(self, message, details):
        super().__init__(message)
        self.details = details


def _dynamic_term(config):
    if not config:
        return None
    return DynamicTerm(lam=float(config.get('lambda', 1.0)),
                       density=float(config.get('density', 1600.0)))


class Simulation:
    """One scene, ready to step. Attributes: model, data, engine, scenario, scene.

    surface: a `sand.surface.Surface` made in Python (a HeightGrid of an array of heights, a
    Slope) that the sand takes instead of the scene's `sand.surface`, which must then be
    left as the plane; deformable sand (sand.deformable) lays its bed over it as over the
    scene's. summary.json's `surface` (`Surface.describe`) records which it was.
    """

    def __init__(self, scene, surface=None):
        self.scene = scene
        self.notices = []  # what start-up decided for the user (e.g. the auto sand bodies)
        self.scenario = load_scenario(scene)
        robot = scene.robot or {}
        try:
            self.description = load_description(
                scene.model_path, package_paths=robot.get('package_paths'),
                xacro_args=robot.get('xacro_args'), base=robot.get('base'),
                log=self.notices.append)  # (what reading the description changed)
        except DescriptionError as error:
            raise SceneError(f'scene {scene.name}: {error}') from None
        # initial pose: ros2_control initial values of the description, then the scene's
        self._initial_positions = {**(self.description.initial_positions or {}),
                                   **scene.initial_positions}
        spec = self.description.spec
        self._in_scenario(self.scenario.edit_model, spec)
        visual = scene.plate_geoms == 'visual'
        patterns = scene.sand_bodies
        if visual and AUTO in patterns:  # auto's bodies' visuals are marked before compiling
            patterns = self._auto_sand_bodies(spec) + [p for p in patterns if p != AUTO]
        keep_sand_visuals(spec, patterns, visual)
        spec.compiler.discardvisual = True  # headless: visual-only geoms and meshes not needed
        joint_plan = add_joint_interfaces(spec, scene.servos)
        self.passive_joint_names = joint_plan.passive
        if joint_plan.passive:
            names = joint_plan.passive
            self.notices.append(
                f'joint{"s" * (len(names) > 1)} {", ".join(names)}: no actuator in the model, '
                f'so {"they stay" if len(names) > 1 else "it stays"} passive as written '
                '(spring, damping, limits) and commands leave them out; servos: {NAME: {kp: '
                '..., kd: ...}} gives one a servo')
        try:
            self.model = spec.compile()
        except Exception as error:
            raise SceneError(f'scene {scene.name}: model does not compile: {error}') from None
        self.model.opt.timestep = scene.timestep
        self._keyframe = initial_keyframe(self.model, scene.keyframe)
        if self._keyframe is not None and scene.keyframe is None:
            names = [self.model.key(k).name or f'#{k}' for k in range(self.model.nkey)]
            self.notices.append(
                f"initial pose: the model's keyframe {keyframe_label(self._keyframe)} (by "
                f'default the first of {", ".join(DEFAULT_KEYFRAMES)} it has, else its first '
                f'keyframe; it has {", ".join(names)}): robot.keyframe or --keyframe NAME '
                "picks another, '' the model's qpos0")
        try:
            surface = self._surface(surface)
            zeta_map = zeta_map_from_settings(scene.zeta_map)
        except ValueError as error:
            raise SceneError(f'scene {scene.name}: {error}') from None
        self._ground_to_sand()
        if not can_collide(self.model):  # sand alone: skip MuJoCo's (empty) collision pass
            self.model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
        self.data = mujoco.MjData(self.model)
        self._say_moved_into_ranges(self._initial_pose())
        # the body /odom follows: the scene's, else the first body under the world
        self._base_id = self._base(self.model)
        self.base_body = self.model.body(self._base_id).name  # (every body has one:
        # robot.description names the others)
        given = sorted(set((scene.raw.get('sand') or {}).get('deformable') or {}) - {'enabled'})
        if given and not scene.deformable.get('enabled'):
            self.notices.append(f'sand.deformable.{", sand.deformable.".join(given)} set, but '
                                'sand.deformable.enabled is false: the sand is rigid and they '
                                'have no effect (sand.deformable.enabled=true makes it '
                                'deformable)')
        if scene.deformable.get('enabled'):
            surface = self._bed(surface, scene.deformable)
            self.notices.extend(surface.notices)
        steepest = surface.steepest_deg()
        if steepest > CHECKED_SLOPE_DEG:
            self.notices.append(
                f'the sand surface is {steepest:.3g} deg steep at its steepest: '
                f'beyond the slopes checked (up to {CHECKED_SLOPE_DEG:g} deg) and near dry '
                "sand's angle of repose (about 30 deg), where real sand fails and flows; the "
                'model knows nothing of that failure (docs/terrain.md, "Stated limit")')
        try:
            self.sand_bodies = tuple(resolve_sand_bodies(self.model, self.data, patterns,
                                                         self._base_id))
        except ValueError as error:
            raise scene.locator.error('rft.bodies', str(error)) from None
        if list(scene.sand_bodies) != list(self.sand_bodies):
            self.notices.append(f'sand bodies ({", ".join(scene.sand_bodies)}): '
                                f'{", ".join(self.sand_bodies)}')
        self.other_bodies = ()
        if scene.other_bodies_density_per_mm2 is not None:
            self.other_bodies = tuple(other_bodies(self.model, self.sand_bodies))
        for body in scene.plates_by_body:
            if body not in self.sand_bodies:
                raise scene.locator.error('rft.plates', f'{body!r} is not a sand body '
                                          f'({", ".join(self.sand_bodies)})')
        plates = self._plates(scene)
        try:
            self.engine = SandEngine(self.model, self.data, plates, scene.zeta,
                                     surface_height=scene.surface_height, surface=surface,
                                     zeta_map=zeta_map,
                                     normalisation=scene.normalisation,
                                     dynamic=_dynamic_term(scene.dynamic),
                                     low_velocity=LowVelocity(**scene.low_velocity))
        except (TypeError, ValueError) as error:
            raise SceneError(f'scene {scene.name}: rft: {error}') from None
        self._joints = self._named_joints()  # (those /joint_states reports)
        self.joint_names = tuple(self.model.joint(j).name for j in self._joints)
        self._qpos_adr = self.model.jnt_qposadr[self._joints]
        self._dof_adr = self.model.jnt_dofadr[self._joints]
        self._set_legs(scene)
        try:
            self.sensors = Sensors(self.model, self._base_id, self._leg_names,
                                   scene_settings(scene.values), self.engine.surface,
                                   self.engine.deformable)
        except ValueError as error:
            raise scene.locator.error('sensors', str(error)) from None
        self.notices += caveats(self.model, self.data, self.engine, scene, self._base_id,
                                len(self.sand_bodies))
        self._entry_watch = SandEntryWatch(self.model, self.engine.body_ids)
        self._outcome = OutcomeWatch(self.model, self._base_id, self.engine.body_ids)
        if scene.servo_kp is not None:  # stiffness of every position servo, N m/rad or N/m
            for actuator, _ in position_servos(self.model):
                self.model.actuator_gainprm[actuator, 0] = scene.servo_kp
                self.model.actuator_biasprm[actuator, 1] = -scene.servo_kp
        mujoco.mj_forward(self.model, self.data)
        self.interfaces = JointInterfaces(
            self.model, self.data, joint_plan.commanded, scene.servos, scene.timestep,
            effort_limits=self.description.effort_limits)
        self.servo_joint_names = self.interfaces.joint_names
        self.hybrid_drive = HybridDrive(self.model, self.interfaces,
                                        scene.values.get('joint_gains'))
        self._command_qpos = self.model.jnt_qposadr[
            [self.model.joint(name).id for name in self.servo_joint_names]].astype(int)
        try:
            self._spawn = parse_spawn(scene.spawn, scene.scenario)
        except ValueError as error:
            raise scene.locator.error('robot.spawn', str(error)) from None
        if self._spawn[0] != 'model' and free_root_joint(self.model, self._base_id) is None:
            if scene.spawn != 'auto':  # (the default: a welded robot starts where it is)
                self.notices.append(f'robot.spawn {scene.spawn}: body {self.base_body} is fixed '
                                    'to the world (no free joint at its root), so it starts '
                                    'where the model puts it')
            self._spawn = ('model', None)
        self._control_every = max(1, int(round(1.0 / (scene.control_rate * scene.timestep))))
        # runaway checks at ~CHECK_RATE Hz of sim time (MuJoCo's own resets: every step)
        self._check_every = max(1, int(round(
            1.0 / (CHECK_RATE * self._control_every * scene.timestep))))
        self._outcome_every = max(1, int(round(
            1.0 / (OUTCOME_RATE * self._control_every * scene.timestep))))
        self._ctrl = self.data.ctrl
        self._warning_numbers = self.data.warning.number  # a view of mjData's warning counts
        self._time_offset = 0.0
        self.steps = 0  # engine steps since the start, resets included (the run's count)
        self.settle_steps = 0  # engine steps spawn rest took to settle, resets included
        self._settle_counts = np.zeros(3, dtype=np.int64)  # their `_engine_counts`
        self._in_scenario(self._start)

    def _in_scenario(self, call, *args):
        """call(*args) at start-up; an exception that the scenario's code raised is a
        SceneError naming its file and line (the run does not start)."""
        try:
            return call(*args)
        except SceneError:
            raise
        except Exception as error:
            line = failure_line(error, scenario_files(type(self.scenario)))
            if line is None:
                raise
            raise SceneError(f'scene {self.scene.name}: the scenario raised at {line}') from None

    def scenario_failure(self, error):
        """ScenarioFailed for exception `error` where the scenario's code raised it (a frame
        of its traceback in the scenario's source), else None; sets `diverged`."""
        line = failure_line(error, scenario_files(type(self.scenario)))
        if line is None:
            return None
        self.diverged = f'at t = {self.time:.4f} s: the scenario raised at {line}'
        return ScenarioFailed(self.diverged, ''.join(traceback.format_exception(error)))

    def _auto_sand_bodies(self, spec):
        """The body names auto picks, found on a compiled copy of `spec` (visual geoms
        discarded) in the initial pose; [AUTO] where that copy fails, so that the model's
        own compile and pose report the error."""
        scene = self.scene
        try:
            probe = spec.copy()
            probe.compiler.discardvisual = True
            model = probe.compile()
            data = mujoco.MjData(model)
            set_initial_pose(model, data, initial_keyframe(model, scene.keyframe),
                             self._initial_positions)
            mujoco.mj_kinematics(model, data)
            return resolve_sand_bodies(model, data, [AUTO], self._base(model))
        except (ValueError, KeyError):
            return [AUTO]

    def _plates(self, scene):
        """{body: Plates}: the sand bodies' as the scene asks (a count or a density per body;
        a body whose geoms make more plates than its count even at their coarsest is named
        in a notice), then the other bodies' at rft.other_bodies_density_per_mm2 (one whose
        geoms cannot carry plates, a plane, is left out of them and named in a notice)."""
        plates, over = {}, []
        for body in self.sand_bodies:
            count = scene.plates_by_body.get(body, scene.plates_per_body)
            try:
                plates[body] = body_plates(
                    self.model, self.model.body(body).id, count=count,
                    density_per_mm2=None if count is not None else scene.plate_density_per_mm2)
            except ValueError as error:
                raise scene.locator.error('rft.bodies', str(error)) from None
            if count is not None and len(plates[body].areas) > count:
                over.append(f'{body} {len(plates[body].areas)}')
        if over:
            self.notices.append(f'plates: {", ".join(over)}, more than asked: their geoms '
                                'tessellate (a mesh decimates) no coarser')
        density, without = scene.other_bodies_density_per_mm2, []
        for body in self.other_bodies:
            try:
                plates[body] = body_plates(self.model, self.model.body(body).id,
                                           density_per_mm2=density)
            except ValueError as error:
                without.append(f'{body} ({error})')
        if without:
            self.notices.append(f'other bodies without plates, which pass through the sand: '
                                f'{first_few(without)}')
        self.other_bodies = tuple(b for b in self.other_bodies if b in plates)
        if self.other_bodies:
            count = sum(len(plates[b].areas) for b in self.other_bodies)
            self.notices.append(
                f'other bodies: {first_few(list(self.other_bodies))} carry {count} plates '
                f'({density:g} per mm^2), so that the sand holds them too (those on a '
                "leg's branch add to that leg's wrench; rft.other_bodies_density_per_mm2: null "
                'leaves them without)')
        return plates

    def _named_joints(self):
        """Ids of the hinge and slide joints that have a name; how many have none is said in
        a notice (they get no interfaces either: `add_joint_interfaces`)."""
        movable = movable_joints(self.model)
        named = [j for j in movable if self.model.joint(j).name]
        if len(named) < len(movable):
            self.notices.append(f'{len(movable) - len(named)} hinge or slide joint(s) without '
                                'a name: no command interfaces, not in /joint_states (name '
                                'them in the model to command them)')
        return named

    def _surface(self, given):
        """The sand's surface: `given` (a Surface made in Python; the scene's sand.surface
        must then be the plane), else the scene's sand.surface; its notices said."""
        if given is None:
            surface = surface_from_settings(self.scene.surface, self.scene.surface_height,
                                            self.model)
        elif not isinstance(given, Surface) or isinstance(given, DeformableSand):
            raise ValueError(f'surface must be a rft_sim_ros.sand.surface.Surface (a Plane, '
                             f'Slope or HeightGrid), got {type(given).__name__}'
                             + ('; deformable sand is the scene\'s sand.deformable, laid over '
                                'the surface given' if isinstance(given, DeformableSand) else ''))
        elif self.scene.surface.get('type', 'plane') != 'plane':
            raise ValueError('a surface given in Python replaces the scene\'s sand.surface, '
                             f'which is a {self.scene.surface["type"]} here: leave it out')
        else:
            surface = given
        self.notices.extend(surface.notices)
        return surface

    def _bed(self, surface, bed):
        """The deformable bed (scene key sand.deformable) over `surface`, centred where the
        scene says, else under the base body in the initial pose, its x, y rounded to whole
        cells (a robot at the origin: the bed centred there)."""
        center = bed.get('center')
        if center is None:
            center = bed['cell'] * np.round(self.data.xpos[self._base_id, :2] / bed['cell'])
        try:
            return DeformableSand(surface, bed['size'], bed['cell'], bed['repose_deg'],
                                  tuple(float(c) for c in center))
        except ValueError as error:
            raise SceneError(f'scene {self.scene.name}: {error}') from None

    def _base(self, model):
        """Id of the body /odom follows in `model`: the scene's base_body, else the first body
        under the world (named or not)."""
        if not self.scene.base_body:
            return min(1, model.nbody - 1)
        try:
            return model.body(self.scene.base_body).id
        except KeyError:
            raise self.scene.locator.error('base_body', f'{self.scene.base_body!r} is not a '
                                           f'body of {self.scene.model_path.name}') from None

    def _initial_pose(self):
        """The keyframe and initial joint positions of the scene (robot/pose.py); joints
        outside their range start at its nearest end. Returns those (`into_ranges`)."""
        try:
            moved = set_initial_pose(self.model, self.data, self._keyframe,
                                     self._initial_positions)
        except ValueError as error:
            key = 'robot.keyframe' if 'keyframe' in str(error) else 'robot.initial_positions'
            raise self.scene.locator.error(key, str(error)) from None
        mujoco.mj_kinematics(self.model, self.data)
        return moved

    def _say_moved_into_ranges(self, moved):
        """The start-up notice of the joints `_initial_pose` moved into their ranges."""
        if moved:
            name, value, low, high = moved[0]
            self.notices.append(
                f'joint{"s" if len(moved) > 1 else ""} {", ".join(m[0] for m in moved)} '
                f'started outside {"their ranges" if len(moved) > 1 else "its range"} '
                f'({name} at {value:.4g}, range {low:.4g} .. {high:.4g}): each starts at its '
                "range's nearest end, which its servo holds (robot.initial_positions or "
                'robot.keyframe give another start)')

    def _set_legs(self, scene):
        """Legs: the scene's, or one per branch of the kinematic tree that holds sand bodies,
        with the other bodies of that branch (robot/sand_bodies.py)."""
        legs = scene.legs
        if legs == 'auto':
            legs = legs_from_tree(self.model, self.sand_bodies, self._base_id,
                                  self.other_bodies)
        for leg, bodies in scene.legs.items() if scene.legs != 'auto' else ():
            for body in bodies:
                if body not in self.sand_bodies:
                    raise scene.locator.error(f'legs.{leg}', f'{body!r} is not a sand body '
                                              f'({", ".join(self.sand_bodies)})')
        self.legs = {leg: tuple(bodies) for leg, bodies in legs.items()}
        self._leg_names = tuple(self.legs)
        self._leg_feet = np.array([self.model.body(bodies[-1]).id
                                   for bodies in self.legs.values()], dtype=int)
        # rows: the engine's body index of every (leg, sand body) pair; membership: (legs, rows)
        # 0/1 matrix that sums the rows of each leg
        self._leg_rows = np.array([self.engine.body_names.index(b)
                                   for bodies in self.legs.values() for b in bodies], dtype=int)
        leg_of_row = np.repeat(np.arange(len(self.legs)),
                               [len(bodies) for bodies in self.legs.values()])
        self._leg_membership = (leg_of_row == np.arange(len(self.legs))[:, None]).astype(float)
        self._foot_rows = np.array([self.engine.body_names.index(bodies[-1])
                                    for bodies in self.legs.values()], dtype=int)

    def _start(self):
        """Initial state (keyframe, initial positions, scenario, spawn), fresh command
        handler holding it, cleared divergence flags, control and observation ticks counted
        from here (a reset replays a fresh start's ticks)."""
        self.diverged = None
        self._ticks = 0
        self._since_start = 0  # engine steps since this (re)start: the ticks' phase
        self._steps_before = self.steps  # (the outcome counts from here)
        self._warnings = self._warning_count()
        self._left_bed = self._entered = False  # (said once a run: `run_warnings`)
        self._next_entry_check = 0.0  # sim time, s
        self._initial_pose()
        self.scenario.initialize(self)
        kind, height = self._spawn
        if kind != 'model':
            bodies = [self.model.body(b).id for b in self.sand_bodies]
            root = self.model.body_rootid[self._base_id]  # its plated bodies clear the sand
            plated = [b for b in self.engine.body_ids if self.model.body_rootid[b] == root]
            surface = self.engine.surface
            try:  # turned to the sand surface under its sand bodies, onto (or above) it
                turned = align_to(self.model, self.data, self._base_id, bodies, surface.height)
                lift_to(self.model, self.data, self._base_id, plated, height or 0.0,
                        surface.highest)
            except ValueError as error:
                raise self.scene.locator.error('robot.spawn', str(error)) from None
            notice = (f'robot.spawn {kind}: turned {np.degrees(turned):.3g} deg to the sand '
                      'surface under its sand bodies (the normal of its plane there)')
            if turned and notice not in self.notices:  # (a reset spawns again)
                self.notices.append(notice)
        mujoco.mj_forward(self.model, self.data)
        self.hybrid_drive.release()
        self.interfaces.set_mode('position')
        self.commands = None
        if self.servo_joint_names:
            self.commands = CommandHandler(self.servo_joint_names,
                                           self.data.qpos[self._command_qpos])
        if kind == 'rest':
            self._settle()
        self._unsettled_before = self._engine_counts()[1] - self._settle_counts[1]
        self._outcome.start(self.data, self.time)

    def _settle(self):
        """Spawn 'rest': step, the joints holding their targets, until the base is at rest
        (robot/pose.py), then start the clock at 0 from there. A robot that does not come to
        rest standing (still moving after SETTLE_LIMIT_S; or at rest fallen: its base turned
        more than FALL_TILT_DEG from how it was set down, onto its side or back, as one that
        cannot stand without its controller falls) starts instead from the state before, at
        rest on the sand, as spawn drop:0 would. A notice says what was seen where it was
        not a plain settling: the base's turn at the end and its largest on the way (a
        robot that rocks far and then stands is not called fallen), its speed if still
        moving, and what was done."""
        if self.commands is not None:
            self._ctrl[self.interfaces.position_actuators] = self.commands.sample(0.0).positions
        kind = mujoco.mjtState.mjSTATE_INTEGRATION
        lowered = np.empty(mujoco.mj_stateSize(self.model, kind))
        mujoco.mj_getState(self.model, self.data, lowered, kind)
        set_down = self.data.xmat[self._base_id].reshape(3, 3)[:, 2].copy()  # its up axis
        still, hold = 0, max(1, int(round(REST_HOLD_S / self.timestep)))
        check = max(1, int(round(ENTRY_CHECK_S / self.timestep)))
        failure = None
        before = self._engine_counts()
        most, most_at = 0.0, 0.0  # the base's largest turn (deg) and when (s of settling)
        for step in range(1, int(round(SETTLE_LIMIT_S / self.timestep)) + 1):
            self.engine.step()
            self.settle_steps += 1
            velocity = self.data.qvel[self.model.body_dofadr[self._base_id]:][:3]
            speed = float(np.linalg.norm(velocity))
            if not np.isfinite(speed) or speed > RUNAWAY_SPEED:
                raise SceneError(f'scene {self.scene.name}: spawn rest: the robot did not '
                                 'settle (diverged)')
            still = still + 1 if speed < REST_SPEED else 0
            if step % check == 0:
                up = self.data.xmat[self._base_id].reshape(3, 3)[:, 2]
                tilt = float(np.degrees(np.arccos(np.clip(up @ set_down, -1.0, 1.0))))
                if tilt > most:
                    most, most_at = tilt, step * self.timestep
            if still >= hold:
                break
        up = self.data.xmat[self._base_id].reshape(3, 3)[:, 2]
        tilt = float(np.degrees(np.arccos(np.clip(up @ set_down, -1.0, 1.0))))
        if tilt > most:
            most, most_at = tilt, step * self.timestep
        turns = (f'{tilt:.3g} deg from how it was set down (up to {most:.3g} deg, '
                 f'{most_at:.2f} s into settling)')
        if still < hold:
            failure = (f'still moving after {SETTLE_LIMIT_S:g} s: its base ({self.base_body}) '
                       f'at {speed:.2g} m/s, turned {turns}'
                       + (f', touching rigid geoms ({self.data.ncon} contacts), on which it '
                          'may slide' if self.data.ncon else ''))
        elif tilt > FALL_TILT_DEG:
            failure = (f'fell: its base ({self.base_body}) came to rest turned {turns}, on '
                       'its side or back')
        elif most > FALL_TILT_DEG:
            notice = (f'spawn rest: its base ({self.base_body}) came to rest after '
                      f'{step * self.timestep:.2f} s turned {turns}: it starts from there')
            if notice not in self.notices:  # (a reset settles again)
                self.notices.append(notice)
        if failure is not None:
            notice = (f'spawn rest: {failure}; so it starts as spawn drop:0 starts it instead, '
                      'where it was set down on the sand, the clock running at once')
            if notice not in self.notices:  # (a reset settles again)
                self.notices.append(notice)
            mujoco.mj_setState(self.model, self.data, lowered, kind)
            mujoco.mj_forward(self.model, self.data)
            self.engine.forget_last_step()
            self.reset_terrain()
        self._settle_counts += self._engine_counts() - before
        self.data.time = 0.0

    def _engine_counts(self):
        e = self.engine
        return np.array([e.solves, e.unsettled_steps, e.handed_back_steps], dtype=np.int64)

    @property
    def fell(self):
        """Whether the robot has fallen since the last (re)start (sim/outcome.py)."""
        return self._outcome.fell_at is not None

    def outcome(self):
        """What happened since the last (re)start, the state now included, as
        summary.json's `outcome` says it (sim/outcome.py): fell, how deep any body went, the
        unsettled share, in words."""
        self._outcome.observe(self.data, self.engine.surface, self.time)
        unsettled = self._engine_counts()[1] - self._settle_counts[1] - self._unsettled_before
        return self._outcome.result(self.data, self.engine.surface,
                                    self.steps - self._steps_before, int(unsettled))

    def implicit_counts(self):
        """The implicit solve's counts over the steps the run took (`step`, resets
        included), spawn rest's settling left out: (solves, steps that did not settle, steps
        whose constraint rows were handed back to MuJoCo), as `SandEngine` counts them."""
        return tuple(int(n) for n in self._engine_counts() - self._settle_counts)

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
        return sum(self._warning_numbers[_INSTABILITY_WARNINGS].tolist())

    def step(self, count=1):
        """Advance `count` steps: at control ticks the scenario's control and the servo
        targets, then sand + MuJoCo. Raises SimulationDiverged, and keeps `diverged` set,
        once the state blows up, or ScenarioFailed (one) once the scenario's code raised."""
        if self.diverged:
            raise SimulationDiverged(self.diverged)
        scenario, engine_step, data = self.scenario, self.engine.step, self.data
        observe_every, control_every = scenario.observe_interval, self._control_every
        try:
            for _ in range(count):
                if self._since_start % control_every == 0:
                    self._control_tick()
                before = data.time
                engine_step()
                self.steps += 1
                self._since_start += 1
                if data.time <= before:  # MuJoCo reset a non-finite state
                    self._diverge(self._check() or 'MuJoCo reset an unstable state',
                                  self._time_offset + before)
                if self._since_start % observe_every == 0:
                    scenario.observe(self)
        except SimulationDiverged:
            raise
        except Exception as error:  # the scenario's: ends the run as a divergence does
            failure = self.scenario_failure(error)
            if failure is None:
                raise
            raise failure from None

    def _control_tick(self):
        self._ticks += 1
        if self._ticks % self._check_every == 0:
            problem = self._check()
            if problem:
                self._diverge(problem)
        if self._ticks % self._outcome_every == 0:
            self._outcome.observe(self.data, self.engine.surface, self.time)
        self.scenario.control(self)
        commands = self.commands
        if commands is not None:
            interfaces, efforts, hybrid = self.interfaces, commands.efforts, commands.hybrid
            drive = self.hybrid_drive
            if hybrid is not None:
                if not drive.engaged:
                    drive.engage()
                    self._ctrl[interfaces.effort_actuators] = 0.0
                self._ctrl[interfaces.position_actuators] = drive.controls(hybrid)
                commands.track(self.data.qpos[self._command_qpos], self.time)
                return
            if drive.engaged:
                drive.release()
            if efforts is None:
                if interfaces.mode != 'position':
                    interfaces.set_mode('position')
                    self._ctrl[interfaces.effort_actuators] = 0.0
                self._ctrl[interfaces.position_actuators] = commands.sample(self.time).positions
            else:
                if interfaces.mode != 'effort':
                    interfaces.set_mode('effort')
                self._ctrl[interfaces.effort_actuators] = efforts
                commands.track(self.data.qpos[self._command_qpos], self.time)

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
        peak = np.maximum.reduce(np.abs(qvel)) if qvel.size else 0.0
        if not peak <= RUNAWAY_SPEED:  # also catches NaN
            return f'runaway speed {peak:.3g} (> {RUNAWAY_SPEED:g} m/s or rad/s)'
        return None

    def reset(self):
        """Back to the scene's initial state (deformable sand: its pristine surface, on which
        a spawn at rest then settles again, as at the start), the sand engine's memory of the
        last step forgotten: the run that follows is a fresh start's; sim time keeps
        counting forward, and settings changed while running (zeta) stay as set, as the ROS
        node's parameters do."""
        self._time_offset += self.data.time
        mujoco.mj_resetData(self.model, self.data)
        self.engine.forget_last_step()
        self.reset_terrain()
        self._start()

    def reset_terrain(self):
        """Deformable sand back to its pristine surface (nothing to do on rigid sand)."""
        if self.engine.deformable:
            self.engine.surface.reset()

    def terrain_metrics(self):
        """Deformable sand's summary metrics (`DeformableSand.metrics`); {} on rigid sand."""
        return self.engine.surface.metrics() if self.engine.deformable else {}

    def _ground_to_sand(self):
        """Switch off the rigid collisions of the model's ground that the sand replaces: the
        hfield geom that is the sand's surface, and the floor planes (`floor_planes`, said in
        a notice) unless sand.keep_floor. The model's other hfields stay rigid ground, said
        in a notice with the keys that make one of them the sand's surface."""
        scene, model = self.scene, self.model
        ground = [] if scene.keep_floor else floor_planes(model)
        if ground:
            names = ', '.join(model.geom(g).name or f'#{g}' for g in ground)
            self.notices.append(f'floor plane {names}: rigid collisions switched off, the sand '
                                'carries the robot (sand.keep_floor: true keeps it)')
        kind = scene.surface.get('type', 'plane')
        if kind == 'hfield':
            ground.append(hfield_geom(model, scene.surface.get('geom')))
        rigid = [g for g in world_ground(model, mujoco.mjtGeom.mjGEOM_HFIELD) if g not in ground]
        if rigid:
            labels = [hfield_label(model, g) for g in rigid]
            self.notices.append(
                f'hfield geom{"s" * (len(labels) > 1)} {", ".join(labels)}: rigid ground where '
                f"the robot meets it, not sand (the sand's surface is the {kind}); --set "
                f'sand.surface.type=hfield --set sand.surface.geom={labels[0]} makes it the '
                "sand's surface")
        model.geom_contype[ground] = model.geom_conaffinity[ground] = 0

    def run_warnings(self):
        """What a run says once (and again after each reset), the first time it happens:
        plates in the sand outside the deformable bed, a body without plates reaching into
        the sand (`sand_entry`). A list of lines, mostly empty; called at the publish rate."""
        return [line for line in (self._left_bed_warning(), self._entry_warning()) if line]

    def _left_bed_warning(self):
        sand = self.engine.surface
        if self._left_bed or not self.engine.deformable or not sand.plates_outside:
            return None
        self._left_bed = True
        (x0, y0), (sx, sy) = sand.origin, sand.size
        return (f'by t = {self.time:.2f} s plates were in the sand outside the deformable bed '
                f'(x {x0:.3g} .. {x0 + sx:.3g} m, y {y0:.3g} .. {y0 + sy:.3g} m): they leave no '
                'footprints there; enlarge sand.deformable.size or move sand.deformable.center')

    def _entry_warning(self):
        if self._entered or self.data.time < self._next_entry_check:
            return None
        self._next_entry_check = self.data.time + ENTRY_CHECK_S
        found = self._entry_watch.deepest(self.data, self.engine.surface)
        if found is None:
            return None
        self._entered = True
        body, depth = found
        return (f'by t = {self.time:.2f} s body {body} reached {depth * 100:.3g} cm into the '
                'sand: it carries no plates, so the sand does not act on it and it passes '
                "through; name it a sand body (rft.bodies; '*' takes every body) or give the "
                'other bodies plates (rft.other_bodies_density_per_mm2)')

    def leg_wrenches(self):
        """Per-leg summed sand wrenches (LegWrench, world axes; see state.py), each the mean
        over the steps since the previous call (`SandEngine.mean_wrenches`), with the torque
        about the leg's point now."""
        return self._legs_and_feet()[0]

    def _legs_and_feet(self):
        """(`leg_wrenches`, (legs, 3) the sand force on each leg's foot, its last sand body,
        N, world axes), means over the steps since the previous call."""
        wrenches = self.engine.mean_wrenches()
        # summed per leg: [force, torque about the world origin]
        sums = self._leg_membership @ wrenches[self._leg_rows]
        points = self.data.xpos[self._leg_feet]
        forces = sums[:, :3]
        torques = sums[:, 3:] - _cross(points, forces)
        return (tuple(map(LegWrench, self._leg_names, forces, torques, points)),
                wrenches[self._foot_rows, :3])

    def state(self, with_plates=False):
        """A SimState snapshot of the current state; its leg wrenches are the means over the
        steps since the previous snapshot (see `leg_wrenches`); with the sensor readings the
        scene enables (sensors.*)."""
        d = self.data
        velocity = np.empty(6)
        mujoco.mj_objectVelocity(self.model, d, mujoco.mjtObj.mjOBJ_XBODY, self._base_id,
                                 velocity, 1)  # base frame origin, base frame axes
        plates = None
        if with_plates:
            positions, forces, areas = self.engine.active_plates()
            plates = ActivePlates(positions, forces, areas)
        legs, feet = self._legs_and_feet()
        sensors = self.sensors.read(d, legs, feet) if self.sensors.active else None
        return SimState(
            time=self.time,
            joint_names=self.joint_names,
            joint_positions=d.qpos[self._qpos_adr],  # (index arrays: copies already)
            joint_velocities=d.qvel[self._dof_adr],
            joint_efforts=d.qfrc_actuator[self._dof_adr],
            base_frame=self.base_body,
            base_position=d.xpos[self._base_id].copy(),
            base_quaternion_wxyz=d.xquat[self._base_id].copy(),
            base_linear_velocity=velocity[3:],  # (this call's own array)
            base_angular_velocity=velocity[:3],
            legs=legs,
            zeta=self.engine.zeta,
            plates_active=int(self.engine.plates_active),
            active_plates=plates,
            sensors=sensors,
        )
