"""The rft_sim node's FollowJointTrajectory action server, driven by an rclpy ActionClient
as MoveIt or a gait stack drives joint_trajectory_controller's; the names of the node's
interface under another controller name and in a namespace.

Runs where ROS 2 Jazzy is sourced with control_msgs; skipped with the reason elsewhere.
Where ROS is sourced, pytest must be below 9 (requirements.txt): Jazzy's launch_testing
pytest plugin, which pytest then loads, does not load with pytest 9.
"""
import pytest

pytest.importorskip('rclpy', reason='ROS 2 Jazzy (rclpy) is not installed here')
pytest.importorskip('control_msgs.action',
                    reason='ROS 2 package control_msgs is not installed here')

from action_msgs.msg import GoalStatus  # noqa: E402
from builtin_interfaces.msg import Duration  # noqa: E402
from control_msgs.action import FollowJointTrajectory  # noqa: E402
from control_msgs.msg import JointTolerance  # noqa: E402
from rclpy.action import ActionClient, ActionServer  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint  # noqa: E402

import numpy as np  # noqa: E402
from rclpy.serialization import serialize_message  # noqa: E402

from rft_sim_ros.control import trajectory_goals as goals  # noqa: E402
from rft_sim_ros.control.commands import Targets  # noqa: E402
from rft_sim_ros.ros import follow_messages, topics  # noqa: E402
from rft_sim_ros.ros.factory import RclpyFactory, RosbagsFactory  # noqa: E402
from rft_sim_ros.ros.node import SimNode  # noqa: E402
from ros_test_support import SERVO_RIG, control_msgs_typestore, messages_equal  # noqa: E402
from test_node_rclpy import hip, start_sim  # noqa: E402

pytestmark = pytest.mark.ros

Result = FollowJointTrajectory.Result
#: Messages a subscription of the test keeps until the executor hands them over: all that a
#: test publishes (on a busy machine the test's side lags the simulator, in the same executor,
#: by hundreds of messages, and a shallower queue dropped the one a test waited for).
KEEP_EVERY = 10_000


def goal(positions, after_s, names=('hip',), **fields):
    point = JointTrajectoryPoint(positions=positions,
                                 time_from_start=Duration(sec=int(after_s),
                                                          nanosec=int(after_s % 1 * 1e9)))
    return FollowJointTrajectory.Goal(
        trajectory=JointTrajectory(joint_names=list(names), points=[point]), **fields)


class Client:
    """An ActionClient on the test's probe node that records feedback."""

    def __init__(self, ros, action=topics.FOLLOW_JOINT_TRAJECTORY):
        self.ros = ros
        self.action = ActionClient(ros.probe, FollowJointTrajectory, action,
                                   feedback_sub_qos_profile=QoSProfile(depth=KEEP_EVERY))
        self.feedback = []
        assert self.action.wait_for_server(timeout_sec=5.0)

    def send(self, goal_msg):
        future = self.action.send_goal_async(goal_msg,
                                             feedback_callback=self.feedback.append)
        assert self.ros.spin_until(future.done)
        return future.result()

    def result(self, handle, timeout=10.0):
        future = handle.get_result_async()
        assert self.ros.spin_until(future.done, timeout=timeout)
        return future.result()


def _seconds(time):
    return time.sec + time.nanosec * 1e-9


