"""RFT wrench on a whole rigid body, given its pose and twist (like Treers' rft_3D_body)."""
import numpy as np

from .force_law import plate_forces
from .plates import Plates


def body_wrench(mesh, position, rotation, linear_velocity, angular_velocity, zeta,
                surface_height=0.0, **law_options):
    """Total RFT force (N) and torque (N m, about `position`) on a rigid body in sand.

    mesh: trimesh.Trimesh (or Plates) in the body frame, m; each triangle is one plate.
    position: (3,) m, body-frame origin in the world. rotation: (3, 3) body-to-world matrix.
    linear_velocity: (3,) m/s of the body-frame origin, world axes.
    angular_velocity: (3,) rad/s, world axes. zeta: N/cm^3. surface_height: m.
    law_options: passed to `plate_forces` (normalisation, dynamic).
    Returns (force (3,), torque (3,)), world axes.
    """
    plates = mesh if isinstance(mesh, Plates) else Plates.from_mesh(mesh)
    rotation = np.asarray(rotation, dtype=float).reshape(3, 3)
    position = np.asarray(position, dtype=float)
    lever = plates.centroids @ rotation.T
    velocities = np.asarray(linear_velocity, float) + np.cross(
        np.asarray(angular_velocity, float), lever)
    forces = plate_forces(lever + position, plates.normals @ rotation.T, plates.areas,
                          velocities, zeta, surface_height, **law_options)
    return forces.sum(axis=0), np.cross(lever, forces).sum(axis=0)
