"""sensor_msgs/JointState commands, as ros2_control's topic hardware interfaces write them.

ROS-free. The topic hardware interfaces (`joint_state_topic_hardware_interface/
JointStateTopicSystem` of ros-controls/topic_based_hardware_interfaces and its predecessor
`topic_based_ros2_control/TopicBasedSystem` of PickNikRobotics/topic_based_ros2_control)
publish a robot's commands as one JointState a controller cycle: `name` lists every joint of
the `<ros2_control>` block, and each of `position`, `velocity`, `effort` holds one value
for every joint that *declares* that command interface, in `name` order, and none for the
others. A robot whose joints all declare the same interfaces gets arrays as long as `name`
(or empty); one with mixed interfaces gets shorter, packed arrays: joints A (position), B
(effort), C (position and effort) give position = [A, C], effort = [B, C]. An interface no
controller has claimed holds NaN.

`read_joint_state_command` reads such a message as it is meant:

* an empty array: no joint commands that interface;
* an array as long as `name`: entry i belongs to joint name[i];
* a shorter one: packed, entry k to the k-th joint of `name` that declares the interface
  (`declared`: {joint: interfaces} of the robot's `<ros2_control>` block,
  `rft_sim_ros.robot.control_block`); without declarations, or when their count differs
  from the array's length, the message cannot be read;
* NaN entries leave that interface of that joint as it was (+-inf is refused).

The message is rejected whole (`CommandRejected`, its result naming the `Reason`) when a
name is unknown, empty or repeated, a field is not a list of numbers, a value is infinite,
or an array's length fits no reading above. Units: rad or m, rad/s or m/s, N m or N (the joint's own).
"""
from dataclasses import dataclass
from typing import Mapping, Optional

import numpy as np

from rft_sim_ros.control.commands import (CommandRejected, CommandResult, Reason, _float_vector,
                                          _Rejected, check_joint_names)

#: The JointState fields, as ros2_control names the command interfaces they carry.
INTERFACES = ('position', 'velocity', 'effort')


@dataclass(frozen=True)
class JointStateCommand:
    """A read JointState command over `joints` (indices into the handler's joint names):
    per interface, one value per joint of `joints`, NaN where it leaves the interface as it
    was (positions rad or m, velocities rad/s or m/s, efforts N m or N); per joint, whether
    it declares a position and a velocity command interface (all do without declarations)."""
    joints: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    efforts: np.ndarray
    position_declared: Optional[np.ndarray] = None
    velocity_declared: Optional[np.ndarray] = None


def _field(msg, interface):
    try:
        raw = getattr(msg, interface)
    except AttributeError:
        raise _Rejected(Reason.MALFORMED, f'not a joint state: no {interface} field') from None
    if raw is None:
        return np.zeros(0)
    return _float_vector(raw, interface)


def _spread(values, interface, names, declared):
    """One value per joint of `names` (NaN where none) from the JointState array `values`
    read as the module docstring says; raises _Rejected."""
    count = len(names)
    if values.size in (0, count):
        return values if values.size else np.full(count, np.nan)
    owners = None
    if declared is not None:
        owners = [i for i, name in enumerate(names) if interface in declared.get(name, ())]
    if owners is None or len(owners) != values.size:
        which = ('' if declared is None else
                 f'; {len(owners)} of them declare a {interface} command interface')
        raise _Rejected(Reason.ARRAY_LENGTH,
                        f'{interface} has {values.size} values for {count} joint names{which}: '
                        f'an array as long as name, one per joint of name declaring the '
                        f"interface in the robot's <ros2_control> block, or empty")
    spread = np.full(count, np.nan)
    spread[owners] = values
    return spread


def read_joint_state_command(msg, joint_index: Mapping[str, int],
                             declared: Optional[Mapping[str, tuple]] = None, passive=()):
    """`JointStateCommand` of the sensor_msgs/JointState `msg` (any backend: rclpy, rosbags
    or anything with name, position, velocity, effort); joint_index: {joint name: index}
    of the joints commands may address; declared: {joint: command interfaces} of the
    robot's `<ros2_control>` block, or None; passive: the robot's joints without command
    interfaces (a rejection says so). Raises `CommandRejected` (module docstring)."""
    try:
        return _read(msg, joint_index, declared, passive)
    except _Rejected as rejected:
        raise CommandRejected(CommandResult(rejected.reason, str(rejected))) from None


def _read(msg, joint_index, declared, passive=()):
    try:
        names = list(msg.name)
    except (AttributeError, TypeError) as error:
        raise _Rejected(Reason.MALFORMED, f'not a joint state ({error})') from None
    check_joint_names(names, joint_index, 'joint state command names no joint', passive)
    values = [_spread(_field(msg, interface), interface, names, declared)
              for interface in INTERFACES]
    for interface, spread in zip(INTERFACES, values):
        infinite = np.isinf(spread)
        if infinite.any():
            bad = [names[i] for i in np.flatnonzero(infinite)]
            raise _Rejected(Reason.NOT_FINITE, f'{interface} is infinite for joint(s) '
                                               f'{", ".join(bad)} (NaN leaves it as it was)')
    declares = [declared.get(n, INTERFACES) if declared else INTERFACES for n in names]
    return JointStateCommand(np.array([joint_index[n] for n in names], dtype=int), *values,
                             np.array(['position' in d for d in declares], dtype=bool),
                             np.array(['velocity' in d for d in declares], dtype=bool))
