"""Kinematics of sideways-pointing 2-DOF legs: a knee about the vertical axis, then an ankle
about a horizontal axis, as on the RFT-SiM hexapod (models/hexapod.xml).

Pure numpy. Every quantity is in SI units (m, rad) and, unless stated, in the base_link frame
(+x forward, +y left, +z up). Functions take arrays with one entry per leg.

Leg model, with all joint angles zero being the neutral pose:
- the knee axis is vertical through `knee_xyz` (that point is taken at the height of the
  ankle axis; the mid segment is horizontal);
- the mid segment reaches `mid_length` straight outward (+y on a left leg, -y on a right
  leg) from the knee axis to the ankle axis, which is horizontal and perpendicular to it;
- the dactyl tip sits `tip_out` further outward and `tip_down` below the ankle axis at
  ankle = 0, i.e. the dactyl is a segment of length hypot(tip_out, tip_down) tilted
  atan2(tip_out, tip_down) outward from straight down.
Signs, the same on both sides: knee > 0 swings the foot forward (+x); ankle > 0 swings the
dactyl outward and up (lifts the foot).

With two joints only the fore-aft position x and the height z of the foot can be chosen;
its sideways position follows from them (the foot moves on an arc around the knee axis).
"""
from dataclasses import dataclass
from typing import Tuple

import numpy as np
from numba import njit

from ..kernel_cache import forget_stale


@njit(cache=True)
def leg_inverse(foot_x, foot_z, knee_xyz, mid_length, dactyl_length, dactyl_neutral_angle):
    """`LateralLegs.inverse` for (M, N) foot targets (m; N legs): knee, ankle angles (rad)."""
    knee = np.empty(foot_x.shape)
    ankle = np.empty(foot_x.shape)
    for m in range(foot_x.shape[0]):
        for i in range(foot_x.shape[1]):
            ratio = min(max((knee_xyz[i, 2] - foot_z[m, i]) / dactyl_length, -1.0), 1.0)
            theta = np.arccos(ratio)
            reach = mid_length + dactyl_length * np.sin(theta)
            knee[m, i] = np.arcsin(min(max((foot_x[m, i] - knee_xyz[i, 0]) / reach, -1.0), 1.0))
            ankle[m, i] = theta - dactyl_neutral_angle
    return knee, ankle


@dataclass(frozen=True, eq=False)
class LateralLegs:
    """Geometry and joint ranges of a set of knee-ankle legs (see the module docstring).

    names:        leg names, e.g. ('L1', ..., 'R3').
    knee_xyz:     (N, 3) m, point on each knee axis at ankle-axis height, base_link frame.
    side:         (N,) +1 for a leg pointing to +y (left), -1 for one pointing to -y (right).
    mid_length:   m, knee axis to ankle axis (horizontal).
    tip_out, tip_down: m, dactyl tip relative to the ankle axis at ankle = 0
                  (outward along the leg, and downward).
    knee_range, ankle_range: (min, max) rad, joint limits as in the MuJoCo model.
    """
    names: Tuple[str, ...]
    knee_xyz: np.ndarray
    side: np.ndarray
    mid_length: float
    tip_out: float
    tip_down: float
    knee_range: Tuple[float, float]
    ankle_range: Tuple[float, float]

    @property
    def dactyl_length(self):
        """Ankle axis to dactyl tip, m."""
        return float(np.hypot(self.tip_out, self.tip_down))

    @property
    def dactyl_neutral_angle(self):
        """Dactyl tilt outward from straight down at ankle = 0, rad."""
        return float(np.arctan2(self.tip_out, self.tip_down))

    def neutral_feet(self):
        """(N, 3) m: foot tip positions with all joints at zero, base_link frame."""
        return self.forward(np.zeros(len(self.names)), np.zeros(len(self.names)))

    def forward(self, knee, ankle):
        """Foot tip positions (N, 3) m in base_link for knee and ankle angles (N,) rad."""
        theta = self.dactyl_neutral_angle + np.asarray(ankle, dtype=float)
        knee = np.asarray(knee, dtype=float)
        reach = self.mid_length + self.dactyl_length * np.sin(theta)
        offset = np.stack([reach * np.sin(knee),
                           self.side * reach * np.cos(knee),
                           -self.dactyl_length * np.cos(theta)], axis=-1)
        return self.knee_xyz + offset

    def inverse(self, foot_x, foot_z):
        """Knee and ankle angles (rad, each (N,)) that put each foot tip at fore-aft position
        foot_x and height foot_z (m, base_link frame, each (N,)).

        Closed form: the foot height fixes the dactyl angle from the vertical,
        theta = arccos((z_knee - z) / L_dactyl) (the branch with the tip outward of the ankle),
        hence the horizontal reach rho = L_mid + L_dactyl sin(theta) from the knee axis; the
        knee angle then puts the foot at x: q_knee = arcsin((x - x_knee) / rho).
        Targets out of reach are clipped to the edge of the workspace; see `reachable`.
        """
        foot_x, foot_z = np.asarray(foot_x, dtype=float), np.asarray(foot_z, dtype=float)
        if foot_x.shape != foot_z.shape:
            foot_x, foot_z = np.broadcast_arrays(foot_x, foot_z)
        shape = foot_x.shape
        knee, ankle = leg_inverse(foot_x.reshape(-1, len(self.names)),
                               foot_z.reshape(-1, len(self.names)), self.knee_xyz,
                               self.mid_length, self.dactyl_length, self.dactyl_neutral_angle)
        return knee.reshape(shape), ankle.reshape(shape)

    def reachable(self, foot_x, foot_z):
        """(N,) bool: can `inverse` place each foot exactly at (foot_x, foot_z), and are the
        joint angles it returns within knee_range and ankle_range (to 1e-9 rad)?"""
        ratio = self._drop_ratio(foot_z)
        theta = np.arccos(np.clip(ratio, -1.0, 1.0))
        reach = self.mid_length + self.dactyl_length * np.sin(theta)
        sweep = (np.asarray(foot_x) - self.knee_xyz[:, 0]) / reach
        knee, ankle = self.inverse(foot_x, foot_z)
        tol = 1e-9
        return ((np.abs(ratio) <= 1.0) & (np.abs(sweep) <= 1.0)
                & (self.knee_range[0] - tol <= knee) & (knee <= self.knee_range[1] + tol)
                & (self.ankle_range[0] - tol <= ankle) & (ankle <= self.ankle_range[1] + tol))

    def _drop_ratio(self, foot_z):
        """cos(theta): depth of the foot below the ankle axis over the dactyl length."""
        return (self.knee_xyz[:, 2] - np.asarray(foot_z, dtype=float)) / self.dactyl_length


forget_stale(globals())  # (kernel_cache: drops kernels compiled from older sources)
