"""ros2_control's topic hardware contract in the node's ROS-free core (SimRuntime): JointState
commands on /robot_joint_commands drive the joints (hybrid mode), bad ones are rejected whole
with a throttled warning naming the topic, the gains are a dynamic parameter; and the
`<ros2_control>` block's command interfaces are read from the robot description."""
import math

import numpy as np
import pytest

from rft_sim_ros import resources
from rft_sim_ros.ros import parameters, topics
from rft_sim_ros.robot import load_description
from rft_sim_ros.scenes.config import load_scene
from ros_test_support import SERVO_RIG, Harness
from test_joint_state_commands import joint_state


@pytest.fixture(scope='module')
def rig_scene():
    return load_scene(SERVO_RIG)


def test_joint_state_commands_move_the_named_joints_and_leave_the_others(rig_scene):
    h = Harness(rig_scene)
    h.run(0.05)
    hip = h.sim.data.joint('hip').qpos[0]
    result = h.runtime.on_joint_commands(joint_state(['knee'], position=[0.3],
                                                     effort=[math.nan]))
    assert result.accepted and h.sim.commands.hybrid is not None
    h.run(0.5)
    assert h.sim.data.joint('knee').qpos[0] == pytest.approx(0.3, abs=0.02)
    assert h.sim.data.joint('hip').qpos[0] == pytest.approx(hip, abs=0.02)
    assert h.warnings == []


def test_bad_joint_state_commands_are_rejected_whole_and_counted(rig_scene):
    h = Harness(rig_scene)
    h.runtime.tick()
    for _ in range(5):
        result = h.runtime.on_joint_commands(joint_state(['knee', 'ankle'], position=[0.3, 0.1]))
        assert result.reason.value == 'unknown_joint'
    assert h.sim.commands.hybrid is None
    assert len(h.warnings) == 1 and topics.ROBOT_JOINT_COMMANDS in h.warnings[0]
    assert 'ankle' in h.warnings[0]
    assert h.runtime.rejections == {'unknown_joint': 5}


def test_the_gains_are_a_checked_dynamic_parameter(rig_scene):
    h = Harness(rig_scene)
    runtime = h.runtime
    assert parameters.SPECS[parameters.JOINT_GAINS].dynamic
    problem = runtime.parameter_problem(parameters.JOINT_GAINS, ['kn*: {kp: -2}'])
    assert problem.startswith('joint_gains: kn*.kp: must be a finite number >= 0')
    assert runtime.parameter_problem(parameters.JOINT_GAINS, ['knee: {kp: 2, kd: 0.1}']) is None
    default = h.sim.hybrid_drive.kp.copy()
    runtime.set_parameter(parameters.JOINT_GAINS, ['knee: {kp: 2, kd: 0.1}'])
    knee = h.sim.servo_joint_names.index('knee')
    assert h.sim.hybrid_drive.kp[knee] == 2.0 and h.sim.hybrid_drive.kd[knee] == 0.1
    runtime.set_parameter(parameters.JOINT_GAINS, [])
    np.testing.assert_array_equal(h.sim.hybrid_drive.kp, default)


def test_topic_names_are_checked():
    assert parameters.topic_name('/robot_joint_commands', 'x') == '/robot_joint_commands'
    with pytest.raises(ValueError, match='joint_states_topic'):
        parameters.topic_name('robot joint', parameters.JOINT_STATES_TOPIC)


def test_the_quadruped_declares_position_and_effort_commands():
    description = load_description(resources.models_dir() / 'quadruped' /
                                   'quadruped.urdf.xacro', log=lambda notice: None)
    assert len(description.command_interfaces) == 12
    assert set(description.command_interfaces.values()) == {('position', 'effort')}
