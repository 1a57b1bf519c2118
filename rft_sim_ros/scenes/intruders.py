"""Procedural intruder geometry for the rail scenes (no CAD files): added to an MjSpec body.

Shapes, all `width` wide along the body's y axis and `thickness` thick (m):
- flat: a rectangular plate from the body origin (the servo axle) along +x to x = `length`.
- c:    a C-shaped (half-annulus) leg whose centre line is a semicircle of diameter `length`
        from the body origin to the tip at (length, 0, 0), bulging towards -z by length / 2.
        Driven about +y by a positive angle, a point of the leg moves towards its own -z,
        so the bulge (the convex side) leads: a "closed C". Driven the other way the hollow
        leads: an "open C" (the same leg, rotated in the opposite direction).
The farthest point from the axle is the tip, `length` away, for both shapes.

`arc_mesh` also makes the articulated leg's scoop (a half-cylinder shell).
"""
import mujoco
import numpy as np

SHAPES = ('flat', 'c')


def arc_mesh(diameter, width, thickness, segments=48):
    """Vertices (V, 3) and triangles (F, 3) of a closed half-annulus shell, metres.

    Centre line: semicircle in the x-z plane from (0, 0, 0) to (diameter, 0, 0) through
    (diameter / 2, 0, -diameter / 2); cross-section `thickness` radially by `width` along y,
    centred on the line. Triangles wind counter-clockwise seen from outside (outward normals).
    """
    radius = diameter / 2.0
    phi = np.linspace(0.0, np.pi, segments + 1)         # 0: tip, pi: axle end
    rings = []
    for rho, y in ((radius + thickness / 2, -width / 2), (radius + thickness / 2, width / 2),
                   (radius - thickness / 2, width / 2), (radius - thickness / 2, -width / 2)):
        rings.append(np.stack([radius + rho * np.cos(phi), np.full_like(phi, y),
                               -rho * np.sin(phi)], axis=-1))
    vertices = np.stack(rings, axis=1).reshape(-1, 3)   # (segments + 1) sections x 4 corners
    faces = []
    for i in range(segments):
        for c in range(4):
            a, b = 4 * i + c, 4 * i + (c + 1) % 4
            faces += [(a, b + 4, b), (a, a + 4, b + 4)]
    last = 4 * segments
    faces += [(0, 1, 2), (0, 2, 3), (last, last + 2, last + 1), (last, last + 3, last + 2)]
    return vertices, np.array(faces, dtype=np.int64)


def add_intruder(spec, body, shape, length, width, thickness, mass, name='intruder'):
    """Add the intruder geom (see module docstring) to `body` (an MjsBody of `spec`).

    length, width, thickness: m; mass: kg. Returns the new MjsGeom. Raises ValueError for an
    unknown shape or a thickness that does not fit the shape.
    """
    if shape not in SHAPES:
        raise ValueError(f'shape must be one of {SHAPES}, got {shape!r}')
    if not 0.0 < thickness < (length if shape == 'flat' else length / 2):
        raise ValueError(f'thickness {thickness} m does not fit a {shape} intruder of '
                         f'length {length} m')
    geom = body.add_geom()
    geom.name = name
    geom.mass = mass
    geom.contype = geom.conaffinity = 0
    geom.rgba = [0.85, 0.45, 0.15, 1.0]
    if shape == 'flat':
        geom.type = mujoco.mjtGeom.mjGEOM_BOX
        geom.size = [length / 2, width / 2, thickness / 2]
        geom.pos = [length / 2, 0.0, 0.0]
        return geom
    add_arc_mesh(spec, f'{name}_mesh', length, width, thickness)
    geom.type = mujoco.mjtGeom.mjGEOM_MESH
    geom.meshname = f'{name}_mesh'
    return geom


def add_arc_mesh(spec, name, diameter, width, thickness):
    """Add `arc_mesh(diameter, width, thickness)` to `spec` as mesh `name` (exact inertia)."""
    vertices, faces = arc_mesh(diameter, width, thickness)
    mesh = spec.add_mesh()
    mesh.name = name
    mesh.uservert = vertices.ravel().tolist()
    mesh.userface = faces.ravel().tolist()
    mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_EXACT
    return mesh
