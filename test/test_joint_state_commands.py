"""sensor_msgs/JointState commands as ros2_control's topic hardware interfaces write them
(rft_sim_ros.control.joint_state_commands), read from rosbags' Jazzy JointState messages,
and the hybrid targets they set (rft_sim_ros.control.hybrid)."""
import math

import numpy as np
import pytest

from rft_sim_ros.control.commands import CommandHandler, CommandRejected, Reason
from rft_sim_ros.control.hybrid import HybridTargets, gain_patterns, resolve_gains
from rft_sim_ros.control.joint_state_commands import read_joint_state_command
from rft_sim_ros.ros.factory import RosbagsFactory, jazzy_typestore

NAN = math.nan
JOINTS = ('a', 'b', 'c')
INDEX = {name: i for i, name in enumerate(JOINTS)}


def joint_state(names, position=(), velocity=(), effort=()):
    factory = RosbagsFactory(jazzy_typestore())
    stamp = factory.make('builtin_interfaces/msg/Time', sec=0, nanosec=0)
    return factory.make('sensor_msgs/msg/JointState',
                        header=factory.make('std_msgs/msg/Header', stamp=stamp, frame_id=''),
                        name=list(names), position=factory.float64_sequence(position),
                        velocity=factory.float64_sequence(velocity),
                        effort=factory.float64_sequence(effort))


def rejected(msg, declared=None):
    with pytest.raises(CommandRejected) as caught:
        read_joint_state_command(msg, INDEX, declared)
    return caught.value.result


def test_full_arrays_give_each_joint_its_values_in_name_order():
    command = read_joint_state_command(
        joint_state(['c', 'a'], position=[0.3, 0.1], velocity=[3.0, 1.0]), INDEX)
    assert command.joints.tolist() == [2, 0]
    assert command.positions.tolist() == [0.3, 0.1]
    assert command.velocities.tolist() == [3.0, 1.0]
    assert np.isnan(command.efforts).all()  # empty: no joint commands effort


def test_packed_arrays_of_mixed_interfaces_go_to_the_joints_that_declare_them():
    # as the plugins write them: a position only, b effort only, c position and effort
    declared = {'a': ('position',), 'b': ('effort',), 'c': ('position', 'effort')}
    command = read_joint_state_command(
        joint_state(['a', 'b', 'c'], position=[0.1, 0.3], effort=[2.0, 3.0]), INDEX, declared)
    assert command.positions.tolist()[0] == 0.1 and command.positions.tolist()[2] == 0.3
    assert np.isnan(command.positions[1])
    assert np.isnan(command.efforts[0]) and command.efforts[1:].tolist() == [2.0, 3.0]


def test_packed_arrays_without_declarations_are_refused_whole():
    result = rejected(joint_state(['a', 'b', 'c'], position=[0.1, 0.3]))
    assert result.reason is Reason.ARRAY_LENGTH
    assert 'position has 2 values for 3 joint names' in result.message
    declared = {'a': ('position',), 'b': ('position',), 'c': ('position',)}
    result = rejected(joint_state(['a', 'b', 'c'], position=[0.1, 0.3]), declared)
    assert '3 of them declare a position command interface' in result.message


@pytest.mark.parametrize('msg, reason', [
    (joint_state([]), Reason.EMPTY),
    (joint_state(['a', 'a'], position=[0.0, 0.0]), Reason.DUPLICATE_JOINT),
    (joint_state(['a', 'x'], position=[0.0, 0.0]), Reason.UNKNOWN_JOINT),
    (joint_state(['a'], position=[math.inf]), Reason.NOT_FINITE),
    (joint_state(['a'], effort=[1.0, 2.0]), Reason.ARRAY_LENGTH),
])
def test_unreadable_messages_are_rejected_with_a_reason(msg, reason):
    assert rejected(msg).reason is reason


def test_a_field_that_is_not_numbers_is_malformed():
    class Odd:
        name, position, velocity, effort = ['a'], ['x'], [], []
    assert rejected(Odd()).reason is Reason.MALFORMED
    assert rejected(object()).reason is Reason.MALFORMED


