"""Servo position targets from joint commands, as ros2_control's controllers treat them.

ROS-free: the rclpy node and headless runs feed the same `CommandHandler`. Two inputs:

* `TrajectoryCommand` (trajectory_msgs/JointTrajectory), handled like
  joint_trajectory_controller with trajectory replacement. A trajectory takes over at its
  start time (0 = on receipt; a start in the past also means on receipt) from the target
  state at that moment (position and velocity); until then the active trajectory keeps
  running. Only the newest deferred trajectory is kept, and a command that takes effect at
  once discards it. Waypoints whose time has already passed at takeover are dropped (a
  trajectory that ends in the past is rejected); a first waypoint exactly at takeover is
  jumped to, as in joint_trajectory_controller. Segments are linear when either end has
  positions only and cubic Hermite when both ends carry velocities; the state at takeover
  always carries its velocity. Joints left out of a trajectory hold the target they have at
  takeover (velocity 0 at waypoints with velocities). After the last waypoint its
  positions are held with velocity 0. Accelerations and efforts are not used.
* `set_positions` (std_msgs/Float64MultiArray to forward_position_controller): new
  targets for all joints in `joint_names` order, held from now on; cancels any trajectory.
  `hold_positions` does the same, unchecked, for the targets of a built-in gait.
* `set_velocities` (std_msgs/Float64MultiArray to a velocity forward controller, ros2_control's
  JointGroupVelocityController): velocities for all joints in `joint_names` order (rad/s or
  m/s), held from now on: each joint's target moves at its velocity from the target it has
  now, so the servo turns a wheel at that speed (its position lags the target by what the
  load asks of the servo's gain), and stops at the end of a limited joint's range
  (`ranges`); cancels any trajectory, and a later trajectory takes over from the moving
  target, velocity included.
* `set_efforts` (std_msgs/Float64MultiArray to the effort forward controller): efforts for
  all joints in `joint_names` order (N m or N), applied from now on instead of the position
  targets (`efforts` is then not None) until the next position command or trajectory; the
  simulation reports the joints' positions meanwhile (`track`), so that a trajectory then
  starts where the joints are.
* `set_joint_states` (a `joint_state_commands.JointStateCommand`, read from the
  sensor_msgs/JointState of ros2_control's topic hardware interface): hybrid mode, per joint
  position, velocity and feed-forward effort under the law of `control.hybrid` (`hybrid` is
  then not None) until the next position command, trajectory or effort command; positions
  are tracked as in effort mode.

Every command is validated first; a bad one is rejected with a `CommandResult` naming the
problem, counted per `Reason`, and changes nothing (`CommandResult.check` turns a rejection
into a `CommandRejected` exception, for scripts that must stop on it). Times are sim time
in s; positions in rad (or m), velocities in rad/s (or m/s), in the joint's own unit.
"""
import bisect
import enum
import math
import numbers
import reprlib
from collections import Counter
from dataclasses import dataclass
from typing import NamedTuple, Optional, Sequence, Tuple

import numpy as np

from rft_sim_ros.control.hybrid import HybridTargets

class Reason(str, enum.Enum):
    """Why a command was rejected (the key of `CommandHandler.rejections`)."""
    MALFORMED = 'malformed'
    EMPTY = 'empty'
    ARRAY_LENGTH = 'array_length'
    UNKNOWN_JOINT = 'unknown_joint'
    DUPLICATE_JOINT = 'duplicate_joint'
    NOT_FINITE = 'not_finite'
    TIME_NEGATIVE = 'time_negative'
    TIME_NOT_INCREASING = 'time_not_increasing'
    POSITIONS_LENGTH = 'positions_length'
    VELOCITIES_LENGTH = 'velocities_length'
    ENDS_IN_PAST = 'ends_in_past'
    #: a FollowJointTrajectory goal's own parts: tolerances, multi-DOF joints
    #: (`trajectory_goals`)
    GOAL = 'goal'


@dataclass(frozen=True)
class CommandResult:
    """Outcome of a command: accepted, or rejected for `reason` explained in `message`.
    span: an accepted trajectory's start and the time of its last waypoint (s of sim time),
    else None."""
    reason: Optional[Reason] = None
    message: str = ''
    span: Optional[Tuple[float, float]] = None

    @property
    def accepted(self):
        return self.reason is None

    def check(self):
        """This result if the command was accepted; else raises `CommandRejected` with the
        reason and message: for a script or a learning loop that must stop on a bad command
        rather than go on with the targets held before it."""
        if self.reason is not None:
            raise CommandRejected(self)
        return self


