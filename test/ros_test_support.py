"""Shared helpers of the ROS-interface tests (not a test module)."""
import dataclasses
from pathlib import Path

import numpy as np

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