def test_nan_leaves_an_interface_as_it_was():
    targets = HybridTargets([0.1, 0.2, 0.3])
    targets.update(read_joint_state_command(
        joint_state(['a', 'b', 'c'], position=[1.0, NAN, 3.0], effort=[NAN, 5.0, NAN]), INDEX))
    targets.update(read_joint_state_command(
        joint_state(['b'], velocity=[7.0]), INDEX))
    assert targets.positions.tolist() == [1.0, 0.2, 3.0]
    assert targets.velocities.tolist() == [0.0, 7.0, 0.0]
    assert targets.efforts.tolist() == [0.0, 5.0, 0.0]


def test_a_joint_declaring_velocity_and_no_position_has_its_target_move_at_that_velocity():
    """(A wheel whose <ros2_control> declares a velocity command interface only: kp would
    otherwise hold it where hybrid commands began.) A joint declaring a position interface is
    held where its position was, NaN or not; one declaring an effort interface alone is not
    tracked (no kp, kd)."""
    declared = {'a': ('position', 'velocity'), 'b': ('velocity',), 'c': ('effort',)}
    handler = CommandHandler(JOINTS, [0.1, 0.2, 0.3])

    def command(**fields):
        return read_joint_state_command(joint_state(['a', 'b', 'c'], **fields), INDEX,
                                        declared)
    handler.set_joint_states(command(position=[0.5, NAN, NAN], velocity=[1.0, 4.0, NAN],
                                     effort=[NAN, NAN, 2.0]), now=1.0)
    targets = handler.hybrid
    assert targets.tracked.tolist() == [True, True, False]
    assert targets.advance(1.5).positions.tolist() == [0.5, 0.2 + 2.0, 0.3]
    handler.set_joint_states(command(position=[NAN, NAN, NAN], velocity=[NAN, -2.0, NAN],
                                     effort=[NAN, NAN, NAN]), now=2.0)  # (-2 rad/s from 2 s)
    assert targets.advance(2.5).positions == pytest.approx([0.5, 0.2 + 4.0 - 1.0, 0.3])


def test_hybrid_mode_starts_from_the_targets_and_ends_with_a_position_command():
    handler = CommandHandler(JOINTS, [0.1, 0.2, 0.3])
    assert handler.hybrid is None
    handler.set_joint_states(read_joint_state_command(joint_state(['b'], effort=[4.0]), INDEX),
                             now=1.0)
    assert handler.hybrid.positions.tolist() == [0.1, 0.2, 0.3]
    assert handler.hybrid.efforts.tolist() == [0.0, 4.0, 0.0]
    handler.track([0.5, 0.6, 0.7], now=1.5)  # a trajectory then starts where the joints are
    assert handler.sample(1.5).positions.tolist() == [0.5, 0.6, 0.7]
    assert handler.set_efforts([1.0, 1.0, 1.0], now=2.0).accepted
    assert handler.hybrid is None and handler.efforts is not None
    handler.set_joint_states(read_joint_state_command(joint_state(['a'], position=[0.0]),
                                                      INDEX), now=2.5)
    assert handler.efforts is None
    assert handler.set_positions([0.0, 0.0, 0.0], now=3.0).accepted
    assert handler.hybrid is None and handler.efforts is None


def test_gain_patterns_from_parameter_strings_later_ones_win():
    patterns = gain_patterns(['*: {kp: 20, kd: 0.5}', '*_knee: {kp: 40}'])
    kp, kd = resolve_gains(patterns, ('fl_hip', 'fl_knee', 'x'), [1.0, 2.0, 3.0],
                           [0.1, 0.2, 0.3])
    assert kp.tolist() == [20.0, 40.0, 20.0] and kd.tolist() == [0.5, 0.5, 0.5]
    assert gain_patterns({'x': {'kd': 0}}) == {'x': {'kd': 0.0}}
    assert gain_patterns(['']) == {} == gain_patterns([])  # (the defaults: the CLI's way)
    for bad in (['kp: 3'], ['a: {kp: -1}'], ['a: {ki: 1}'], 'a', ['a: {kp: .nan}']):
        with pytest.raises(ValueError):
            gain_patterns(bad)
