"""Shared helpers of the ROS-interface tests (not a test module)."""
import dataclasses
from pathlib import Path

import numpy as np

from rft_sim_ros.ros.factory import jazzy_typestore
from rft_sim_ros.ros.runtime import SimRuntime
from rft_sim_ros.ros.terrain import TerrainTile, TerrainUpdate
from rft_sim_ros.sim.simulation import Simulation
from rft_sim_ros.sim.state import ActivePlates, LegWrench, SimState


def quaternion_wxyz_about(axis, angle):
    """Unit quaternion (w, x, y, z) of a rotation by `angle` (rad) about `axis`."""
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    return np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis])


def rotation_from_xyzw(x, y, z, w):
    """Rotation matrix of a ROS-order quaternion (columns: child axes in parent frame)."""
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def make_state(time=12.3456789012, legs=('L1', 'R2'), plates=2, seed=0):
    """A SimState with distinct, non-trivial values in every field (base rotated 30 deg
    about an oblique axis)."""
    rng = np.random.default_rng(seed)
    joint_names = ('knee_L1', 'ankle_L1', 'knee_R2', 'ankle_R2')
    active = None
    if plates is not None:
        active = ActivePlates(positions=rng.normal(size=(plates, 3)) * 0.1,
                              forces=rng.normal(size=(plates, 3)),
                              areas=rng.uniform(1e-5, 1e-4, size=plates))
    return SimState(
        time=time,
        joint_names=joint_names,
        joint_positions=rng.normal(size=4),
        joint_velocities=rng.normal(size=4),
        joint_efforts=rng.normal(size=4),
        base_frame='trunk',
        base_position=np.array([0.5, -0.25, 0.125]),
        base_quaternion_wxyz=quaternion_wxyz_about([1.0, 2.0, 3.0], np.pi / 6),
        base_linear_velocity=np.array([0.1, -0.02, 0.003]),
        base_angular_velocity=np.array([0.4, 0.05, -0.6]),
        legs=tuple(LegWrench(name=name, force=rng.normal(size=3) * 10,
                             torque=rng.normal(size=3), point=rng.normal(size=3))
                   for name in legs),
        zeta=3.75,
        plates_active=plates or 0,
        active_plates=active)


def make_terrain_update(clear, time=2.5, cloud=True):
    """A TerrainUpdate at `time` (s) on a grid of 1 cm: tile 3 holding two changed nodes
    (m, odom; dug 1 cm, piled 5 mm), tile 7 pristine again; `cloud`: with a cloud of those
    two nodes; `clear`: the markers sent whole (a DELETEALL first)."""
    points = np.array([[0.1, 0.2, -0.01], [0.11, 0.2, 0.005]], dtype=np.float32)
    tiles = (TerrainTile(3, points, np.array([-0.01, 0.005])),
             TerrainTile(7, np.zeros((0, 3), np.float32), np.zeros(0)))
    return TerrainUpdate(time, points if cloud else None, (1, 2) if cloud else None, clear,
                         tiles, 0.01)


def messages_equal(a, b):
    """Deep equality of rosbags messages (dataclasses holding numpy arrays and lists)."""
    if dataclasses.is_dataclass(a):
        return (type(a) is type(b) and all(
            messages_equal(getattr(a, f.name), getattr(b, f.name))
            for f in dataclasses.fields(a)))
    if isinstance(a, np.ndarray):
        return (isinstance(b, np.ndarray) and a.dtype == b.dtype
                and np.array_equal(a, b))
    if isinstance(a, list):
        return (isinstance(b, list) and len(a) == len(b)
                and all(messages_equal(x, y) for x, y in zip(a, b)))
    return type(a) is type(b) and a == b


#: Scene of the ROS-interface tests: two position servos (hip, knee), a foot in sand.
SERVO_RIG = str(Path(__file__).resolve().parent / 'scenes' / 'servo_rig.yaml')


class FakeClock:
    """A wall clock for tests: returns `now`, then moves on by `per_call` s."""

    def __init__(self, now=1000.0, per_call=0.0):
        self.now, self.per_call = now, per_call

    def __call__(self):
        now = self.now
        self.now += self.per_call
        return now

    def advance(self, seconds):
        self.now += seconds


