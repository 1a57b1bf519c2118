"""The rclpy nodes in-process (one executor, the test's probe node beside them).

Runs where ROS 2 Jazzy is sourced (rclpy and the message packages of package.xml); skipped
with the reason everywhere else. Uses the servo_rig test scene (two position servos). Where
ROS is sourced, pytest must be below 9 (requirements.txt): Jazzy's launch_testing pytest
plugin, which pytest then loads, does not load with pytest 9.
"""
import math
import os
import select
import signal
import subprocess
import sys
import threading
import time

import pytest

rclpy = pytest.importorskip('rclpy', reason='ROS 2 Jazzy (rclpy) is not installed here')
for _package in ('std_srvs.srv', 'trajectory_msgs.msg', 'sensor_msgs.msg', 'nav_msgs.msg',
                 'tf2_msgs.msg', 'diagnostic_msgs.msg', 'rosgraph_msgs.msg',
                 'visualization_msgs.msg'):
    pytest.importorskip(_package, reason=f'ROS 2 package {_package} is not installed here')

from builtin_interfaces.msg import Duration, Time  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from rcl_interfaces.msg import ParameterType  # noqa: E402
from rcl_interfaces.srv import (DescribeParameters, GetParameters, ListParameters,  # noqa: E402
                                SetParameters)
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile  # noqa: E402
from std_msgs.msg import Float64MultiArray, String  # noqa: E402
from std_srvs.srv import SetBool, Trigger  # noqa: E402
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint  # noqa: E402

from rft_sim_ros.ros import topics  # noqa: E402
from rft_sim_ros.ros.gait_node import TripodGaitNode  # noqa: E402
from rft_sim_ros.ros.gait_node import main as gait_main  # noqa: E402
from rft_sim_ros.ros.node import SimNode  # noqa: E402
from rft_sim_ros.ros.node import main as sim_main  # noqa: E402
from rft_sim_ros.ros.startup import StartFailed  # noqa: E402
from rft_sim_ros.ros.trot_gait_node import TrotGaitNode  # noqa: E402
from rft_sim_ros.robot.packages import PackageResolver  # noqa: E402
from rft_sim_ros.robot.xacro_files import expand_xacro  # noqa: E402
from rft_sim_ros.scenes.quadruped import JOINT_NAMES as QUADRUPED_JOINTS  # noqa: E402
from rft_sim_ros.scenes.hexapod import JOINT_NAMES as HEXAPOD_JOINTS  # noqa: E402
from rft_sim_ros.scenes.config import SceneError  # noqa: E402
from ros_test_support import SERVO_RIG  # noqa: E402

pytestmark = pytest.mark.ros

PERIOD = 0.01  # s of sim time between /clock messages (servo_rig publishes at 100 Hz)
#: Wall s a simulator may take to build its simulation (minutes where its kernels compile).
BUILD_TIMEOUT_S = 600.0

#: A DDS domain of this test process, so no other ROS graph on the machine (another
#: simulator's /clock, say) mixes with the nodes under test.
DOMAIN_ID = 1 + os.getpid() % 100


def seconds(stamp):
    return stamp.sec + stamp.nanosec * 1e-9


class Probe(Node):
    """Test-side node: records what rft_sim publishes, sends commands, calls services."""

    def __init__(self, context):
        super().__init__('probe', context=context)
        self.clocks, self.joint_states, self.diagnostics, self.trajectories = [], [], [], []
        self.create_subscription(Clock, topics.CLOCK, lambda m: self.clocks.append(m), 100)
        self.create_subscription(JointState, topics.JOINT_STATES,
                                 lambda m: self.joint_states.append(m), 100)
        self.create_subscription(DiagnosticArray, topics.DIAGNOSTICS,
                                 lambda m: self.diagnostics.append(m), 100)
        self.create_subscription(JointTrajectory, topics.JOINT_TRAJECTORY,
                                 lambda m: self.trajectories.append(m), 100)
        self.trajectory = self.create_publisher(JointTrajectory, topics.JOINT_TRAJECTORY, 10)
        self.positions = self.create_publisher(Float64MultiArray, topics.POSITION_COMMANDS, 10)
        self.efforts = self.create_publisher(Float64MultiArray, topics.EFFORT_COMMANDS, 10)
        self.clock = self.create_publisher(Clock, topics.CLOCK, 10)
        self.pause = self.create_client(SetBool, '/rft_sim/pause')
        self.step = self.create_client(Trigger, '/rft_sim/step')
        self.reset = self.create_client(Trigger, '/rft_sim/reset')
        self.set_parameters = self.create_client(SetParameters, '/rft_sim/set_parameters')

    def clock_times(self):
        return [seconds(m.clock) for m in self.clocks]


