"""The granular RFT force law and plate geometry (numpy; no MuJoCo, no ROS).

Public entry points:
  plate_forces(positions, normals, areas, velocities, zeta, surface_height=0.0, ...)
  body_wrench(mesh, position, rotation, linear_velocity, angular_velocity, zeta, ...)
  Plates, refine: plate sets from meshes.
"""
from .body import body_wrench
from .coefficients import NORMALISATIONS, alpha_x, alpha_z
from .force_law import DynamicTerm, plate_forces
from .plates import Plates, refine

__all__ = ['plate_forces', 'body_wrench', 'Plates', 'refine', 'DynamicTerm',
           'alpha_x', 'alpha_z', 'NORMALISATIONS']
