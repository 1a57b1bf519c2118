"""Kinematics of 2-DOF legs that move in the lateral plane: a knee and an ankle, both turning
about the body's long axis (x), as on the RFT-SiM crab hexapod (models/hexapod.xml).

numpy, and `gait_kernels.leg_inverse`. Every quantity is in SI units (m, rad) and, unless
stated, in the base_link frame (+x forward along the body's long axis, +y left, +z up).
Functions take arrays with one entry per leg.

Leg model; all joint angles zero is the model's zero pose (the leg stretched out sideways):
- the knee axis is parallel to x through `knee_xyz`;
- the mid segment reaches `mid_length` straight outward (+y on a left leg, -y on a right
  leg) from the knee axis to the ankle axis, also parallel to x;
- the dactyl tip sits `tip_out` further outward and `tip_down` below the ankle axis at
  ankle = 0, i.e. the dactyl is a segment of length hypot(tip_out, tip_down) drooping
  atan2(tip_down, tip_out) below the mid segment's line.
Signs, the same on both sides (a left leg's hinges turn about +x, a right leg's about -x):
knee > 0 raises the mid segment's outer end; ankle > 0 raises the dactyl relative to the mid
segment. A leg's foot therefore moves only sideways (y) and up and down (z): the robot walks
sideways, like a crab.

Inverse kinematics picks the arched branch (the ankle above the line from knee to foot, as a
crab holds its legs), the branch that contains the zero pose.
"""
from dataclasses import dataclass
from typing import Tuple

import numpy as np

from .. import prebuilt
from ..kernel_names import LEG_INVERSE


@dataclass(frozen=True, eq=False)
class LateralLegs:
    """Geometry, joint ranges and neutral stance of a set of lateral-plane knee-ankle legs
    (see the module docstring).

    names:        leg names, e.g. ('L1', ..., 'R3').
    knee_xyz:     (N, 3) m, a point on each knee axis, base_link frame.
    side:         (N,) +1 for a leg pointing to +y (left), -1 for one pointing to -y (right).
    mid_length:   m, knee axis to ankle axis.
    tip_out, tip_down: m, dactyl tip relative to the ankle axis at ankle = 0
                  (outward along the leg, and downward).
    knee_range, ankle_range: (min, max) rad, joint limits as in the MuJoCo model.
    neutral_out, neutral_down: m, the stance's neutral foot tip relative to the knee axis
                  (outward, and downward): where a gait centres each foot's stroke.
    """
    names: Tuple[str, ...]
    knee_xyz: np.ndarray
    side: np.ndarray
    mid_length: float
    tip_out: float
    tip_down: float
    knee_range: Tuple[float, float]
    ankle_range: Tuple[float, float]
    neutral_out: float
    neutral_down: float

    @property
    def dactyl_length(self):
        """Ankle axis to dactyl tip, m."""
        return float(np.hypot(self.tip_out, self.tip_down))

    @property
    def dactyl_droop(self):
        """Dactyl angle below the mid segment's line at ankle = 0, rad."""
        return float(np.arctan2(self.tip_down, self.tip_out))

    def neutral_feet(self):
        """(N, 3) m: the neutral foot tips, base_link frame."""
        return self.knee_xyz + np.stack([np.zeros(len(self.names)),
                                         self.side * self.neutral_out,
                                         np.full(len(self.names), -self.neutral_down)], axis=-1)

    def neutral_angles(self):
        """Knee and ankle angles (rad, each (N,)) of the neutral stance."""
        feet = self.neutral_feet()
        return self.inverse(feet[:, 1], feet[:, 2])

    def forward(self, knee, ankle):
        """Foot tip positions (N, 3) m in base_link for knee and ankle angles (N,) rad."""
        knee = np.asarray(knee, dtype=float)
        dactyl = knee + np.asarray(ankle, dtype=float) - self.dactyl_droop
        out = self.mid_length * np.cos(knee) + self.dactyl_length * np.cos(dactyl)
        up = self.mid_length * np.sin(knee) + self.dactyl_length * np.sin(dactyl)
        return self.knee_xyz + np.stack([np.zeros_like(out), self.side * out, up], axis=-1)

    def inverse(self, foot_y, foot_z):
        """Knee and ankle angles (rad, each (N,)) that put each foot tip at sideways position
        foot_y and height foot_z (m, base_link frame, each (N,)); the foot's x is its knee's.

        Closed form (a planar two-link arm in the leg's y-z plane): the knee-to-foot distance
        d fixes the bend between the segments, cos(bend) = (d^2 - L_mid^2 - L_dactyl^2) /
        (2 L_mid L_dactyl), taken negative (the arched branch); the knee angle then turns the
        arm onto the foot. Targets out of reach are clipped to the edge of the workspace;
        see `reachable`.
        """
        foot_y, foot_z = np.broadcast_arrays(np.asarray(foot_y, dtype=float),
                                             np.asarray(foot_z, dtype=float))
        shape, legs = foot_y.shape, len(self.names)
        # (C-ordered copies: a column of feet, or a broadcast, is strided, which the kernel's
        # prebuilt function does not take: numba would compile it for that)
        knee, ankle = prebuilt.kernel(LEG_INVERSE)(
            np.array(foot_y, order='C').reshape(-1, legs),
            np.array(foot_z, order='C').reshape(-1, legs), self.knee_xyz,
            self.side.astype(float), self.mid_length, self.dactyl_length, self.dactyl_droop)
        return knee.reshape(shape), ankle.reshape(shape)

    def reachable(self, foot_y, foot_z):
        """(N,) bool: can `inverse` place each foot exactly at (foot_y, foot_z), and are the
        joint angles it returns within knee_range and ankle_range (to 1e-9 rad)?"""
        out = self.side * (np.asarray(foot_y, dtype=float) - self.knee_xyz[:, 1])
        reach = np.hypot(out, np.asarray(foot_z, dtype=float) - self.knee_xyz[:, 2])
        knee, ankle = self.inverse(foot_y, foot_z)
        tol = 1e-9
        return ((reach <= self.mid_length + self.dactyl_length)
                & (reach >= abs(self.mid_length - self.dactyl_length))
                & (self.knee_range[0] - tol <= knee) & (knee <= self.knee_range[1] + tol)
                & (self.ankle_range[0] - tol <= ankle) & (ankle <= self.ankle_range[1] + tol))