class Ros:
    """An rclpy context with an executor spinning the nodes under test and the probe."""

    def __init__(self):
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=DOMAIN_ID)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.probe = Probe(self.context)
        self.executor.add_node(self.probe)
        self.nodes = [self.probe]

    def add(self, node, built=True):
        """Spin `node` from now on; a simulator is returned once its simulation is built
        (a StartFailed of its start-up propagates), or at once with built=False."""
        self.executor.add_node(node)
        self.nodes.append(node)
        if built and getattr(node, 'starting', False):
            assert self.spin_until(lambda: not node.starting, timeout=BUILD_TIMEOUT_S)
        return node

    def spin_until(self, predicate, timeout=10.0):
        deadline = time.monotonic() + timeout
        while not predicate() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.01)
        return predicate()

    def spin_for(self, seconds_):
        deadline = time.monotonic() + seconds_
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.01)

    def catch_up(self, sim, timeout=10.0):
        """Spin until the probe has the /clock and /joint_states of `sim`'s sim time now: on a
        busy machine the probe lags behind the simulator by up to its queues, and what was
        published before a moment keeps arriving after it."""
        now = sim.runtime.sim.time - 1e-6
        return self.spin_until(lambda: self.probe.clocks and self.probe.joint_states
                               and self.probe.clock_times()[-1] >= now
                               and seconds(self.probe.joint_states[-1].header.stamp) >= now,
                               timeout)

    def call(self, client, request):
        assert client.wait_for_service(timeout_sec=5.0), client.srv_name
        future = client.call_async(request)
        assert self.spin_until(future.done), f'no answer from {client.srv_name}'
        return future.result()

    def close(self):
        self.executor.shutdown()
        for node in self.nodes:
            node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def start_sim(ros, **parameters):
    overrides = {'scene': SERVO_RIG, 'real_time_factor': 2.0, **parameters}
    return ros.add(SimNode(context=ros.context, parameter_overrides=[
        Parameter(name, value=value) for name, value in overrides.items()]))


def hip(message):
    return message.position[list(message.name).index('hip')]


def trajectory(names, positions, after_s):
    point = JointTrajectoryPoint(positions=positions,
                                 time_from_start=Duration(sec=0, nanosec=int(after_s * 1e9)))
    return JointTrajectory(joint_names=names, points=[point])


def test_clock_advances_and_joint_states_arrive(ros):
    start_sim(ros)
    assert ros.spin_until(lambda: len(ros.probe.clocks) >= 10 and ros.probe.joint_states)
    times = ros.probe.clock_times()
    assert all(b > a for a, b in zip(times, times[1:]))
    assert all(math.isclose(b - a, PERIOD, abs_tol=1e-6) for a, b in zip(times, times[1:]))
    state = ros.probe.joint_states[-1]
    assert list(state.name) == ['hip', 'knee']
    assert any(math.isclose(seconds(state.header.stamp), t, abs_tol=1e-9) for t in times)


def _set_parameter(ros, name, value):
    """SetParameters on the simulator through its service (as `ros2 param set` does)."""
    request = SetParameters.Request(parameters=[Parameter(name, value=value)
                                                .to_parameter_msg()])
    return ros.call(ros.probe.set_parameters, request).results[0]


