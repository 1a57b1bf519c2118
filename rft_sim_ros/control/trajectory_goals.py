"""Goals of control_msgs/action/FollowJointTrajectory, followed as ros2_controllers'
joint_trajectory_controller follows them: tolerances, feedback and outcome.

ROS-free: `rft_sim_ros.ros.runtime.SimRuntime` runs the goal's trajectory through the same
`CommandHandler` as a trajectory on the topic, and checks the goal once per publish cycle
with `FollowedGoal.check`. The rules, as joint_trajectory_controller's (ros2_controllers,
`joint_trajectory_controller.cpp` and `tolerances.hpp`):

* error = desired - actual, per joint, for positions (rad or m) and velocities (rad/s or
  m/s); desired is the interpolated trajectory at the cycle's sim time.
* Tolerances (control_msgs/JointTolerance, per joint name): > 0 is checked, 0 means the
  default and -1 means erased; the defaults are none (nothing checked), as the
  controller's with no `constraints` parameters. Any other negative value rejects the goal,
  as does a tolerance naming a joint that is not commanded, or a tolerance on
  accelerations (the servos follow positions and velocities only).
* Path tolerance: checked while the trajectory runs (before the time of its last waypoint);
  exceeded -> aborted with PATH_TOLERANCE_VIOLATED.
* Goal tolerance: from the time of the last waypoint on, the goal succeeds (SUCCESSFUL) in
  the first cycle where every joint is within it; with no goal tolerance that is the first
  cycle at or after the last waypoint. A goal_time_tolerance > 0 aborts the goal
  (GOAL_TOLERANCE_VIOLATED) once more than that has passed since the last waypoint without
  success; 0 waits as long as it takes.
* A goal ended by a tolerance, or canceled, leaves its joints holding where they are.

Times in s of sim time.
"""
import enum
import math
from dataclasses import dataclass
from typing import NamedTuple, Optional, Sequence

import numpy as np

from ..stamps import seconds_to_ns
from .commands import Reason, Targets, TrajectoryCommand

#: A tolerance of this value erases the default (control_msgs/JointTolerance).
ERASE = -1.0


class ErrorCode(enum.IntEnum):
    """FollowJointTrajectory's Result.error_code values."""
    SUCCESSFUL = 0
    INVALID_GOAL = -1
    INVALID_JOINTS = -2
    OLD_HEADER_TIMESTAMP = -3
    PATH_TOLERANCE_VIOLATED = -4
    GOAL_TOLERANCE_VIOLATED = -5


class GoalState(str, enum.Enum):
    """How a goal ended (the action's terminal states)."""
    SUCCEEDED = 'succeeded'
    ABORTED = 'aborted'
    CANCELED = 'canceled'


@dataclass(frozen=True)
class JointTolerance:
    """control_msgs/JointTolerance: a joint's tolerances (rad or m, rad/s or m/s, rad/s^2 or
    m/s^2); 0 = the default (none), -1 = erased."""
    name: str
    position: float = 0.0
    velocity: float = 0.0
    acceleration: float = 0.0


@dataclass(frozen=True)
class GoalRequest:
    """A FollowJointTrajectory goal: the trajectory, its tolerances, the time it may take
    beyond its last waypoint to meet the goal tolerance (s; 0 = no limit), and how many
    multi-DOF joints and component tolerances it carries (this simulator commands none)."""
    trajectory: TrajectoryCommand
    path_tolerance: Sequence[JointTolerance] = ()
    goal_tolerance: Sequence[JointTolerance] = ()
    goal_time_tolerance: float = 0.0
    multi_dof_joints: int = 0
    component_tolerances: int = 0


@dataclass(frozen=True)
class GoalOutcome:
    """How a goal ended: its state, error_code and error_string (the action's Result)."""
    state: GoalState
    error_code: ErrorCode
    message: str


@dataclass(frozen=True)
class GoalFeedback:
    """The action's feedback at sim time `time`: joint names (the commanded joints) and
    desired, actual and error (desired - actual) positions and velocities in their order;
    time_from_start: s since the trajectory's start."""
    time: float
    joint_names: Sequence[str]
    desired: Targets
    actual: Targets
    error: Targets
    time_from_start: float


class Tolerances(NamedTuple):
    """Checked tolerances per commanded joint (0 = not checked) and goal_time (s, 0 = none)."""
    path_position: np.ndarray
    path_velocity: np.ndarray
    goal_position: np.ndarray
    goal_velocity: np.ndarray
    goal_time: float


def _tolerance_value(value, what):
    value = float(value)
    if not math.isfinite(value) or (value < 0.0 and value != ERASE):
        raise ValueError(f'{what} is {value}: a tolerance is > 0, 0 (the default: none) or '
                         f'-1 (erased)')
    return max(value, 0.0)