def test_a_goal_runs_sends_feedback_and_succeeds(ros):
    """What the action guarantees: the result, and feedback at the goal time (the
    trajectory's end) within the goal tolerance, the one the server found the goal reached
    on. Feedback and result travel apart (a topic, a service), and rclpy's ActionClient drops
    the feedback of a goal once it has its result: on a busy machine the last feedback comes
    after the result. So the test waits for that feedback first, then asks for the result."""
    sim = start_sim(ros)
    joint_states = []  # (all of them: the one of the feedback's cycle is looked for later)
    ros.probe.create_subscription(JointState, topics.JOINT_STATES, joint_states.append,
                                  KEEP_EVERY)
    client = Client(ros)
    handle = client.send(goal([0.3], 0.2, goal_tolerance=[
        JointTolerance(name='hip', position=0.01)]))
    assert handle.accepted

    def reached():
        """The feedback at or after the goal time within the tolerance, if received."""
        return [f.feedback for f in client.feedback
                if _seconds(f.feedback.desired.time_from_start) >= 0.2 - 1e-9
                and abs(f.feedback.error.positions[0]) <= 0.01]
    assert ros.spin_until(reached), [  # (the last feedback: time, error)
        (_seconds(f.feedback.desired.time_from_start), f.feedback.error.positions[0])
        for f in client.feedback[-3:]]
    answer = client.result(handle)  # (asked for now: rclpy drops feedback that comes after it)
    assert answer.status == GoalStatus.STATUS_SUCCEEDED
    assert answer.result.error_code == Result.SUCCESSFUL
    final = reached()[0]
    assert list(final.joint_names) == ['hip', 'knee']
    assert abs(final.desired.positions[0] - 0.3) < 1e-9
    assert final.error.positions[0] == pytest.approx(
        final.desired.positions[0] - final.actual.positions[0], abs=1e-12)

    def joint_states_then():  # the /joint_states of the cycle that feedback is of
        return [m for m in joint_states if m.header.stamp == final.header.stamp]
    assert ros.spin_until(joint_states_then, timeout=5.0)
    assert final.actual.positions[0] == pytest.approx(hip(joint_states_then()[0]), abs=1e-12)
    assert any(_seconds(f.feedback.header.stamp) < _seconds(final.header.stamp)
               for f in client.feedback)  # and feedback came along the way
    assert abs(sim.runtime.sim.commands.sample(sim.runtime.sim.time).positions[0] - 0.3) < 1e-9


def test_a_bad_goal_is_rejected_with_the_reason_counted(ros):
    sim = start_sim(ros)
    client = Client(ros)
    assert not client.send(goal([0.3], 0.2, names=('ankle',))).accepted
    assert not client.send(goal([0.3], 0.2, path_tolerance=[
        JointTolerance(name='hip', position=-2.0)])).accepted
    assert sim.runtime.rejections == {'unknown_joint': 1, 'goal': 1}


def test_cancel_holds_the_joints_and_a_new_goal_preempts(ros):
    sim = start_sim(ros)
    client = Client(ros)
    first = client.send(goal([0.8], 3.0))
    assert ros.spin_until(lambda: len(client.feedback) >= 5)
    second = client.send(goal([-0.8], 3.0))
    answer = client.result(first)
    assert answer.status == GoalStatus.STATUS_ABORTED
    assert answer.result.error_code == Result.INVALID_GOAL
    assert 'preempted' in answer.result.error_string
    assert ros.spin_until(lambda: hip(ros.probe.joint_states[-1]) < 0.0)
    cancel = second.cancel_goal_async()
    assert ros.spin_until(cancel.done)
    answer = client.result(second)
    assert answer.status == GoalStatus.STATUS_CANCELED
    held = sim.runtime.sim.commands.sample(sim.runtime.sim.time).positions[0]
    assert -0.8 < held < 0.0
    since = sim.runtime.sim.time
    assert ros.spin_until(lambda: sim.runtime.sim.time >= since + 0.6)  # held 0.6 s of sim time
    assert ros.catch_up(sim)
    assert abs(hip(ros.probe.joint_states[-1]) - held) < 0.01


def test_a_path_tolerance_violation_aborts_the_goal(ros):
    start_sim(ros)
    client = Client(ros)
    handle = client.send(goal([0.6], 0.3, path_tolerance=[
        JointTolerance(name='hip', position=0.02)]))
    answer = client.result(handle)
    assert answer.status == GoalStatus.STATUS_ABORTED
    assert answer.result.error_code == Result.PATH_TOLERANCE_VIOLATED
    assert 'hip' in answer.result.error_string