def test_the_node_answers_while_its_simulation_is_built(ros, monkeypatch):
    """While the scene is read (the simulation's modules imported) and the simulation built
    (its kernels compiling on a cold cache; the start-up thread is held here until the test
    lets it go), zeta is accepted or refused with the reason, pause is taken, reset is refused
    with the reason, /diagnostics says it starts, and nothing else is published; then the
    simulation starts with what was set meanwhile (zeta: not the scene's 0.5)."""
    from rft_sim_ros.ros import node as node_module
    go = threading.Event()
    read = node_module.read_scene

    def held_read(*args):
        assert go.wait(BUILD_TIMEOUT_S)
        return read(*args)
    monkeypatch.setattr(node_module, 'read_scene', held_read)
    try:
        sim = ros.add(SimNode(context=ros.context, parameter_overrides=[
            Parameter('scene', value=SERVO_RIG), Parameter('real_time_factor', value=2.0)]),
            built=False)
        assert sim.starting and sim.get_parameter_or('zeta').value is None  # (the scene's)
        accepted = _set_parameter(ros, 'zeta', 5.0)
        refused = _set_parameter(ros, 'zeta', -1.0)
        assert accepted.successful
        assert not refused.successful and 'zeta must be > 0' in refused.reason
        paused = ros.call(ros.probe.pause, SetBool.Request(data=True))
        assert paused.success and 'start paused once built' in paused.message
        reset = ros.call(ros.probe.reset, Trigger.Request())
        assert not reset.success and 'not built yet (reading the scene' in reset.message

        def starting(zeta, paused):  # /diagnostics of the start-up saying what it starts with
            return [m for m in ros.probe.diagnostics
                    if m.status[0].message.startswith('starting: reading the scene')
                    and {kv.key: kv.value for kv in m.status[0].values}.get(
                        'zeta_n_per_cm3') == zeta
                    and {kv.key: kv.value for kv in m.status[0].values}.get('paused') == paused]
        assert ros.spin_until(lambda: starting('5.0', 'true'))
        assert sim.starting and not ros.probe.clocks and not ros.probe.joint_states
    finally:
        go.set()
    assert ros.spin_until(lambda: not sim.starting, timeout=BUILD_TIMEOUT_S)
    assert sim.runtime.paused and sim.runtime.sim.zeta == 5.0 and sim.runtime.sim.time == 0.0
    assert sim.get_parameter('publish_rate').value == 100.0     # the scene's, once read
    assert ros.call(ros.probe.pause, SetBool.Request(data=False)).success
    assert ros.spin_until(lambda: ros.probe.joint_states)
    assert sim.runtime.sim.zeta == 5.0


def test_the_node_module_imports_none_of_the_simulation():
    """`ros2 run rft_sim_ros sim` imports the node's module before rclpy.init: it imports
    rclpy and light modules only, so the node is on the graph, answering, while the start-up
    thread imports MuJoCo, numba and the engine (seconds) and reads the scene."""
    heavy = ('numba', 'mujoco', 'trimesh', 'rft_sim_ros.sim.simulation',
             'rft_sim_ros.scenes.config', 'rft_sim_ros.ros.runtime')
    done = subprocess.run([sys.executable, '-c', 'import sys, rft_sim_ros.ros.node; '
                           f'print([m for m in {heavy!r} if m in sys.modules])'],
                          capture_output=True, text=True, timeout=120, check=True)
    assert done.stdout.strip() == '[]'


def test_zeta_parameter_is_validated(ros):
    sim = start_sim(ros)
    assert sim.get_parameter('zeta').value == 0.5              # unset: the scene's

    def set_(name, value):
        request = SetParameters.Request(parameters=[Parameter(name, value=value)
                                                    .to_parameter_msg()])
        return ros.call(ros.probe.set_parameters, request).results[0]

    refused = set_('zeta', -1.0)
    assert not refused.successful and '> 0' in refused.reason
    assert not set_('zeta', float('nan')).successful
    assert '<= 100' in set_('zeta', 250.0).reason
    assert sim.runtime.sim.zeta == 0.5
    accepted = set_('zeta', 2)  # an integer is a number too
    assert accepted.successful and sim.runtime.sim.zeta == 2.0
    assert sim.get_parameter('zeta').type_ == Parameter.Type.DOUBLE
    assert not set_('zeta', -1).successful                   # refused as -1.0 would be
    assert not set_('scene', 'plate_drop').successful        # read-only
    assert not set_('real_time_factor', -1.0).successful
    assert set_('real_time_factor', 0.5).successful and sim.runtime.real_time_factor == 0.5


DOUBLES = ['zeta', 'real_time_factor', 'publish_rate', 'terrain_rate']


