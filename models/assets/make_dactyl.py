"""Generate the hexapod's pointed dactyl mesh, models/assets/dactyl.stl.

A straight circular cone, the robot's "crab-like pointed dactyl": base disc of radius
DACTYL_BASE_RADIUS_M at z = 0 (the ankle end), apex at z = -DACTYL_LENGTH_M (the foot tip).
Units: metres, in the mesh's own frame; models/hexapod.xml orients it along the dactyl.

The length is the ankle-axis-to-tip distance of models/hexapod.xml: the tip site sits at
(0.108, 0, -0.015) m from the ankle axis, so the length is hypot(0.108, 0.015) = 0.1090 m.

Run from anywhere:  python models/assets/make_dactyl.py
"""
import math
from pathlib import Path

import trimesh

DACTYL_LENGTH_M = math.hypot(0.108, 0.015)
DACTYL_BASE_RADIUS_M = 0.010
SECTIONS = 24


def dactyl_mesh():
    """The cone as a watertight trimesh.Trimesh: base at z = 0, apex at z = -length (m)."""
    cone = trimesh.creation.cone(radius=DACTYL_BASE_RADIUS_M, height=DACTYL_LENGTH_M,
                                 sections=SECTIONS)
    # trimesh puts the base at z = 0 and the apex at z = +height; point it down instead.
    cone.apply_transform(trimesh.transformations.rotation_matrix(math.pi, [1.0, 0.0, 0.0]))
    return cone


if __name__ == '__main__':
    mesh = dactyl_mesh()
    assert mesh.is_watertight and mesh.volume > 0.0
    out = Path(__file__).resolve().parent / 'dactyl.stl'
    mesh.export(out)
    print(f'wrote {out}: {len(mesh.faces)} faces, length {DACTYL_LENGTH_M:.6f} m, '
          f'volume {mesh.volume * 1e6:.3f} cm^3')