class CommandRejected(ValueError):
    """A rejected command (`CommandResult.check`); `result` is its CommandResult."""

    def __init__(self, result):
        super().__init__(f'command rejected ({result.reason.value}): {result.message}')
        self.result = result


#: The result of every accepted command.
ACCEPTED = CommandResult()


@dataclass(frozen=True)
class TrajectoryPoint:
    """One waypoint: positions (one per joint of the command), optional velocities (None or
    empty = positions only) and time_from_start (s after the trajectory's start time)."""
    positions: Sequence[float]
    time_from_start: float
    velocities: Optional[Sequence[float]] = None


@dataclass(frozen=True)
class TrajectoryCommand:
    """A joint trajectory: joint names, waypoints and start time (s of sim time; 0 = now)."""
    joint_names: Sequence[str]
    points: Sequence[TrajectoryPoint]
    start_time: float = 0.0


class Targets(NamedTuple):
    """Servo targets at one instant, in `CommandHandler.joint_names` order."""
    positions: np.ndarray
    velocities: np.ndarray


class _Rejected(Exception):
    def __init__(self, reason, message):
        super().__init__(message)
        self.reason = reason


def check_joint_names(names, known, empty, passive=()):
    """Raise _Rejected unless the joint `names` of a command are strings, at least one
    (`empty`: the reason given when there is none), each named once and all in `known` (the
    joints commands may address, a mapping or sequence in their order); `passive`: the
    robot's joints without command interfaces, said as such where named."""
    if not all(isinstance(n, str) for n in names):
        raise _Rejected(Reason.MALFORMED, f'joint names must be strings, got '
                                          f'{reprlib.repr(names)}')
    if not names:
        raise _Rejected(Reason.EMPTY, empty)
    duplicates = sorted(n for n, c in Counter(names).items() if c > 1)
    if duplicates:
        raise _Rejected(Reason.DUPLICATE_JOINT,
                        f'joint(s) named more than once: {", ".join(duplicates)}')
    unknown = [n for n in names if n not in known]
    if unknown:
        free = [n for n in unknown if n in passive]
        others = [n for n in unknown if n not in passive]
        said = ([f'passive joint(s) {", ".join(free)} (no command interfaces: the scene\'s '
                 'servos can give them a servo)'] if free else []) + (
            [f'unknown joint(s) {", ".join(others)}'] if others else [])
        raise _Rejected(Reason.UNKNOWN_JOINT, f'{"; ".join(said)}; commanded joints: '
                                              f'{", ".join(known)}')


class _Spline:
    """Piecewise linear / cubic Hermite target path through knots (times strictly increasing).

    positions, velocities: (K, J); cubic: (K,) whether the knot's velocities are given.
    Before the first knot and after the last, that knot's positions are held (velocity 0).
    """

    def __init__(self, times, positions, velocities, cubic):
        self.times = list(times)
        self.positions = positions
        self.velocities = velocities
        self.cubic = cubic

    def sample(self, t):
        times = self.times
        if t < times[0] or t >= times[-1]:
            k = 0 if t < times[0] else -1
            return Targets(self.positions[k].copy(), np.zeros(self.positions.shape[1]))
        k = bisect.bisect_right(times, t) - 1
        duration = times[k + 1] - times[k]
        s = (t - times[k]) / duration
        p0, p1 = self.positions[k], self.positions[k + 1]
        if not (self.cubic[k] and self.cubic[k + 1]):
            return Targets(p0 + (p1 - p0) * s, (p1 - p0) / duration)
        m0 = self.velocities[k] * duration
        m1 = self.velocities[k + 1] * duration
        position = ((2 * s**3 - 3 * s**2 + 1) * p0 + (s**3 - 2 * s**2 + s) * m0
                    + (-2 * s**3 + 3 * s**2) * p1 + (s**3 - s**2) * m1)
        velocity = ((6 * s**2 - 6 * s) * p0 + (3 * s**2 - 4 * s + 1) * m0
                    + (-6 * s**2 + 6 * s) * p1 + (3 * s**2 - 2 * s) * m1) / duration
        return Targets(position, velocity)


class _Hold:
    """Targets held at `positions` ((J,) float array, taken over), velocity 0: what a
    position command, a built-in gait's tick, the start, or the joints' positions tracked in
    effort and hybrid modes (`track`) set."""

    def __init__(self, positions):
        self.positions = positions

    def sample(self, t):
        return Targets(self.positions.copy(), np.zeros(self.positions.shape[0]))