def test_number_parameters_stay_doubles_when_given_integers(ros):
    """An integer for a double parameter, at start-up (`-p zeta:=2`, a launch file's value) or
    set later (`ros2 param set /rft_sim zeta 3`), is taken as a double: `ros2 param describe`
    says double and a client reading double_value gets the value."""
    sim = ros.add(SimNode(context=ros.context, cli_args=[
        '--ros-args', '-p', 'zeta:=2', '-p', 'publish_rate:=50', '-p', 'terrain_rate:=1'],
        parameter_overrides=[Parameter('scene', value=SERVO_RIG),
                             Parameter('real_time_factor', value=2)]))
    describe = ros.probe.create_client(DescribeParameters, '/rft_sim/describe_parameters')
    get = ros.probe.create_client(GetParameters, '/rft_sim/get_parameters')

    def typed_values():
        types = [d.type for d in ros.call(describe, DescribeParameters.Request(
            names=DOUBLES)).descriptors]
        values = ros.call(get, GetParameters.Request(names=DOUBLES)).values
        return types, [(v.type, v.double_value) for v in values]

    double = ParameterType.PARAMETER_DOUBLE
    assert typed_values() == ([double] * 4, [(double, 2.0), (double, 2.0), (double, 50.0),
                                             (double, 1.0)])
    assert sim.runtime.publish_period == pytest.approx(0.02)
    request = SetParameters.Request(parameters=[Parameter('zeta', value=3).to_parameter_msg()])
    assert ros.call(ros.probe.set_parameters, request).results[0].successful
    assert typed_values()[1][0] == (double, 3.0) and sim.runtime.sim.zeta == 3.0


def test_every_parameter_has_a_value_so_a_dump_gets_them_all(ros):
    """GetParameters of every parameter the node lists (what `ros2 param dump` asks) answers
    a value for each: one declared without a value (joint_gains, before this was given one)
    made rclpy answer none at all. joint_gains: an empty string list, the defaults."""
    start_sim(ros)
    listed = ros.call(ros.probe.create_client(ListParameters, '/rft_sim/list_parameters'),
                      ListParameters.Request()).result.names
    values = ros.call(ros.probe.create_client(GetParameters, '/rft_sim/get_parameters'),
                      GetParameters.Request(names=listed)).values
    assert 'joint_gains' in listed and len(values) == len(listed)
    gains = values[list(listed).index('joint_gains')]
    assert gains.type == ParameterType.PARAMETER_STRING_ARRAY and gains.string_array_value == []


def test_a_trajectory_moves_a_joint_and_a_malformed_one_is_rejected(ros):
    sim = start_sim(ros)
    assert ros.spin_until(lambda: ros.probe.joint_states)
    ros.probe.trajectory.publish(trajectory(['hip', 'ankle'], [0.4, 0.1], 0.1))
    ros.probe.trajectory.publish(trajectory(['hip'], [math.nan], 0.1))
    ros.probe.positions.publish(Float64MultiArray(data=[0.1]))
    assert ros.spin_until(lambda: sum(sim.runtime.rejections.values()) == 3)
    assert sim.runtime.rejections == {'unknown_joint': 1, 'not_finite': 1, 'array_length': 1}
    ros.spin_for(0.3)
    assert abs(hip(ros.probe.joint_states[-1])) < 1e-3        # nothing moved
    ros.probe.trajectory.publish(trajectory(['hip'], [0.4], 0.1))
    assert ros.spin_until(lambda: abs(hip(ros.probe.joint_states[-1]) - 0.4) < 0.01)
    ros.probe.positions.publish(Float64MultiArray(data=[-0.2, 0.0]))
    assert ros.spin_until(lambda: abs(hip(ros.probe.joint_states[-1]) + 0.2) < 0.01)
    assert ros.spin_until(lambda: any(
        kv.key == 'commands_rejected' and kv.value == '3'
        for m in ros.probe.diagnostics for kv in m.status[0].values), timeout=5.0)


