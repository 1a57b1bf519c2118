"""Whether a robot's sand bodies can carry it: the depth at which their plates facing down
bear its weight, against how far down they reach. RFT's force on a horizontal plate pushed
straight down is zeta A z (RFT-SiM's 3D RFT at beta = 0, gamma = -90 deg), so a robot of
mass m standing on sand bodies whose plates face down with area A (projected) sinks about

    z = m g / (zeta A).

Where z exceeds every sand body's own height (its plates' vertical extent), the sand bodies
go under and the robot sinks until bodies that the sand does not hold (shins, a trunk) meet
the surface and pass through it: a model whose feet collide as a few small spheres, made for
rigid ground. An estimate for a notice (curved or tilted soles bear less), not a law."""
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Bearing:
    """area_m2: the sand bodies' plate area facing down (projected on the horizontal);
    depth_m: the depth that bears the weight (inf with no area facing down); reach_m: the
    tallest sand body's plates' vertical extent."""
    area_m2: float
    depth_m: float
    reach_m: float

    @property
    def sinks(self):
        """Whether the weight needs more depth than any sand body has."""
        return self.depth_m > self.reach_m


def bearing(mass, gravity, zeta_si, rotations, plates):
    """`Bearing` of a robot of `mass` (kg) under `gravity` (m/s^2, world (3,)) on sand of
    stiffness zeta_si (N/m^3), its sand bodies' plates given as (normals (K, 3), centroids
    (K, 3), areas (K,)) in each body's frame, one per body, with the bodies' world
    rotations (3, 3) in the current pose."""
    down, reach = 0.0, 0.0
    for rotation, (normals, centroids, areas) in zip(rotations, plates):
        down += float(areas @ np.maximum(-(normals @ rotation[2]), 0.0))
        if len(areas):
            reach = max(reach, float(np.ptp(centroids @ rotation[2])))
    weight = mass * float(np.linalg.norm(gravity))
    depth = weight / (zeta_si * down) if down > 0 else float('inf')
    return Bearing(down, depth, reach)