class _Ramp:
    """Targets moving at constant `velocities` (J,) from `positions` (J,) at `time` (s) on,
    each stopping at its end of (`low`, `high`) (J,): a joint's range, so that a target
    driven past it does not run on (and a reversed command starts from the stop)."""

    def __init__(self, time, positions, velocities, low, high):
        self.time, self.positions, self.velocities = time, positions, velocities
        self._low, self._high = low, high

    def sample(self, t):
        moved = self.positions + self.velocities * (t - self.time)
        positions = np.clip(moved, self._low, self._high)
        return Targets(positions, np.where(positions == moved, self.velocities, 0.0))


@dataclass(frozen=True)
class _Plan:
    """A validated trajectory: absolute waypoint times, indices of its joints, values."""
    start: float
    times: np.ndarray            # (K,) s of sim time
    joints: np.ndarray           # (n,) indices into joint_names
    positions: np.ndarray        # (K, n)
    velocities: np.ndarray       # (K, n), zeros where not given
    has_velocities: np.ndarray   # (K,) bool


def _float_vector(values, what):
    try:
        raw = np.asarray(values)
    except (TypeError, ValueError) as error:
        raise _Rejected(Reason.MALFORMED, f'{what} must be numbers ({error})') from None
    if raw.dtype.kind not in 'iuf':
        raise _Rejected(Reason.MALFORMED, f'{what} must be numbers, got {reprlib.repr(values)}')
    if raw.ndim != 1:
        raise _Rejected(Reason.MALFORMED, f'{what} must be a flat list of numbers')
    return raw.astype(float)


def _float_scalar(value, what):
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise _Rejected(Reason.MALFORMED, f'{what} must be a number, got {reprlib.repr(value)}')
    out = float(value)
    if not math.isfinite(out):
        raise _Rejected(Reason.NOT_FINITE, f'{what} is {out}')
    return out


def _check_finite(values, what, names):
    finite = np.isfinite(values)
    if not np.logical_and.reduce(finite):  # (.all() adds a Python wrapper, at every tick)
        bad = [names[i] for i in np.flatnonzero(~finite)]
        raise _Rejected(Reason.NOT_FINITE, f'{what} not finite for joint(s) {", ".join(bad)}')