def test_efforts_drive_the_joints_and_malformed_ones_are_rejected(ros):
    """/effort_controller/commands: N m per joint in joint_names order; the servos let go
    while efforts apply, a position command takes the joints back."""
    sim = start_sim(ros)
    assert ros.spin_until(lambda: ros.probe.joint_states)
    ros.probe.efforts.publish(Float64MultiArray(data=[0.1]))
    ros.probe.efforts.publish(Float64MultiArray(data=[math.nan, 0.0]))
    assert ros.spin_until(lambda: sum(sim.runtime.rejections.values()) == 2)
    assert sim.runtime.rejections == {'array_length': 1, 'not_finite': 1}
    ros.probe.efforts.publish(Float64MultiArray(data=[0.3, 0.0]))  # N m about +y at the hip
    assert ros.spin_until(lambda: hip(ros.probe.joint_states[-1]) > 0.1)
    assert sim.runtime.sim.interfaces.mode == 'effort'
    ros.probe.positions.publish(Float64MultiArray(data=[0.0, 0.0]))
    assert ros.spin_until(lambda: abs(hip(ros.probe.joint_states[-1])) < 0.01)
    assert sim.runtime.sim.interfaces.mode == 'position'


def test_velocities_turn_the_joints_and_malformed_ones_are_rejected(ros):
    """/velocity_controller/commands: rad/s per joint in joint_names order, as ros2_control's
    velocity forward controller takes them."""
    sim = start_sim(ros)
    velocities = ros.probe.create_publisher(Float64MultiArray, topics.VELOCITY_COMMANDS, 10)
    assert ros.spin_until(lambda: ros.probe.joint_states
                          and velocities.get_subscription_count() > 0)
    velocities.publish(Float64MultiArray(data=[math.inf, 0.0]))
    assert ros.spin_until(lambda: sim.runtime.rejections == {'not_finite': 1})
    velocities.publish(Float64MultiArray(data=[0.4, 0.0]))
    assert ros.spin_until(lambda: hip(ros.probe.joint_states[-1]) > 0.15)
    state = ros.probe.joint_states[-1]
    assert abs(state.velocity[list(state.name).index('hip')] - 0.4) < 0.02


def test_pause_step_and_reset_services(ros):
    sim = start_sim(ros)
    ros.probe.positions.publish(Float64MultiArray(data=[0.3, 0.0]))
    assert ros.spin_until(lambda: ros.probe.joint_states
                          and abs(hip(ros.probe.joint_states[-1]) - 0.3) < 0.01)
    refused = ros.call(ros.probe.step, Trigger.Request())
    assert not refused.success and 'pause' in refused.message
    answer = ros.call(ros.probe.pause, SetBool.Request(data=True))
    assert answer.success and sim.get_parameter('paused').value is True
    assert ros.catch_up(sim)                  # what was published before the pause, then
    count, last = len(ros.probe.clocks), ros.probe.clock_times()[-1]
    ros.spin_for(0.3)
    assert len(ros.probe.clocks) == count                      # time stands still
    assert ros.call(ros.probe.step, Trigger.Request()).success
    assert ros.spin_until(lambda: len(ros.probe.clocks) == count + 1)
    assert ros.probe.clock_times()[-1] == pytest.approx(last + PERIOD, abs=1e-9)
    reset = ros.call(ros.probe.reset, Trigger.Request())
    assert reset.success and 'paused' in reset.message
    assert ros.call(ros.probe.step, Trigger.Request()).success
    assert ros.spin_until(lambda: len(ros.probe.clocks) == count + 2)
    assert ros.probe.clock_times()[-1] == pytest.approx(last + 2 * PERIOD, abs=1e-9)
    assert abs(hip(ros.probe.joint_states[-1])) < 0.05         # back at the initial pose
    assert ros.call(ros.probe.pause, SetBool.Request(data=False)).success
    assert sim.get_parameter('paused').value is False
    assert ros.spin_until(lambda: len(ros.probe.clocks) > count + 5)


def test_divergence_pauses_and_reports_an_error(ros):
    sim = start_sim(ros)
    assert ros.spin_until(lambda: ros.probe.clocks)
    sim.runtime.sim.data.qvel[:] = 1e5   # rad/s: a runaway, caught at the next control tick
    assert ros.spin_until(lambda: any(m.status[0].level == DiagnosticStatus.ERROR
                                      for m in ros.probe.diagnostics))
    assert sim.get_parameter('paused').value is True
    refused = ros.call(ros.probe.pause, SetBool.Request(data=False))
    assert not refused.success and 'reset' in refused.message
    assert ros.call(ros.probe.reset, Trigger.Request()).success
    assert ros.call(ros.probe.pause, SetBool.Request(data=False)).success
    count = len(ros.probe.clocks)
    assert ros.spin_until(lambda: len(ros.probe.clocks) > count + 3)