def test_the_trajectory_controller_parameter_renames_topic_and_action(ros):
    """ROS 2 Jazzy cannot remap an action's name: the parameter serves a stack whose
    controller has another name, its topic and its action."""
    start_sim(ros, trajectory_controller='left/leg_controller')
    client = Client(ros, '/left/leg_controller/follow_joint_trajectory')
    answer = client.result(client.send(goal([0.25], 0.2)))
    assert answer.status == GoalStatus.STATUS_SUCCEEDED
    publisher = ros.probe.create_publisher(JointTrajectory,
                                           '/left/leg_controller/joint_trajectory', 10)
    assert ros.spin_until(lambda: publisher.get_subscription_count() > 0)
    publisher.publish(goal([-0.25], 0.1).trajectory)
    assert ros.spin_until(lambda: abs(hip(ros.probe.joint_states[-1]) + 0.25) < 0.01)


def test_feedback_and_result_serialise_as_control_msgs_defines_them():
    """The node's rclpy messages and the rosbags ones built from the control_msgs
    definitions the ROS-free tests use are the same bytes on the wire."""
    store = control_msgs_typestore()
    reference = RosbagsFactory(store)
    pair = Targets(np.array([0.1, -0.2]), np.array([0.5, 0.25]))
    feedback = goals.GoalFeedback(time=3.25, joint_names=('hip', 'knee'), desired=pair,
                                  actual=pair, error=pair, time_from_start=1.5)
    outcome = goals.GoalOutcome(goals.GoalState.ABORTED, goals.ErrorCode.PATH_TOLERANCE_VIOLATED,
                                'path tolerance exceeded')
    for build in (lambda f: follow_messages.feedback_message(f, feedback),
                  lambda f: follow_messages.result_message(f, outcome)):
        expected = build(reference)
        decoded = store.deserialize_cdr(serialize_message(build(RclpyFactory())),
                                        expected.__msgtype__)
        assert messages_equal(decoded, expected)


def test_a_namespace_applies_to_the_robot_topics_not_to_clock_tf_and_diagnostics(ros):
    """`--ros-args -r __ns:=/go2`: the robot's topics, commands, action and services are
    /go2/..., as a namespaced ros2_control robot's; /clock, /tf and /diagnostics stay global."""
    sim = ros.add(SimNode(context=ros.context, namespace='go2', parameter_overrides=[
        Parameter('scene', value=SERVO_RIG), Parameter('real_time_factor', value=2.0)]))
    assert ros.spin_until(lambda: ros.probe.clocks)
    published = {name for name, _ in sim.get_publisher_names_and_types_by_node('rft_sim',
                                                                                '/go2')}
    assert {'/clock', '/tf', '/diagnostics', '/go2/joint_states', '/go2/odom',
            '/go2/rft/leg/wrench'} <= published
    assert not {'/joint_states', '/odom'} & published
    subscribed = {name for name, _ in sim.get_subscriber_names_and_types_by_node('rft_sim',
                                                                                 '/go2')}
    assert {'/go2/joint_trajectory_controller/joint_trajectory',
            '/go2/forward_position_controller/commands',
            '/go2/effort_controller/commands'} <= subscribed
    services = {name for name, _ in sim.get_service_names_and_types_by_node('rft_sim', '/go2')}
    assert '/go2/rft_sim/reset' in services
    client = Client(ros, '/go2/joint_trajectory_controller/follow_joint_trajectory')
    handle = client.send(goal([0.1], 0.3, names=('ankle',)))
    assert not handle.accepted
    assert sim.runtime.rejections == {'unknown_joint': 1}


def test_without_control_msgs_the_node_runs_without_the_action(ros, monkeypatch):
    """A ROS install that lacks control_msgs: the node starts, says so, and serves the rest."""
    real = RclpyFactory.message_class

    def without_control_msgs(self, type_name):
        if type_name.startswith('control_msgs/'):
            raise ModuleNotFoundError("No module named 'control_msgs'")
        return real(self, type_name)

    def trajectory_servers(node):  # (simulation_interfaces' simulate_steps is another)
        return [w for w in node.waitables if isinstance(w, ActionServer)
                and w.action_type.__name__ == 'FollowJointTrajectory']

    monkeypatch.setattr(RclpyFactory, 'message_class', without_control_msgs)
    sim = start_sim(ros)
    assert not trajectory_servers(sim)
    assert ros.spin_until(lambda: len(ros.probe.joint_states) >= 3)
    monkeypatch.undo()
    served = start_sim(ros, trajectory_controller='other')      # (the check can fail)
    assert trajectory_servers(served)