class CommandHandler:
    """Turns joint commands into servo targets sampled in sim time.

    joint_names: the joints commands may address; array commands list positions in this
    order and `sample` returns targets in it. initial_positions: targets until the first
    command (rad or m). passive_joint_names: the robot's joints without command interfaces
    (a rejection naming one says so). ranges: (joints, 2) each joint's range, rad or m (+-inf
    where it has none; None: none has), where a velocity command's target stops.
    """

    def __init__(self, joint_names, initial_positions, passive_joint_names=(), ranges=None):
        self.joint_names = tuple(str(n) for n in joint_names)
        self._passive = tuple(passive_joint_names)  # (named in rejections as such)
        count = len(self.joint_names)
        bounds = (np.array(ranges, dtype=float).reshape(count, 2) if ranges is not None
                  else np.tile([-np.inf, np.inf], (count, 1)))
        self._low, self._high = bounds[:, 0].copy(), bounds[:, 1].copy()  # (a velocity's)
        if not self.joint_names or len(set(self.joint_names)) != len(self.joint_names):
            raise ValueError(f'joint names must be non-empty and unique: {self.joint_names}')
        initial = np.array(initial_positions, dtype=float)
        if initial.shape != (len(self.joint_names),) or not np.all(np.isfinite(initial)):
            raise ValueError(f'need {len(self.joint_names)} finite initial positions, '
                             f'got {initial_positions!r}')
        self._index = {name: i for i, name in enumerate(self.joint_names)}
        self._active = _Hold(initial)
        self._pending = None
        self._efforts = None
        self._hybrid = None
        self._rejections = Counter()

    @property
    def rejections(self):
        """{reason value: count} of rejected commands since construction."""
        return {reason.value: n for reason, n in self._rejections.items()}

    def sample(self, t):
        """`Targets` at sim time `t` (s); `t` should not go back past commands given."""
        if self._pending is not None:
            self._start_pending(t)
        return self._active.sample(t)

    def set_positions(self, positions, now):
        """Hold `positions` (all joints, `joint_names` order) from sim time `now` (s) on."""
        try:
            values = self._joint_array(positions, 'position command')
        except _Rejected as rejected:
            return self._reject(rejected)
        self.hold_positions(values, now)
        return ACCEPTED

    def hold_positions(self, positions, now):
        """`set_positions` for targets the simulation's own code computed (a built-in gait,
        at every control tick), without the checks that commands from outside get:
        `positions` must be a float array of one finite value per joint (`joint_names`
        order), and is held as it is (the caller must not change it afterwards)."""
        self._pending = None
        self._efforts = self._hybrid = None
        self._active = _Hold(positions)

    def set_velocities(self, velocities, now):
        """Move every joint's target at `velocities` (all joints, `joint_names` order; rad/s or
        m/s) from sim time `now` (s) on, from the targets at `now` (module docstring)."""
        try:
            values = self._joint_array(velocities, 'velocity command')
        except _Rejected as rejected:
            return self._reject(rejected)
        start = self.sample(now).positions
        self._pending = None
        self._efforts = self._hybrid = None
        self._active = _Ramp(now, start, values, self._low, self._high)
        return ACCEPTED

    def set_efforts(self, efforts, now):
        """Apply `efforts` (all joints, `joint_names` order; N m or N) from sim time `now` (s)
        on: effort mode, as ros2_control's effort forward controller, until the next position
        command or trajectory (which starts from the positions last given to `track`)."""
        try:
            values = self._joint_array(efforts, 'effort command')
        except _Rejected as rejected:
            return self._reject(rejected)
        self._pending = self._hybrid = None
        self._efforts = values
        return ACCEPTED

    def set_joint_states(self, command, now):
        """Apply a `JointStateCommand` (already read and checked: `joint_state_commands`) at
        sim time `now` (s): hybrid mode from now on (module docstring); entering it, every
        joint's position target is its target now, velocity and effort 0."""
        if self._hybrid is None:
            self._hybrid = HybridTargets(self.sample(now).positions, now)
        self._pending = self._efforts = None
        self._hybrid.update(command, now)
        return ACCEPTED

    @property
    def hybrid(self):
        """The `HybridTargets` in hybrid mode (`set_joint_states`); None otherwise."""
        return self._hybrid

    def track(self, positions, now):
        """In effort or hybrid mode: the joints are at `positions` (`joint_names` order) at sim time
        `now`; a later trajectory starts from there (as joint_trajectory_controller starts
        from the current state), not from the targets held before the efforts."""
        if self._efforts is not None or self._hybrid is not None:
            self._active = _Hold(np.asarray(positions, dtype=float))

    @property
    def efforts(self):
        """The commanded efforts (N m or N, `joint_names` order) in effort mode; None in
        position mode."""
        return self._efforts

    def _joint_array(self, values, what):
        """One finite value per joint, `joint_names` order, as a new float array; raises
        _Rejected."""
        if type(values) is np.ndarray and values.dtype == np.float64 \
                and values.shape == (len(self.joint_names),):
            values = values.copy()  # what a gait or controller hands over each tick, as is
        else:
            values = _float_vector(values, what)
        if values.size != len(self.joint_names):
            raise _Rejected(Reason.ARRAY_LENGTH,
                            f'{what} has {values.size} values, expected '
                            f'{len(self.joint_names)} ({", ".join(self.joint_names)})')
        _check_finite(values, what, self.joint_names)
        return values

    def set_trajectory(self, command, now):
        """Accept `command` (a `TrajectoryCommand`) received at sim time `now` (s), or reject it.

        Never raises for bad input: the returned `CommandResult` says what was wrong, or
        gives the accepted trajectory's span.
        """
        result, plan = self._plan(command, now)
        if plan is None:
            return result
        self._start_pending(now)
        self._efforts = self._hybrid = None
        if plan.start > now:
            self._pending = plan
        else:
            self._pending = None
            self._active = self._spline(plan, now)
        return result

    def check_trajectory(self, command, now):
        """`set_trajectory`'s verdict on `command` at sim time `now` (s), changing nothing
        but the count of rejections (an action server's decision to accept a goal)."""
        return self._plan(command, now)[0]

    def _plan(self, command, now):
        """(CommandResult, the validated _Plan or None if rejected)."""
        try:
            plan = self._validate(command, now)
        except _Rejected as rejected:
            return self._reject(rejected), None
        return CommandResult(span=(plan.start, float(plan.times[-1]))), plan

    def _reject(self, rejected):
        self._rejections[rejected.reason] += 1
        return CommandResult(rejected.reason, str(rejected))

    def _start_pending(self, t):
        if self._pending is not None and t >= self._pending.start:
            plan, self._pending = self._pending, None
            self._active = self._spline(plan, plan.start)

    def _spline(self, plan, handoff):
        """The active path once `plan` takes over at sim time `handoff` (s)."""
        before = self._active.sample(handoff)
        keep = plan.times >= handoff
        count = int(keep.sum())
        positions = np.tile(before.positions, (count, 1))
        velocities = np.zeros_like(positions)
        positions[:, plan.joints] = plan.positions[keep]
        velocities[:, plan.joints] = plan.velocities[keep]
        times, cubic = plan.times[keep], plan.has_velocities[keep]
        if times[0] > handoff:
            times = np.concatenate([[handoff], times])
            positions = np.vstack([before.positions, positions])
            velocities = np.vstack([before.velocities, velocities])
            cubic = np.concatenate([[True], cubic])
        return _Spline(times, positions, velocities, cubic)

    def _validate(self, command, now):
        try:
            names = list(command.joint_names)
            points = list(command.points)
            start_value = command.start_time
        except (AttributeError, TypeError) as error:
            raise _Rejected(Reason.MALFORMED, f'not a joint trajectory ({error})') from None
        check_joint_names(names, self._index, 'trajectory has no joint names', self._passive)
        if not points:
            raise _Rejected(Reason.EMPTY, 'trajectory has no points')
        start = _float_scalar(start_value, 'start time')
        if start < 0.0:
            raise _Rejected(Reason.TIME_NEGATIVE, f'start time {start} s is negative')
        positions, velocities, has_velocities, offsets = [], [], [], []
        for i, point in enumerate(points):
            p, v, offset = self._validate_point(i, point, names, offsets)
            positions.append(p)
            has_velocities.append(v is not None)
            velocities.append(v if v is not None else np.zeros(len(names)))
            offsets.append(offset)
        explicit_start = start != 0.0
        if not explicit_start:
            start = now
        if not math.isfinite(start + offsets[-1]):
            raise _Rejected(Reason.NOT_FINITE, f'trajectory end time {start + offsets[-1]} s')
        times = start + np.array(offsets)
        if np.any(np.diff(times) <= 0.0):
            raise _Rejected(Reason.TIME_NOT_INCREASING,
                            f'waypoint times too close to tell apart at start time {start} s')
        if explicit_start and times[-1] < now:
            raise _Rejected(Reason.ENDS_IN_PAST,
                            f'trajectory starting at {start} s ends at {times[-1]} s, '
                            f'before now ({now} s)')
        return _Plan(start=start, times=times,
                     joints=np.array([self._index[n] for n in names]),
                     positions=np.array(positions), velocities=np.array(velocities),
                     has_velocities=np.array(has_velocities))

    @staticmethod
    def _validate_point(i, point, names, earlier_offsets):
        try:
            raw_positions, raw_velocities = point.positions, point.velocities
            raw_time = point.time_from_start
        except AttributeError as error:
            raise _Rejected(Reason.MALFORMED, f'point {i} is not a trajectory point '
                                              f'({error})') from None
        positions = _float_vector(raw_positions, f'point {i} positions')
        if positions.size != len(names):
            raise _Rejected(Reason.POSITIONS_LENGTH,
                            f'point {i} has {positions.size} positions for {len(names)} joints')
        _check_finite(positions, f'point {i} positions', names)
        velocities = None
        if raw_velocities is not None:
            velocities = _float_vector(raw_velocities, f'point {i} velocities')
            if velocities.size == 0:
                velocities = None
            elif velocities.size != len(names):
                raise _Rejected(Reason.VELOCITIES_LENGTH,
                                f'point {i} has {velocities.size} velocities for '
                                f'{len(names)} joints')
            else:
                _check_finite(velocities, f'point {i} velocities', names)
        offset = _float_scalar(raw_time, f'point {i} time_from_start')
        if offset < 0.0:
            raise _Rejected(Reason.TIME_NEGATIVE,
                            f'point {i} time_from_start {offset} s is negative')
        if earlier_offsets and offset <= earlier_offsets[-1]:
            raise _Rejected(Reason.TIME_NOT_INCREASING,
                            f'point {i} time_from_start {offset} s is not after point {i - 1} '
                            f'({earlier_offsets[-1]} s)')
        return positions, velocities, offset