@pytest.mark.parametrize('parameters, words', [
    ({'scene': 'no_such_scene'}, 'unknown scene'),
    ({'zeta': -1.0}, 'zeta must be > 0'),
    ({'joint_names': ['hip']}, 'joint_names'),
    ({'publish_rate': 0.0}, 'publish_rate'),
    ({'scene_overrides': ['no_such_key=1']}, 'no_such_key'),
    ({'scene_overrides': ['sand.deformable.cell=-1']},
     'scene_overrides sand.deformable.cell: must be > 0')])
def test_bad_start_parameters_are_refused_with_the_reason(ros, parameters, words):
    with pytest.raises((SceneError, ValueError, StartFailed), match=words):
        start_sim(ros, **parameters)


@pytest.mark.parametrize('main, arguments', [
    (sim_main, ['-p', 'scene:=no_such_scene']),
    (gait_main, ['-p', 'frequency:=-1.0'])])
def test_executables_exit_with_status_1_on_a_bad_start_parameter(main, arguments, monkeypatch):
    # (the default context: on this test's DDS domain, not the one of the environment)
    monkeypatch.setenv('ROS_DOMAIN_ID', str(DOMAIN_ID))
    assert main(['--ros-args', *arguments]) == 1
    assert not rclpy.ok()                          # the default context is shut down again


def test_tripod_gait_publishes_trajectories_in_sim_time(ros):
    ros.add(TripodGaitNode(context=ros.context, parameter_overrides=[
        Parameter('start_delay', value=0.5), Parameter('rate', value=20)]))
    for k in range(1, 60):  # play the simulator: /clock at 100 Hz from t = 0.01 s
        ros.probe.clock.publish(Clock(clock=Time(sec=0, nanosec=k * 10_000_000)))
        ros.spin_for(0.005)
    assert ros.spin_until(lambda: len(ros.probe.trajectories) >= 3)
    message = ros.probe.trajectories[-1]
    assert tuple(message.joint_names) == HEXAPOD_JOINTS
    assert 0.0 < seconds(message.header.stamp) <= 0.6
    assert len(message.points) == 13 and len(message.points[0].velocities) == 12
    assert seconds(message.points[-1].time_from_start) == pytest.approx(0.24)


def _start_executable(module, *arguments):
    """The console script `module` (its main) as a subprocess on this test's DDS domain."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(DOMAIN_ID), PYTHONUNBUFFERED='1')
    return subprocess.Popen([sys.executable, '-m', module, '--ros-args', *arguments],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait_for_output(process, words, timeout=120.0):
    """Read the process's stderr (rclpy logs there) until a line holds `words`."""
    deadline = time.monotonic() + timeout
    lines = []
    while time.monotonic() < deadline:
        ready, _, _ = select.select([process.stderr], [], [], 0.5)
        if ready:
            line = process.stderr.readline()
            if not line:
                break
            lines.append(line)
            if words in line:
                return lines
    raise AssertionError(f'{words!r} not logged; output so far: {"".join(lines)}')


@pytest.mark.parametrize('rule', ['sand_bodies:=*_foot',
                                  'scene_overrides:=[sand.surface.size=[2,2]]'])
def test_a_parameter_value_rcl_cannot_read_is_refused_in_one_line(rule):
    """`-p` values are YAML to rcl: one that is not (a bare `*`, brackets in a list item)
    stops the node at start-up with one fatal line naming the rule and how to quote it,
    status 1, no traceback."""
    process = _start_executable('rft_sim_ros.ros.node', '-p', rule)
    try:
        stdout, stderr = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    lines = (stdout + stderr).strip().splitlines()
    assert process.returncode == 1, stderr
    assert len(lines) == 1 and 'Traceback' not in stderr, stderr
    assert '[FATAL]' in lines[0] and f"cannot start: the parameter rule '-p {rule}'" in lines[0]
    assert '''-p "sand_bodies:='*_foot'"''' in lines[0]


@pytest.mark.parametrize('signal_number', [signal.SIGINT, signal.SIGTERM],
                         ids=['SIGINT', 'SIGTERM'])
