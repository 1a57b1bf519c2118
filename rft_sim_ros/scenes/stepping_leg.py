"""A 3-DOF leg (coxa yaw, femur pitch, tibia pitch) and the stepping path it traces
(models/rail_leg.xml, scene articulated_leg). Pure numpy.

Frame: the leg's base frame has its origin on the coxa (yaw) axis at the height of the femur
axis, +x forward (along the rail), +y outward (the leg's direction at yaw 0), +z up. SI units.
Joint angles, all zero = femur horizontal straight out, tibia pointing straight down:
- coxa  (axis -z): > 0 swings the foot forward (+x);
- femur (axis along the femur's forward horizontal): > 0 lifts the femur;
- tibia (same axis): > 0 swings the tibia's lower end outward.
The foot point is the lower end of the tibia (the bottom of the scoop).
"""
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class LegGeometry:
    """Link lengths, m: coxa (yaw axis to femur axis, horizontal), femur (femur axis to tibia
    axis), tibia (tibia axis to the foot point)."""
    coxa: float = 0.03
    femur: float = 0.08
    tibia: float = 0.10

    def forward(self, angles):
        """Foot points (..., 3) m in the leg base frame for joint angles (..., 3) rad
        (coxa, femur, tibia)."""
        q = np.asarray(angles, dtype=float)
        yaw, q1, q12 = q[..., 0], q[..., 1], q[..., 1] + q[..., 2]
        reach = self.coxa + self.femur * np.cos(q1) + self.tibia * np.sin(q12)
        height = self.femur * np.sin(q1) - self.tibia * np.cos(q12)
        return np.stack([reach * np.sin(yaw), reach * np.cos(yaw), height], axis=-1)

    def inverse(self, points):
        """Joint angles (..., 3) rad (coxa, femur, tibia) that put the foot at `points`
        (..., 3) m, knee above the femur-foot line. Raises ValueError if a point is out of
        reach."""
        p = np.asarray(points, dtype=float)
        yaw = np.arctan2(p[..., 0], p[..., 1])
        reach = np.hypot(p[..., 0], p[..., 1]) - self.coxa
        cos_knee = ((reach ** 2 + p[..., 2] ** 2 - self.femur ** 2 - self.tibia ** 2)
                    / (2 * self.femur * self.tibia))
        if np.any(np.abs(cos_knee) > 1.0):
            raise ValueError('stepping path leaves the reach of the leg')
        knee = -np.arccos(cos_knee)  # angle from the femur to the tibia-as-a-link, < 0
        femur = np.arctan2(p[..., 2], reach) - np.arctan2(
            self.tibia * np.sin(knee), self.femur + self.tibia * np.cos(knee))
        return np.stack([yaw, femur, knee + np.pi / 2], axis=-1)


def _smoothstep(u):
    u = np.clip(u, 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


@dataclass(frozen=True)
class SteppingPath:
    """The foot's closed 3D path of one step, in the leg base frame (m, s).

    One step of `period` s, phases in order: plunge (straight down from `lift_z` to
    `stance_z`, fraction `plunge_fraction`), stance (straight back along -x from
    +stroke/2 to -stroke/2 at y = `reach`, fraction `stance_fraction`), lift (straight up,
    fraction `plunge_fraction`), return (forward above the sand with an outward excursion
    of `abduction` m mid-way: the 3D part, for the rest of the period). Every segment
    follows a smoothstep, so the foot starts and stops each one at rest.
    """
    stroke: float
    reach: float
    stance_z: float
    lift_z: float
    abduction: float
    period: float
    stance_fraction: float = 0.6
    plunge_fraction: float = 0.1

    def __post_init__(self):
        if not (self.stroke > 0 and self.period > 0 and self.lift_z > self.stance_z):
            raise ValueError('need stroke > 0, period > 0 and lift_z above stance_z')
        if not (0 < self.stance_fraction and 0 < self.plunge_fraction
                and self.stance_fraction + 2 * self.plunge_fraction < 1):
            raise ValueError('stance_fraction + 2 plunge_fraction must be in (0, 1)')

    def foot(self, t):
        """Foot points (n, 3) m at times t (n,) s; phase 0 = start of the plunge."""
        phase = np.mod(np.asarray(t, dtype=float) / self.period, 1.0)
        p, s = self.plunge_fraction, self.stance_fraction
        half = self.stroke / 2
        x = np.full_like(phase, half)
        y = np.full_like(phase, self.reach)
        z = np.full_like(phase, self.stance_z)
        plunge = phase < p
        z[plunge] = self.lift_z + (self.stance_z - self.lift_z) * _smoothstep(phase[plunge] / p)
        stance = (phase >= p) & (phase < p + s)
        x[stance] = half - self.stroke * _smoothstep((phase[stance] - p) / s)
        lift = (phase >= p + s) & (phase < 2 * p + s)
        x[lift] = -half
        z[lift] = self.stance_z + (self.lift_z - self.stance_z) * _smoothstep(
            (phase[lift] - p - s) / p)
        back = phase >= 2 * p + s
        u = (phase[back] - 2 * p - s) / (1 - 2 * p - s)
        x[back] = -half + self.stroke * _smoothstep(u)
        y[back] = self.reach + self.abduction * np.sin(np.pi * u) ** 2
        z[back] = self.lift_z
        return np.stack([x, y, z], axis=-1)