class ListSink:
    """A SimRuntime sink that keeps what would be published."""

    def __init__(self):
        self.states = []
        self.diagnostics = []

    def write_state(self, state):
        self.states.append(state)

    def write_diagnostics(self, state, status):
        self.diagnostics.append((state, status))


#: control_msgs (5.8.0, the version ROS 2 Jazzy ships; github.com/ros-controls/control_msgs,
#: branch jazzy): the FollowJointTrajectory action's messages and the tolerances it uses,
#: which the rosbags Jazzy typestore does not hold. `control_msgs_typestore` registers them.
CONTROL_MSGS_DEFINITIONS = {
    'control_msgs/msg/JointTolerance': """
string name
float64 position
float64 velocity
float64 acceleration
""",
    'control_msgs/msg/JointComponentTolerance': """
uint16 X_AXIS=1
uint16 Y_AXIS=2
uint16 Z_AXIS=3
uint16 TRANSLATION=4
uint16 ROTATION=5
string joint_name
uint16 component
float64 position
float64 velocity
float64 acceleration
""",
    'control_msgs/action/FollowJointTrajectory_Goal': """
trajectory_msgs/JointTrajectory trajectory
trajectory_msgs/MultiDOFJointTrajectory multi_dof_trajectory
control_msgs/JointTolerance[] path_tolerance
control_msgs/JointComponentTolerance[] component_path_tolerance
control_msgs/JointTolerance[] goal_tolerance
control_msgs/JointComponentTolerance[] component_goal_tolerance
builtin_interfaces/Duration goal_time_tolerance
""",
    'control_msgs/action/FollowJointTrajectory_Result': """
int32 error_code
int32 SUCCESSFUL = 0
int32 INVALID_GOAL = -1
int32 INVALID_JOINTS = -2
int32 OLD_HEADER_TIMESTAMP = -3
int32 PATH_TOLERANCE_VIOLATED = -4
int32 GOAL_TOLERANCE_VIOLATED = -5
string error_string
""",
    'control_msgs/action/FollowJointTrajectory_Feedback': """
std_msgs/Header header
string[] joint_names
trajectory_msgs/JointTrajectoryPoint desired
trajectory_msgs/JointTrajectoryPoint actual
trajectory_msgs/JointTrajectoryPoint error
string[] multi_dof_joint_names
trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_desired
trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_actual
trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_error
""",
}


def control_msgs_typestore():
    """A rosbags Jazzy typestore that also holds `CONTROL_MSGS_DEFINITIONS`."""
    from rosbags.typesys import Stores, get_typestore, get_types_from_msg
    store = get_typestore(Stores.ROS2_JAZZY)
    for name, text in CONTROL_MSGS_DEFINITIONS.items():
        store.register(get_types_from_msg(text, name))
    return store


class Harness:
    """A SimRuntime on the servo rig with a fake clock, a list sink and captured logs."""

    def __init__(self, scene, **options):
        self.clock = FakeClock()
        self.sink = ListSink()
        self.warnings, self.errors = [], []
        self.sim = Simulation(scene)
        options.setdefault('publish_rate', 100.0)
        self.runtime = SimRuntime(self.sim, self.sink, warn=self.warnings.append,
                                  error=self.errors.append, clock=self.clock, **options)

    def run(self, wall_seconds, tick=0.005):
        """Tick the runtime for `wall_seconds` of fake wall time."""
        for _ in range(int(round(wall_seconds / tick))):
            self.clock.advance(tick)
            self.runtime.tick()

    def times(self):
        return [s.time for s in self.sink.states]

    def targets(self):
        return self.sim.commands.sample(self.sim.time).positions.copy()


def position_array(values):
    """A std_msgs/Float64MultiArray (rosbags) of `values`."""
    types_ = jazzy_typestore().types
    layout = types_['std_msgs/msg/MultiArrayLayout'](dim=[], data_offset=0)
    return types_['std_msgs/msg/Float64MultiArray'](layout=layout,
                                                    data=np.array(values, dtype=float))