def test_nodes_exit_cleanly_on_a_signal_while_publishing(signal_number):
    """The simulator as fast as it can (a timer callback is publishing almost all the time)
    and the gait nodes on its /clock (every console-script node): a signal to each ends it
    with status 0, no traceback."""
    sim = _start_executable('rft_sim_ros.ros.node', '-p', f'scene:={SERVO_RIG}',
                            '-p', 'real_time_factor:=0.0')
    processes = {'sim': sim}
    for name, module in (('tripod_gait', 'rft_sim_ros.ros.gait_node'),
                         ('trot_gait', 'rft_sim_ros.ros.trot_gait_node')):
        processes[name] = _start_executable(module, '-p', 'start_delay:=0.0',
                                            '-p', 'rate:=200.0')
    try:
        logged = _wait_for_output(sim, 'publishing every')
        time.sleep(1.5)  # publishing at full speed; the gait nodes receive /clock
        for process in processes.values():
            process.send_signal(signal_number)
        for name, process in processes.items():
            _, stderr = process.communicate(timeout=30)
            if process is sim:
                stderr = ''.join(logged) + stderr
            assert 'Traceback' not in stderr, f'{name}: {stderr}'
            assert process.returncode == 0, f'{name} exited {process.returncode}: {stderr}'
    finally:
        for process in processes.values():
            if process.poll() is None:
                process.kill()
                process.communicate()


