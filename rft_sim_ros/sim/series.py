"""A run's time series: one row per published state, the columns of timeseries.csv.
A leg's or joint's column is named `<quantity>_<unit>_<leg or joint>`, as the metrics are.

Columns (SI; world frame = odom, z up; REP 103):
  time_s                              sim time
  base_x_m, base_y_m, base_z_m        base frame origin
  base_roll_rad, base_pitch_rad, base_yaw_rad
                                      base attitude, roll about x, pitch about y, yaw about
                                      z (fixed axes x-y-z; `roll_pitch_yaw`)
  base_speed_mps                      |base linear velocity|
  plates_active                       plates in the sand and leading
  force_z_N_<leg>                     vertical sand force on the leg (mean over the publish
                                      period: state.LegWrench)
  sinkage_m_<leg>                     deepest plate of the leg's sand bodies below the sand
                                      surface over it (0 when out of the sand)
  angle_rad_<joint>, torque_Nm_<joint>    a hinge joint's position and actuator torque
  position_m_<joint>, force_N_<joint>     a slide joint's
"""
import math

import mujoco
import numpy as np


def roll_pitch_yaw(quaternion_wxyz):
    """(roll, pitch, yaw) rad of a unit quaternion (w, x, y, z): the rotation R = Rz(yaw)
    Ry(pitch) Rx(roll) (fixed axes x, y, z; REP 103), pitch in [-pi/2, pi/2]."""
    w, x, y, z = np.asarray(quaternion_wxyz, dtype=float).tolist()
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


def joint_columns(joint, hinge):
    """(position column, effort column) of a joint: hinge (rad, N m) or slide (m, N)."""
    return ((f'angle_rad_{joint}', f'torque_Nm_{joint}') if hinge else
            (f'position_m_{joint}', f'force_N_{joint}'))


def joint_legs(model, joint_ids, legs, base):
    """{joint name: the leg it moves, or None}: a joint belongs to a leg when its body lies on
    the chain from the base to that leg's sand bodies and on no other leg's (a spine or a
    waist joint that several legs hang from belongs to none). legs: {leg: body names}."""
    chains = {}
    for leg, bodies in legs.items():
        chain = set()
        for name in bodies:
            body = model.body(name).id
            while body > 0 and body != base and body not in chain:
                chain.add(body)
                body = int(model.body_parentid[body])
        chains[leg] = chain
    owners = {}
    for joint in joint_ids:
        body = int(model.jnt_bodyid[joint])
        holding = [leg for leg, chain in chains.items() if body in chain]
        owners[model.joint(joint).name] = holding[0] if len(holding) == 1 else None
    return owners


def model_name(model):
    """The name a compiled MuJoCo model gives itself (MJCF <mujoco model=...>, a URDF's
    <robot name=...>); '' when it has none."""
    return model.names.split(b'\0', 1)[0].decode()


class SeriesRows:
    """Makes the time-series rows of a Simulation's states (module docstring): those its
    `state` makes, whose legs are in the order of its `legs`."""

    def __init__(self, sim):
        # a leg's sinkage: the deepest of its sand bodies (the depths' rows); the other
        # bodies of its branch (a shin, sim/outcome.py watches them) are not its feet. Each
        # leg's rows are one run of `_leg_depths`, from `_leg_starts`, so that one reduction
        # gives every leg's sinkage
        index = {name: i for i, name in enumerate(sim.sand_bodies)}
        rows = [[index[b] for b in bodies if b in index] for bodies in sim.legs.values()]
        bare = [leg for leg, run in zip(sim.legs, rows) if not run]
        if bare:  # (build.legs_of gives every leg a sand body)
            raise ValueError(f'legs without a sand body have no sinkage: {bare}')
        self._sinkage_columns = [f'sinkage_m_{leg}' for leg in sim.legs]
        self._force_columns = [f'force_z_N_{leg}' for leg in sim.legs]
        self._leg_depths = np.array([i for leg in rows for i in leg], dtype=int)
        self._leg_starts = np.cumsum([0] + [len(leg) for leg in rows[:-1]])
        hinge = [int(sim.model.jnt_type[sim.model.joint(name).id]) == mujoco.mjtJoint.mjJNT_HINGE
                 for name in sim.joint_names]
        self._joints = [joint_columns(name, h) for name, h in zip(sim.joint_names, hinge)]

    def row(self, state, depths):
        """The row ({column: value}) of `state` (SimState); depths: (sand bodies,) m, each
        body's deepest plate below the surface (`GenericMetrics.depths`)."""
        roll, pitch, yaw = roll_pitch_yaw(state.base_quaternion_wxyz)
        x, y, z = np.asarray(state.base_position).tolist()
        row = {'time_s': state.time, 'base_x_m': x, 'base_y_m': y, 'base_z_m': z,
               'base_roll_rad': roll, 'base_pitch_rad': pitch, 'base_yaw_rad': yaw,
               'base_speed_mps': state.base_speed,
               'plates_active': state.plates_active}
        row.update(zip(self._force_columns, [leg.force[2] for leg in state.legs]))
        if self._sinkage_columns:
            row.update(zip(self._sinkage_columns, np.maximum.reduceat(
                depths[self._leg_depths], self._leg_starts).tolist()))
        for (position, effort), q, tau in zip(self._joints,
                                             np.asarray(state.joint_positions).tolist(),
                                             np.asarray(state.joint_efforts).tolist()):
            row[position] = q
            row[effort] = tau
        return row