def _joint_tolerances(entries, joint_names, kind):
    index = {name: i for i, name in enumerate(joint_names)}
    position, velocity = np.zeros(len(joint_names)), np.zeros(len(joint_names))
    for entry in entries:
        if entry.name not in index:
            raise ValueError(f'{kind} names joint {entry.name!r}, which is not commanded '
                             f'(commanded: {", ".join(joint_names)})')
        what = f'{kind} of {entry.name}'
        if _tolerance_value(entry.acceleration, f'{what}: acceleration') > 0.0:
            raise ValueError(f'{what}: acceleration tolerances cannot be checked (the servos '
                             'follow positions and velocities)')
        i = index[entry.name]
        position[i] = _tolerance_value(entry.position, f'{what}: position')
        velocity[i] = _tolerance_value(entry.velocity, f'{what}: velocity')
    return position, velocity


def goal_tolerances(request, joint_names):
    """The `Tolerances` of `request` (a GoalRequest) over `joint_names` (the commanded joints);
    raises ValueError saying what is wrong with them."""
    if request.multi_dof_joints:
        raise ValueError('the goal has a multi_dof_trajectory: this simulator commands '
                         'single-DOF joints only')
    if request.component_tolerances:
        raise ValueError('the goal has component tolerances, which apply to multi-DOF joints '
                         'only')
    path = _joint_tolerances(request.path_tolerance, joint_names, 'path_tolerance')
    goal = _joint_tolerances(request.goal_tolerance, joint_names, 'goal_tolerance')
    goal_time = _tolerance_value(request.goal_time_tolerance, 'goal_time_tolerance')
    return Tolerances(*path, *goal, goal_time)


def _violations(error, position, velocity, joint_names):
    """Joints whose error exceeds a checked tolerance, as text ('' if none)."""
    bad = ((position > 0.0) & (np.abs(error.positions) > position)) | \
        ((velocity > 0.0) & (np.abs(error.velocities) > velocity))
    return ', '.join(
        f'{joint_names[i]} (position error {error.positions[i]:.4g}, velocity error '
        f'{error.velocities[i]:.4g})' for i in np.flatnonzero(bad))


class FollowedGoal:
    """An accepted goal whose trajectory runs from sim time `start` to `end` (its last
    waypoint), checked against `tolerances` over `joint_names` (the commanded joints)."""

    def __init__(self, tolerances, start, end, joint_names):
        self.tolerances = tolerances
        self.start, self.end = float(start), float(end)
        self.joint_names = tuple(joint_names)

    def check(self, time, desired, actual):
        """Feedback at sim time `time` for `desired` and `actual` (`Targets` of the commanded
        joints), and the goal's `GoalOutcome` if it ends now (else None)."""
        error = Targets(desired.positions - actual.positions,
                        desired.velocities - actual.velocities)
        feedback = GoalFeedback(time, self.joint_names, desired, actual, error,
                                time - self.start)
        return feedback, self._outcome(time, error)

    def _outcome(self, time, error) -> Optional[GoalOutcome]:
        # times compared as ROS stamps them (whole nanoseconds), free of float rounding
        tol, now, end = self.tolerances, seconds_to_ns(time), seconds_to_ns(self.end)
        if now < end:
            bad = _violations(error, tol.path_position, tol.path_velocity, self.joint_names)
            if bad:
                return GoalOutcome(GoalState.ABORTED, ErrorCode.PATH_TOLERANCE_VIOLATED,
                                   f'path tolerance exceeded at {time:.4f} s: {bad}')
            return None
        bad = _violations(error, tol.goal_position, tol.goal_velocity, self.joint_names)
        if not bad:
            return GoalOutcome(GoalState.SUCCEEDED, ErrorCode.SUCCESSFUL,
                               f'goal reached at {time:.4f} s')
        if tol.goal_time > 0.0 and now - end > seconds_to_ns(tol.goal_time):
            return GoalOutcome(GoalState.ABORTED, ErrorCode.GOAL_TOLERANCE_VIOLATED,
                               f'goal tolerance not met {time - self.end:.4g} s after the '
                               f'last waypoint (goal_time_tolerance {tol.goal_time:g} s): '
                               f'{bad}')
        return None


def canceled():
    """The outcome of a goal canceled by its client."""
    return GoalOutcome(GoalState.CANCELED, ErrorCode.SUCCESSFUL, 'canceled')


def aborted(why):
    """The outcome of a goal that something else ended (`why`, text: a new goal or command
    preempting it, a reset), as joint_trajectory_controller aborts a preempted goal:
    INVALID_GOAL."""
    return GoalOutcome(GoalState.ABORTED, ErrorCode.INVALID_GOAL, why)


#: The error code of a goal refused for a `Reason` (INVALID_GOAL for the others).
_REASON_CODES = {Reason.UNKNOWN_JOINT: ErrorCode.INVALID_JOINTS,
                 Reason.DUPLICATE_JOINT: ErrorCode.INVALID_JOINTS,
                 Reason.ENDS_IN_PAST: ErrorCode.OLD_HEADER_TIMESTAMP}


def error_code(reason):
    """The `ErrorCode` of a goal whose trajectory was rejected for `reason` (a Reason)."""
    return _REASON_CODES.get(reason, ErrorCode.INVALID_GOAL)
