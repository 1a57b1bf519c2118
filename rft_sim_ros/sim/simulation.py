"""Simulation: a scene's MuJoCo model, its sand engine and its scenario, stepped together.

This is the ROS-free core that the CLI, the benchmarks and the rclpy node all drive:
build from a SceneConfig (the stages of sim/build.py, in order: description, model, sand
surface, pose, sand bodies, plates, engine, legs), `step()`, read `state()`, change `zeta`,
`reset()`.
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

from .. import prebuilt
from ..control.commands import CommandHandler
from ..kernel_names import function
from ..robot.joints import JointInterfaces
from ..robot.pose import REST_HOLD_S, REST_SPEED, SETTLE_LIMIT_S, align_to, lift_to
from ..sand.engine import cold_start_estimate, kernels_cached
from ..sand.surface import SURFACE_KINDS
from ..sand.surface_codes import KINDS
from ..scenes.config import SceneError
from ..scenes.scenarios import failure_line, load_scenario, rows_expected, scenario_files
from .build import (base_id, choose_sand_bodies, compile_model, deformable_bed, ground_to_sand,
                    in_scenario, initial_pose, legs_of, named_joints, plates_of,
                    read_description, sand_engine, sand_surface, say_moved_into_ranges,
                    servo_stiffness, spawn_of)
from .caveats import caveats
from .hybrid_drive import HybridDrive
from .outcome import TILT_LIMIT_DEG, UPSIDE_DOWN_DEG, OutcomeWatch
from .sand_entry import SandEntryWatch
from .sensors import Sensors, scene_settings
from .state import ActivePlates, LegWrench, SimState

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


def kernel_key(scene):
    """(low-velocity kernels, surface kind, deformable, step parts): what selects the
    compiled sand kernels a `scene` (SceneConfig) steps with (`engine.kernels_cached`), and
    nothing else: 'implicit' or 'explicit' (the 'ema' and 'none' methods share one set);
    the surface's kind ('plane', 'slope', 'grid': `surface_codes.KINDS`; deformable sand has
    one gather kernel whatever surface its bed lies on: 'grid'); the implicit step without
    or with MuJoCo's constraint rows, as its scenario expects (`scenarios.rows_expected`; a
    model with elliptic cones loads a third, said by a notice of the run)."""
    deformable = bool(scene.deformable.get('enabled'))
    kind = 'grid' if deformable else KINDS[SURFACE_KINDS[scene.surface.get('type', 'plane')]]
    method = 'implicit' if scene.low_velocity['method'] == 'implicit' else 'explicit'
    return method, kind, deformable, 'rows' if rows_expected(scene) else 'plain'


def compile_notice(scene):
    """The line to show before building `scene` (SceneConfig) when its sand kernels are
    neither prebuilt nor in numba's cache yet (`engine.kernels_cached`): 'compiling kernels,
    first run only', with ', ~N s as here last
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


