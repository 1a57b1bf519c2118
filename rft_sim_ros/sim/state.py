"""Snapshot of the simulation that publishers and recorders consume.

`SimState` is the one hand-off point from the physics (rft_sim_ros.sim) to everything that
reports it (ROS messages, rosbag2 files, summary metrics). All quantities are SI; frames are
named in each field's docstring. The world frame is ROS's `odom` (REP 105): fixed, z up,
its origin at the world origin of the MuJoCo model; the sand surface is the scene's
(`sand.surface`: a horizontal plane unless a scene says otherwise), in that frame.
"""
import math
from dataclasses import dataclass, field
from typing import Tuple

import numpy as np


@dataclass(frozen=True)
class LegWrench:
    """Summed RFT wrench that the sand applies to one leg (all of the leg's sand bodies),
    averaged over the steps since the previous snapshot (one publish period): what a
    filtered foot force sensor reports. An instantaneous sample would alias the force's
    ripple at the servo update rate into the published series.

    force:  (3,) N, world (odom) axes.
    torque: (3,) N m, world (odom) axes, about `point`.
    point:  (3,) m, world position of the leg's reference point (origin of its last body,
            e.g. the foot/dactyl), so the wrench can be published in a world-aligned frame
            located at the foot without any rotation: force[2] is the vertical ground force.
    """
    name: str
    force: np.ndarray
    torque: np.ndarray
    point: np.ndarray


@dataclass(frozen=True)
class ActivePlates:
    """Plates currently in the sand and leading (feeling force), for visualisation.

    positions: (K, 3) m, world. forces: (K, 3) N on the body, world axes.
    areas: (K,) m^2. stress = |force| / area (Pa).
    """
    positions: np.ndarray
    forces: np.ndarray
    areas: np.ndarray


@dataclass(frozen=True)
class SimState:
    """What the simulated robot looks like at sim time `time`.

    time: s of simulation time since the start (continuous across resets).
    joint_names / joint_positions (rad or m) / joint_velocities (rad/s or m/s) /
    joint_efforts (N m or N, the actuator force acting on the joint, its mean over the steps
    since the previous state): the scene's actuated and passive 1-DOF joints, in the scene's
    joint order.
    base_frame: the TF frame of the robot's base, the base body's name (a URDF's root link,
    e.g. base_link or base), so that odom -> base_frame joins the tree robot_state_publisher
    publishes from the same description.
    base_position: (3,) m, base frame origin in odom. base_quaternion_wxyz: (4,) orientation
    of the base frame in odom (w, x, y, z; MuJoCo order, convert to ROS x, y, z, w when
    packing). base_linear_velocity / base_angular_velocity: (3,) m/s, rad/s, expressed in the
    base frame (the child frame, as nav_msgs/Odometry.twist requires).
    legs: per-leg RFT wrenches. zeta: sand stiffness in N/cm^3 (the paper's unit).
    plates_active: number of plates currently in the sand and leading.
    sensors: `sensors.SensorReadings` of the IMU, foot contacts and model sensors the scene
    enables (sensors.*), or None when it enables none.
    """
    time: float
    joint_names: Tuple[str, ...]
    joint_positions: np.ndarray
    joint_velocities: np.ndarray
    joint_efforts: np.ndarray
    base_frame: str
    base_position: np.ndarray
    base_quaternion_wxyz: np.ndarray
    base_linear_velocity: np.ndarray
    base_angular_velocity: np.ndarray
    legs: Tuple[LegWrench, ...]
    zeta: float
    plates_active: int
    active_plates: ActivePlates = field(default=None)
    sensors: object = field(default=None)

    @property
    def base_speed(self):
        """|base_linear_velocity|, m/s (the speed of the base frame's origin)."""
        v = np.asarray(self.base_linear_velocity, dtype=float)
        return math.sqrt(v @ v)  # np.linalg.norm's own formula, without its checks