def test_sim_node_says_it_compiles_and_a_signal_then_still_exits_cleanly(tmp_path):
    """With an empty numba cache (and no prebuilt kernels) the node says at once that it
    compiles; SIGINT while it does stops it with status 0 and no traceback."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(DOMAIN_ID), PYTHONUNBUFFERED='1',
               NUMBA_CACHE_DIR=str(tmp_path), RFT_SIM_PREBUILT='0')
    sim = subprocess.Popen([sys.executable, '-m', 'rft_sim_ros.ros.node', '--ros-args',
                            '-p', f'scene:={SERVO_RIG}'], env=env, stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True)
    try:
        logged = _wait_for_output(sim, 'compiling kernels, first run only')
        time.sleep(1.0)
        sim.send_signal(signal.SIGINT)
        _, stderr = sim.communicate(timeout=120)
        stderr = ''.join(logged) + stderr
        assert 'Traceback' not in stderr, stderr
        assert sim.returncode == 0, stderr
    finally:
        if sim.poll() is None:
            sim.kill()
            sim.communicate()

ROBOTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'robots')
SANDBOT = os.path.join(ROBOTS, 'sandbot_description', 'urdf', 'sandbot.urdf.xacro')
SANDBOT_FEET = 'fl_foot,fr_foot,rl_foot,rr_foot'


def sandbot_xml():
    return expand_xacro(SANDBOT, PackageResolver(
        {'sandbot_description': os.path.join(ROBOTS, 'sandbot_description')}))


def robot_sim(ros, **parameters):
    """rft_sim with no scene: the sandbot robot from `parameters` (model/robot_description)."""
    overrides = {'sand_bodies': SANDBOT_FEET, 'real_time_factor': 2.0,
                 'scene_overrides': ['sand.surface_height=-0.25'], **parameters}
    return ros.add(SimNode(context=ros.context, parameter_overrides=[
        Parameter(name, value=value) for name, value in overrides.items()]))


def test_model_parameter_puts_a_robot_file_in_sand(ros, monkeypatch):
    monkeypatch.setenv('ROS_PACKAGE_PATH', ROBOTS)
    node = robot_sim(ros, model=SANDBOT)
    assert node.runtime.sim.scene.sand_bodies == tuple(SANDBOT_FEET.split(','))
    assert ros.spin_until(lambda: any('fl_knee' in m.name for m in ros.probe.joint_states))


def test_robot_description_parameter_takes_the_xml(ros, monkeypatch):
    monkeypatch.setenv('ROS_PACKAGE_PATH', ROBOTS)
    node = robot_sim(ros, robot_description=sandbot_xml())
    assert node.runtime.sim.scene.name.startswith('robot_description')
    assert ros.spin_until(lambda: len(ros.probe.clocks) > 3)


def test_robot_description_topic_is_waited_for_and_read_latched(ros, monkeypatch):
    monkeypatch.setenv('ROS_PACKAGE_PATH', ROBOTS)
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    publisher = ros.probe.create_publisher(String, '/robot_description', latched)
    publisher.publish(String(data='<robot name="broken">'))  # refused, node keeps waiting
    node = robot_sim(ros)
    ros.spin_for(0.5)
    assert node.runtime is None and not ros.probe.clocks
    publisher.publish(String(data=sandbot_xml()))  # as robot_state_publisher: latched
    assert ros.spin_until(lambda: node.runtime is not None and len(ros.probe.clocks) > 3,
                          timeout=BUILD_TIMEOUT_S)  # (built in the start-up thread meanwhile)
    assert 'rr_knee' in node.runtime.sim.joint_names


def test_trot_gait_publishes_the_quadruped_joints(ros):
    ros.add(TrotGaitNode(context=ros.context, parameter_overrides=[
        Parameter('start_delay', value=0.0), Parameter('rate', value=20)]))
    for k in range(1, 40):
        ros.probe.clock.publish(Clock(clock=Time(sec=1, nanosec=k * 10_000_000)))
        ros.spin_for(0.005)
    assert ros.spin_until(lambda: len(ros.probe.trajectories) >= 2)
    message = ros.probe.trajectories[-1]
    assert tuple(message.joint_names) == QUADRUPED_JOINTS
    assert len(message.points) == 13 and len(message.points[0].positions) == 12


def test_keyframe_parameter_sets_the_initial_pose(ros, tmp_path):
    """`keyframe`: a torque-motor MJCF (test/robot_files.py) starts in its `home` keyframe,
    held by the PD position interface; an unknown keyframe is refused with the reason."""
    from robot_files import HOME_THIGH, write_torque_quadruped
    path, _ = write_torque_quadruped(tmp_path, trunk_subdivisions=3)
    ros.add(SimNode(context=ros.context, parameter_overrides=[
        Parameter('model', value=str(path)), Parameter('keyframe', value='home'),
        Parameter('real_time_factor', value=2.0)]))
    assert ros.spin_until(lambda: len([m for m in ros.probe.joint_states
                                       if 'FL_thigh_joint' in m.name]) > 10)
    last = ros.probe.joint_states[-1]
    assert last.position[list(last.name).index('FL_thigh_joint')] == pytest.approx(
        HOME_THIGH, abs=0.05)
    with pytest.raises(StartFailed, match="robot.keyframe: keyframe 'nope' is not in the model"):
        ros.add(SimNode(context=ros.context, parameter_overrides=[
            Parameter('model', value=str(path)), Parameter('keyframe', value='nope')]))


def test_as_fast_as_possible_a_command_takes_effect_at_the_next_cycle(ros):
    """real_time_factor 0: a timer callback runs publish cycles for up to 50 ms of wall time
    (on the servo rig, a few tenths of a second of sim time); the node reads its command
    topics before every cycle, so the joint moves from the cycle after the command was
    sent, not only after the callback's cycles (every state stamped from two cycles on
    shows it moving; those of one callback beyond the publisher's depth are not seen)."""
    sim = start_sim(ros, real_time_factor=0.0)
    assert ros.spin_until(lambda: len(ros.probe.joint_states) > 10)
    sent = sim.runtime.sim.time
    ros.probe.positions.publish(Float64MultiArray(data=[0.3, 0.0]))
    assert ros.spin_until(lambda: seconds(ros.probe.joint_states[-1].header.stamp) > sent + 0.1)
    after = [hip(m) for m in ros.probe.joint_states
             if seconds(m.header.stamp) > sent + 2 * PERIOD]
    assert after and min(after) > 0.01, (sent, after)


def test_a_second_clock_publisher_is_warned_of():
    """Two simulators in one ROS domain (two namespaces share the one /clock): each warns
    that another node publishes /clock."""
    first = _start_executable('rft_sim_ros.ros.node', '-p', f'scene:={SERVO_RIG}',
                              '-r', '__ns:=/one')
    second = _start_executable('rft_sim_ros.ros.node', '-p', f'scene:={SERVO_RIG}',
                               '-r', '__ns:=/two')
    try:
        lines = _wait_for_output(first, 'other publisher of /clock', timeout=60)
        assert 'Run one simulator per ROS domain' in lines[-1]
    finally:
        for process in (first, second):
            process.send_signal(signal.SIGINT)
            process.communicate(timeout=30)
