"""The rft_sim node as ros2_control's topic hardware interface meets it, in-process over
rclpy: JointState commands on /robot_joint_commands (QoS of the plugins: reliable, depth 1)
move the joints and bad ones are counted; /robot_joint_states (read with the plugins'
SensorDataQoS) carries position, velocity and effort of every joint; /imu/data and
/rft/foot_contacts are published; the joint_gains parameter is checked.

Runs where ROS 2 Jazzy is sourced; skipped with the reason everywhere else.
"""
import math

import pytest

rclpy = pytest.importorskip('rclpy', reason='ROS 2 Jazzy (rclpy) is not installed here')
pytest.importorskip('sensor_msgs.msg', reason='ROS 2 package sensor_msgs is not installed here')

from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile, qos_profile_sensor_data  # noqa: E402
from rcl_interfaces.srv import SetParameters  # noqa: E402
from sensor_msgs.msg import Imu, JointState  # noqa: E402

from rft_sim_ros.ros import topics  # noqa: E402
from test_node_rclpy import start_sim  # noqa: E402

pytestmark = pytest.mark.ros


def test_joint_state_commands_drive_and_the_state_goes_back_on_the_hardware_topic(ros):
    sim = start_sim(ros)
    probe = ros.probe
    states, imu, contacts = [], [], []
    probe.create_subscription(JointState, topics.ROBOT_JOINT_STATES, states.append,
                              qos_profile_sensor_data)
    probe.create_subscription(Imu, topics.IMU, imu.append, 10)
    probe.create_subscription(JointState, topics.FOOT_CONTACTS, contacts.append, 10)
    commands = probe.create_publisher(JointState, topics.ROBOT_JOINT_COMMANDS, QoSProfile(depth=1))
    assert ros.spin_until(lambda: states and imu and contacts)
    last = states[-1]
    assert len(last.position) == len(last.velocity) == len(last.effort) == len(last.name)
    assert list(contacts[-1].name) == ['leg']
    commands.publish(JointState(name=['hip'], position=[0.3], effort=[math.nan]))
    assert ros.spin_until(lambda: abs(states[-1].position[list(states[-1].name).index('hip')]
                                      - 0.3) < 0.02)
    commands.publish(JointState(name=['hip', 'ankle'], position=[0.0, 0.0]))
    assert ros.spin_until(lambda: sim.runtime.rejections.get('unknown_joint') == 1)
    client = probe.create_client(SetParameters, '/rft_sim/set_parameters')
    bad = Parameter('joint_gains', value=['hip: {kp: -1}']).to_parameter_msg()
    answer = ros.call(client, SetParameters.Request(parameters=[bad])).results[0]
    assert not answer.successful and 'kp' in answer.reason
    good = Parameter('joint_gains', value=['hip: {kp: 5, kd: 0.2}']).to_parameter_msg()
    assert ros.call(client, SetParameters.Request(parameters=[good])).results[0].successful
    assert sim.runtime.sim.hybrid_drive.kp[sim.runtime.sim.servo_joint_names.index('hip')] == 5