class Simulation:
    """One scene, ready to step. Attributes: model, data, engine, scenario, scene.

    surface: a `sand.surface.Surface` made in Python (a HeightGrid of an array of heights, a
    Slope) that the sand takes instead of the scene's `sand.surface`, which must then be
    left as the plane; deformable sand (sand.deformable) lays its bed over it as over the
    scene's. summary.json's `surface` (`Surface.describe`) records which it was.
    """

    def __init__(self, scene, surface=None):
        # prebuilt kernels called with other types (numba's ran them) before this simulation,
        # and before its (re)start, which `kernels` and `run_warnings` tell theirs from
        self._made_from = self._fallbacks_from = prebuilt.fallback_calls()
        self._fallbacks_said = set()
        self.scene = scene
        self.notices = notices = list(scene.notices)  # the scene's, then what start-up decided
        self.scenario = load_scenario(scene)
        # the robot: its description, then its model
        self.description, self._initial_positions = read_description(scene, notices)
        compiled = compile_model(scene, self.scenario, self.description.spec,
                                 self._initial_positions, notices)
        self.model = model = compiled.model
        self._keyframe = compiled.keyframe
        self.passive_joint_names = compiled.joint_plan.passive
        self._other_driven = compiled.joint_plan.other_driven
        # the sand's surface, and the rigid ground it replaces
        surface, zeta_map = sand_surface(scene, model, surface, notices)
        ground_to_sand(scene, model, notices)
        # the initial pose, the body /odom follows, the bed laid out under it
        self.data = data = mujoco.MjData(model)
        say_moved_into_ranges(self._pose(), notices)
        self._base_id = base = base_id(scene, model)
        self.base_body = model.body(base).name  # (robot.description names the others)
        surface = deformable_bed(scene, surface, data, base, notices)
        # the sand bodies, their plates, the sand engine
        self.sand_bodies, others = choose_sand_bodies(scene, model, data, compiled.patterns,
                                                      base, notices)
        plates, self.other_bodies = plates_of(scene, model, self.sand_bodies, others, notices)
        self.engine = engine = sand_engine(scene, model, data, plates, surface, zeta_map)
        if engine.compiled[0]:
            notices.append(f'compiled the sand kernels ({engine.compiled[0]}) in '
                           f'{engine.compiled[1]:.0f} s; numba keeps them for the next runs')
        # what the robot reports and is commanded by: joints, legs, sensors, servos
        self._joints = named_joints(model, notices)  # (those /joint_states reports)
        self.joint_names = tuple(model.joint(j).name for j in self._joints)
        self._qpos_adr = model.jnt_qposadr[self._joints]
        self._dof_adr = model.jnt_dofadr[self._joints]
        # actuator forces (qfrc_actuator) summed over the steps since step `_effort_since`
        self._effort_sum, self._effort_since = np.zeros(model.nv), 0
        legs = legs_of(scene, model, engine, self.sand_bodies, self.other_bodies, base)
        self.legs, self._leg_names, self._leg_feet = legs.legs, legs.names, legs.feet
        self._leg_rows, self._leg_membership = legs.rows, legs.membership
        self._foot_rows = legs.foot_rows
        try:
            self.sensors = Sensors(model, base, self._leg_names, scene_settings(scene.values),
                                   engine.surface, engine.deformable)
        except ValueError as error:
            raise scene.locator.error('sensors', str(error)) from None
        notices += caveats(model, data, engine, scene, base, len(self.sand_bodies))
        self._entry_watch = SandEntryWatch(model, engine.body_ids)
        self._outcome = OutcomeWatch(model, base, engine.body_ids,
                                     engine.body_ids[:len(self.sand_bodies)])
        servo_stiffness(scene, model)
        mujoco.mj_forward(model, data)
        self.interfaces = JointInterfaces(
            model, data, compiled.joint_plan.commanded, scene.servos, scene.timestep,
            effort_limits=self.description.effort_limits)
        self.servo_joint_names = self.interfaces.joint_names
        self.hybrid_drive = HybridDrive(model, self.interfaces, scene.values.get('joint_gains'))
        self._command_qpos = model.jnt_qposadr[
            [model.joint(name).id for name in self.servo_joint_names]].astype(int)
        self._spawn = spawn_of(scene, model, base, notices)
        # the step loop's rates and counts, then the start (spawn, settling)
        self._control_every = max(1, int(round(1.0 / (scene.control_rate * scene.timestep))))
        # runaway checks at ~CHECK_RATE Hz of sim time (MuJoCo's own resets: every step)
        self._check_every = max(1, int(round(
            1.0 / (CHECK_RATE * self._control_every * scene.timestep))))
        self._outcome_every = max(1, int(round(
            1.0 / (OUTCOME_RATE * self._control_every * scene.timestep))))
        self._ctrl = data.ctrl
        self._warning_numbers = data.warning.number  # a view of mjData's warning counts
        self._time_offset = 0.0
        self.steps = 0  # engine steps since the start, resets included (the run's count)
        self.settle_steps = 0  # engine steps spawn rest took to settle, resets included
        self._settle_counts = np.zeros(3, dtype=np.int64)  # their `_engine_counts`
        in_scenario(scene, self.scenario, self._start)

    def scenario_failure(self, error):
        """ScenarioFailed for exception `error` where the scenario's code raised it (a frame
        of its traceback in the scenario's source), else None; sets `diverged`."""
        line = failure_line(error, scenario_files(type(self.scenario)))
        if line is None:
            return None
        self.diverged = f'at t = {self.time:.4f} s: the scenario raised at {line}'
        self._stopped_at = self.time
        return ScenarioFailed(self.diverged, ''.join(traceback.format_exception(error)))

    def _pose(self):
        """The scene's initial pose in `data` (`build.initial_pose`); returns the joints it
        moved into their ranges."""
        return initial_pose(self.scene, self.model, self.data, self._keyframe,
                            self._initial_positions)

    def _start(self):
        """Initial state (keyframe, initial positions, scenario, spawn), fresh command
        handler holding it, cleared divergence flags, control and observation ticks counted
        from here (a reset replays a fresh start's ticks)."""
        self.diverged = None
        self._stopped_at = None  # sim time s of the divergence (`diverged`)
        self._ticks = 0
        self._since_start = 0  # engine steps since this (re)start: the ticks' phase
        self._steps_before = self.steps  # (the outcome counts from here)
        self._effort_sum[:], self._effort_since = 0.0, self.steps
        self._warnings = self._warning_count()
        self._left_bed = self._entered = False  # (said once a run: `run_warnings`)
        self._next_entry_check = 0.0  # sim time, s
        self._pose()
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
        self._outcome.set_down(self.data)
        up = self._outcome.up_angle_set_down
        if up is not None and up > TILT_LIMIT_DEG:
            notice = (f"the base ({self.base_body}) is set down "
                      f'{"upside down" if up > UPSIDE_DOWN_DEG else "tilted"}: its z axis '
                      f'{up:.0f} deg from up (a standing robot\'s base frame has z up, REP '
                      '103); the outcome says so')
            if notice not in self.notices:  # (a reset sets it down again)
                self.notices.append(notice)
        self.hybrid_drive.release()
        self.interfaces.set_mode('position')
        self.commands = None
        if self.servo_joint_names:
            self.commands = CommandHandler(self.servo_joint_names,
                                           self.data.qpos[self._command_qpos],
                                           self.passive_joint_names, self.interfaces.ranges)
        if kind == 'rest':
            self._settle()
        self._counts_before = self._engine_counts() - self._settle_counts
        self._outcome.start()
        self._outcome.observe(self.data, self.engine.surface, self.time)  # (as it starts)

    def _settle(self):
        """Spawn 'rest': step, the joints holding their targets, until the base is at rest
        (robot/pose.py), then start the clock at 0 from there. A robot that does not come to
        rest standing (still moving after SETTLE_LIMIT_S; or at rest fallen: its base turned
        more than FALL_TILT_DEG from how it was set down, onto its side or back, as one that
        cannot stand without its controller falls; or at rest collapsed or sunk, its centre
        of mass held up less than half as high above its sand bodies as set down, or its
        base more than 5 cm into the sand, as one whose servos are too weak for it lies down
        on its belly: sim/outcome.py's `OutcomeWatch.problem`) starts instead from the state
        before, at rest on the sand, as spawn drop:0 would. A notice says what was seen
        where it was not a plain settling: the base's turn at the end and its largest on the
        way (a robot that rocks far and then stands is not called fallen), its speed if
        still moving, and what was done."""
        if self.commands is not None:
            self._ctrl[self.interfaces.position_actuators] = self.commands.sample(0.0).positions
        kind = mujoco.mjtState.mjSTATE_INTEGRATION
        lowered = np.empty(mujoco.mj_stateSize(self.model, kind))
        mujoco.mj_getState(self.model, self.data, lowered, kind)
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
                tilt = self._outcome.tilt(self.data)  # (from how it was set down)
                if tilt > most:
                    most, most_at = tilt, step * self.timestep
            if still >= hold:
                break
        tilt = self._outcome.tilt(self.data)
        if tilt > most:
            most, most_at = tilt, step * self.timestep
        problem = self._outcome.problem(self.data, self.engine.surface)
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
        elif problem is not None:
            failure = f'{problem}, at rest'
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
    def down(self):
        """Whether the robot has fallen, turned upside down, collapsed or sunk since the last
        (re)start (sim/outcome.py)."""
        return self._outcome.down

    def outcome(self):
        """What happened since the last (re)start, the state now included, as
        summary.json's `outcome` says it (sim/outcome.py): fell, collapsed or sank, how deep
        any body went, the unsettled share, in words."""
        self._outcome.observe(self.data, self.engine.surface, self.time)
        _, unsettled, handed_back = (self._engine_counts() - self._settle_counts
                                     - self._counts_before)
        return self._outcome.result(self.data, self.engine.surface,
                                    self.steps - self._steps_before, int(unsettled),
                                    int(handed_back), self._stopped_at)

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
        actuation, effort_sum, add = data.qfrc_actuator, self._effort_sum, np.add
        try:
            for _ in range(count):
                if self._since_start % control_every == 0:
                    self._control_tick()
                before = data.time
                engine_step()
                add(effort_sum, actuation, out=effort_sum)
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
                self._ctrl[interfaces.position_actuators] = drive.controls(
                    hybrid.advance(self.time), self.data.qpos[self._command_qpos])
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
        self._stopped_at = at_time
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
        self._fallbacks_from, self._fallbacks_said = prebuilt.fallback_calls(), set()
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

    def run_warnings(self):
        """What a run says once (and again after each reset), the first time it happens:
        plates in the sand outside the deformable bed, a body without plates reaching into
        the sand (`sand_entry`), a prebuilt kernel called with other types than it was built
        for since the start (`prebuilt.fallbacks_since`: numba's ran it), once for each
        argument that did not match. A list of lines, mostly empty; called at the publish
        rate."""
        return [line for line in (self._left_bed_warning(), self._entry_warning(),
                                  *self._fallback_warnings()) if line]

    def _fallback_warnings(self):
        """A line for each prebuilt kernel called with other types than it was built for
        since this start, once for each argument that did not match (`run_warnings`)."""
        new = [key for key in prebuilt.fallbacks_since(self._fallbacks_from)
               if key not in self._fallbacks_said]
        self._fallbacks_said.update(new)
        return [f'the prebuilt kernel {function(name)} was called with other types than it '
                f'was built for ({why}): numba\'s kernel runs those calls, with the same '
                'results, after it compiles or loads' for name, why in new]

    @property
    def kernels(self):
        """One line: whether the sand engine's step calls the prebuilt kernels or numba's,
        and why (`SandEngine.kernels`), and each prebuilt kernel called with other types than
        it was built for since this simulation was made (its scenario's and gaits' too: numba's
        ran them; `prebuilt.fallback_line`): what a run's summary and /diagnostics say."""
        return self.engine.kernels + prebuilt.fallback_line(self._made_from)

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
                "through; name it a sand body (rft.sand_bodies; '*' takes every body) or give the "
                'other bodies plates (rft.other_bodies_density_per_mm2)')

    def leg_wrenches(self):
        """Per-leg summed sand wrenches (LegWrench, world axes; see state.py), each the mean
        over the steps since the previous call (`SandEngine.mean_wrenches`), with the torque
        about the leg's point now."""
        return self._legs_and_feet()[0]

    def no_commands_reason(self):
        """Why `commands` is None, in words: 'this scene has no commanded joints (passive:
        ...; driven by the model's own actuators of another kind: ...; ...)'."""
        kinds = [(self.passive_joint_names, 'passive'),
                 (self._other_driven, "driven by the model's own actuators of another kind")]
        said = '; '.join(f'{what}: {", ".join(names)}' for names, what in kinds if names)
        return ('this scene has no commanded joints' + (f' ({said}; the start-up notices '
                                                         'say how to give them servos)'
                                                         if said else ''))

    def _mean_efforts(self):
        """(joints,) N m or N: each joint's actuator force, the mean over the steps since the
        last call (with none since, the last step's); then restarts the mean."""
        steps, self._effort_since = self.steps - self._effort_since, self.steps
        if not steps:
            return self.data.qfrc_actuator[self._dof_adr]
        mean = self._effort_sum[self._dof_adr] / steps
        self._effort_sum[:] = 0.0
        return mean

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
        """A SimState snapshot of the current state; its joint efforts and leg wrenches are
        the means over the steps since the previous snapshot (see `leg_wrenches`; with no
        step since, the last step's), as a filtered sensor reports them: a servo whose target
        moves between control ticks (a velocity command, a trajectory) pushes a sawtooth
        about its mean, which a sample at every publish period, in phase with the ticks,
        would read on one side only; with the sensor readings the scene enables
        (sensors.*)."""
        d = self.data
        velocity = np.empty(6)
        mujoco.mj_objectVelocity(self.model, d, mujoco.mjtObj.mjOBJ_XBODY, self._base_id,
                                 velocity, 1)  # base frame origin, base frame axes
        plates = None
        if with_plates:
            positions, forces, areas = self.engine.active_plates()
            plates = ActivePlates(positions, forces, areas)
        legs, feet = self._legs_and_feet()
        sensors = (self.sensors.read(d, legs, feet, stepped=self._since_start > 0)
                   if self.sensors.active else None)
        return SimState(
            time=self.time,
            joint_names=self.joint_names,
            joint_positions=d.qpos[self._qpos_adr],  # (index arrays: copies already)
            joint_velocities=d.qvel[self._dof_adr],
            joint_efforts=self._mean_efforts(),
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
