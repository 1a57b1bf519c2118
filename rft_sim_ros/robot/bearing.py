"""Whether a robot's sand bodies can carry it: the depth at which their plates facing down
bear its weight, against how far its other bodies clear them. RFT's force on a horizontal
plate pushed straight down is zeta A z (RFT-SiM's 3D RFT at beta = 0, gamma = -90 deg), so a
robot of mass m standing on sand bodies whose plates face down with area A (projected)
sinks about

    z = m g / (zeta A).

Where z exceeds the clearance of the robot's other bodies (the lowest point of their geoms
above the sand bodies' lowest plate), those bodies go into the sand, which does not hold
them, and pass through its surface: a model whose feet collide as a few small spheres, made
for rigid ground, sinks to its shins. An estimate for a notice (curved or tilted soles
bear less, and a body dropped from touching stops at twice it: m g z = zeta A z^2 / 2), not
a law."""
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Bearing:
    """area_m2: the sand bodies' plate area facing down (projected on the horizontal);
    depth_m: the depth that bears the weight (inf with no area facing down); clearance_m:
    how far the robot's other bodies clear the sand bodies' lowest plate (inf: none)."""
    area_m2: float
    depth_m: float
    clearance_m: float

    @property
    def sinks(self):
        """Whether the weight is borne only with the robot's other bodies in the sand."""
        return self.depth_m > self.clearance_m


def bearing(mass, gravity, zeta_si, poses, plates, others_lowest=float('inf')):
    """`Bearing` of a robot of `mass` (kg) under `gravity` (m/s^2, world (3,)) on sand of
    stiffness zeta_si (N/m^3). Its sand bodies: `poses`, their world (position (3,) m,
    rotation (3, 3)) in the current pose, and `plates`, their (normals (K, 3), centroids
    (K, 3) m, areas (K,) m^2) in each body's frame; others_lowest: world z (m) of the
    lowest point of its other bodies' geoms (inf: it has none)."""
    down, lowest = 0.0, float('inf')
    for (position, rotation), (normals, centroids, areas) in zip(poses, plates):
        down += float(areas @ np.maximum(-(normals @ rotation[2]), 0.0))
        if len(areas):
            lowest = min(lowest, float(position[2] + (centroids @ rotation[2]).min()))
    weight = mass * float(np.linalg.norm(gravity))
    depth = weight / (zeta_si * down) if down > 0 else float('inf')
    return Bearing(down, depth, others_lowest - lowest)
