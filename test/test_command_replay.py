"""`rft-sim run ... --commands FILE` (rft_sim_ros.ros.replay): recorded commands replayed in
sim time from a rosbag2 folder (JTC trajectory, forward effort array, JointState commands)
and from CSV / YAML joint targets, on the bundled quadruped and on a robot file; a malformed
file is one clear error line.

test/bags/ holds two bags that `ros2 bag record` (ROS 2 Jazzy, MCAP storage) recorded from a
real controller_manager (ros2_control 4.22, launch/control.launch.py) driving the simulator:
jtc_trajectory, the trajectory_msgs/JointTrajectory published to joint_trajectory_controller
(every joint, hips 0.6 -> 0.8 rad, knees -1.2 -> -1.5 rad in 1 s), and
robot_joint_commands, the sensor_msgs/JointState commands the topic hardware interface
(JointStateTopicSystem) sent while that JTC ran the same motion (zstd-compressed, trimmed to
2.5 s by `ros2 bag convert`: held, moving from 0.5 s to 1.5 s, held).
"""
import math
from pathlib import Path

import pytest
from rosbags.rosbag2 import Writer

from rft_sim_ros.cli import main
from rft_sim_ros.control.commands import TrajectoryCommand, TrajectoryPoint
from rft_sim_ros.ros import messages, topics
from rft_sim_ros.ros.factory import RosbagsFactory, jazzy_typestore
from rft_sim_ros.ros.replay import load_commands
from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sim.runner import run_scene
from test_cli import one_error_line
from test_joint_state_commands import joint_state
from ros_test_support import SERVO_RIG

FACTORY = RosbagsFactory(jazzy_typestore())
RIG_MODEL = SERVO_RIG.replace('servo_rig.yaml', 'servo_rig.xml')
NS = 1_000_000_000
BAGS = Path(__file__).parent / 'bags'


class States:
    """A run_scene recorder keeping the states."""

    def __init__(self):
        self.states = []

    def record(self, state):
        self.states.append(state)

    def close(self):
        pass

    def joint(self, name, time):
        state = min(self.states, key=lambda s: abs(s.time - time))
        return state.joint_positions[state.joint_names.index(name)]


def replay(scene, path, duration):
    states = States()
    run_scene(scene, None, duration=duration, recorders=[states], progress=False, plots=False,
              schedule=load_commands(path).schedule())
    return states


@pytest.fixture(scope='module')
def quadruped():
    return load_scene('quadruped', overrides={'params.gait': 'none'})


def test_csv_targets_move_the_quadruped_knees(quadruped, tmp_path):
    path = tmp_path / 'knees.csv'
    path.write_text('time,fl_knee,fr_knee\n0.0,-1.2,-1.2\n0.4,-1.0,-1.4\n')
    states = replay(quadruped, path, 0.8)
    assert states.joint('fl_knee', 0.0) == pytest.approx(-1.2, abs=0.02)
    assert states.joint('fl_knee', 0.8) == pytest.approx(-1.0, abs=0.03)
    assert states.joint('fr_knee', 0.8) == pytest.approx(-1.4, abs=0.03)
    assert states.joint('fl_knee', 0.2) == pytest.approx(-1.1, abs=0.04)  # on the way


def write_bag(path, entries):
    """A rosbag2 folder of (topic, type, time in s after a start at 1000 s, message)."""
    typestore = jazzy_typestore()
    with Writer(path, version=9) as writer:
        connections = {}
        for topic, msgtype, t, message in entries:
            if topic not in connections:
                connections[topic] = writer.add_connection(topic, msgtype, typestore=typestore)
            writer.write(connections[topic], int((1000.0 + t) * NS),
                         typestore.serialize_cdr(message, msgtype))


def array(values):
    layout = FACTORY.make('std_msgs/msg/MultiArrayLayout', dim=[], data_offset=0)
    return FACTORY.make('std_msgs/msg/Float64MultiArray', layout=layout,
                        data=FACTORY.float64_sequence(values))


def test_a_recorded_bag_replays_trajectory_then_joint_state_commands(quadruped, tmp_path):
    names = ['fl_knee', 'rr_knee']
    trajectory = messages.joint_trajectory_message(FACTORY, TrajectoryCommand(
        joint_names=names, points=[TrajectoryPoint([-1.0, -1.0], 0.3)]))
    entries = [('/joint_states', topics.JOINT_STATE_TYPE, 0.0,  # a state: not replayed
                joint_state(['fl_knee'], position=[5.0])),
               (topics.JOINT_TRAJECTORY, topics.JOINT_TRAJECTORY_TYPE, 0.2, trajectory)]
    entries += [(topics.ROBOT_JOINT_COMMANDS, topics.JOINT_STATE_TYPE, 0.8 + 0.02 * k,
                 joint_state(names, position=[-1.3, math.nan])) for k in range(10)]
    write_bag(tmp_path / 'bag', entries)
    replay_ = load_commands(tmp_path / 'bag')
    assert [c.kind for c in replay_.commands] == ['trajectory'] + ['joint_state'] * 10
    assert replay_.commands[0].time == pytest.approx(0.2)
    states = replay(quadruped, tmp_path / 'bag', 1.2)
    assert states.joint('fl_knee', 0.2) == pytest.approx(-1.2, abs=0.02)
    assert states.joint('fl_knee', 0.75) == pytest.approx(-1.0, abs=0.03)
    assert states.joint('fl_knee', 1.2) == pytest.approx(-1.3, abs=0.03)
    assert states.joint('rr_knee', 1.2) == pytest.approx(-1.0, abs=0.03)  # NaN: held


def standing_joints(states, time):
    """{joint: position} at `time`, after checking the quadruped stands upright."""
    state = min(states.states, key=lambda s: abs(s.time - time))
    assert state.base_quaternion_wxyz[0] > 0.99  # (no tilt over ~16 degrees)
    return dict(zip(state.joint_names, state.joint_positions))


@pytest.mark.parametrize('bag, start, end', [('jtc_trajectory', 0.0, 1.0),
                                             ('robot_joint_commands', 0.5, 1.5)])
def test_bags_that_ros2_bag_record_recorded_of_a_real_controller_replay(quadruped, bag, start,
                                                                         end):
    states = replay(quadruped, BAGS / bag, end + 0.6)
    before, after = standing_joints(states, start - 0.02), standing_joints(states, end + 0.6)
    for leg in ('fl', 'fr', 'rl', 'rr'):  # the JTC's goal tolerance: 0.02 rad
        assert before[f'{leg}_knee'] == pytest.approx(-1.2, abs=0.02)
        assert after[f'{leg}_hip_pitch'] == pytest.approx(0.8, abs=0.02)
        assert after[f'{leg}_knee'] == pytest.approx(-1.5, abs=0.02)


def test_forward_effort_commands_from_a_bag_on_a_robot_file(tmp_path):
    scene = load_scene(RIG_MODEL, overrides={'rft.sand_bodies': ['foot']})
    write_bag(tmp_path / 'bag', [('/effort_controller/commands', topics.FLOAT64_ARRAY_TYPE,
                                  0.1, array([0.0, 0.5]))])
    assert load_commands(tmp_path / 'bag').commands[0].kind == 'effort'
    yaml_path = tmp_path / 'rig.yaml'
    yaml_path.write_text('joint_names: [hip, knee]\n'
                         'points:\n  - {time: 0.3, positions: [0.3, -0.4]}\n')
    moved = replay(scene, yaml_path, 0.6)
    assert moved.joint('hip', 0.6) == pytest.approx(0.3, abs=0.05)
    assert moved.joint('knee', 0.6) == pytest.approx(-0.4, abs=0.05)
    pushed = replay(scene, tmp_path / 'bag', 0.6)
    assert pushed.joint('knee', 0.6) - pushed.joint('knee', 0.1) > 0.05  # effort turned it


@pytest.mark.parametrize('name, text, phrases', [
    ('bad.csv', 'time,fl_knee\n0.0,abc\n', ['line 2', "'abc' is not a number"]),
    ('bad.csv', 'fl_knee\n-1.2\n', ['header time,JOINT']),
    ('bad.yaml', 'joint_names: [a]\npoints: 3\n', ['joint_names: [...], points']),
    ('bad.yaml', 'joint_names: [a\n', ['not valid YAML']),
    ('bad.txt', 'x', ['a rosbag2 folder, a .csv or a .yaml file']),
])
def test_a_malformed_commands_file_is_one_error_line(tmp_path, capsys, name, text, phrases):
    path = tmp_path / name
    path.write_text(text)
    out = tmp_path / 'run'
    assert main(['run', 'quadruped', '--set', 'params.gait=none', '--duration', '0.02',
                 '--quiet', '--no-bag', '--out', str(out), '--commands', str(path)]) == 2
    one_error_line(capsys, str(path), *phrases)
    assert not out.exists()  # refused: nothing left behind


def test_a_command_the_handler_rejects_stops_the_run_with_one_error_line(tmp_path, capsys):
    path = tmp_path / 'unknown.csv'
    path.write_text('time,fl_ankle\n0.5,0.0\n')
    out = tmp_path / 'run'
    assert main(['run', 'quadruped', '--set', 'params.gait=none', '--duration', '0.02',
                 '--quiet', '--no-bag', '--out', str(out), '--commands', str(path)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()  # (the start-up notices first)
    errors = [line for line in lines if line.startswith('rft-sim: error: ')]
    assert errors == [lines[-1]]
    for phrase in (str(path), 'at t = 0 s', 'rejected (unknown_joint)', 'fl_ankle'):
        assert phrase in errors[0]
    assert not out.exists()


def test_a_folder_that_is_no_bag_is_one_error_line(tmp_path, capsys):
    (tmp_path / 'empty').mkdir()
    assert main(['run', 'quadruped', '--duration', '0.02', '--quiet', '--no-bag', '--out',
                 str(tmp_path / 'run'), '--commands', str(tmp_path / 'empty')]) == 2
    one_error_line(capsys, 'not a readable rosbag2 folder')
