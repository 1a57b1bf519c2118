"""Plates for a MuJoCo body, made from its geoms (no sites in the XML, no hand remeshing).

Each geom (sphere, capsule, cylinder, box, ellipsoid, mesh) is tessellated with trimesh at a
target edge length, refined so that no edge is longer, and expressed in the body frame (the
frame of mjData.xpos / xmat). Plates whose centroid lies inside another geom of the same body
are dropped, so overlapping geoms contribute their outer surface only. A target plate count
per body is met by searching the edge length; a target density (plates/mm^2) sets it directly.
"""
import mujoco
import numpy as np
import trimesh

from ..rft.plates import Plates, edge_for_plate_area, refine, top_up

_INSIDE_MARGIN = 1e-7  # m; centroids closer than this to another geom's surface are kept


def _geom_rotation(model, geom_id):
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, model.geom_quat[geom_id])
    return rotation.reshape(3, 3)


def geom_mesh(model, geom_id, edge):
    """Surface of geom `geom_id` as a trimesh in the geom's own frame, edges <= `edge` (m).

    Primitives start from a coarse tessellation that is refined by edge bisection; the new
    vertices are then put back on the exact curved surface, so area and normals converge at
    second order in the plate size. Mesh geoms are refined as given.
    """
    kind = mujoco.mjtGeom(int(model.geom_type[geom_id]))
    size = model.geom_size[geom_id]
    if kind in (mujoco.mjtGeom.mjGEOM_SPHERE, mujoco.mjtGeom.mjGEOM_ELLIPSOID):
        radii = np.full(3, size[0]) if kind == mujoco.mjtGeom.mjGEOM_SPHERE else size[:3]
        mesh = trimesh.creation.icosphere(subdivisions=1, radius=1.0)
        mesh.apply_scale(radii)
        project = lambda v: v / np.linalg.norm(v / radii, axis=1)[:, None]  # noqa: E731
    elif kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
        radius, half = size[0], size[1]
        mesh = trimesh.creation.capsule(height=2 * half, radius=radius, count=[6, 12])
        project = lambda v: _onto_capsule(v, radius, half)  # noqa: E731
    elif kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
        radius, half = size[0], size[1]
        # caps stay flat, so their rim polygon must already be fine: one section per edge
        sections = max(12, int(np.ceil(2 * np.pi * radius / min(edge, 1e3 * radius))))
        mesh = trimesh.creation.cylinder(radius=radius, height=2 * half, sections=sections)
        project = lambda v: _onto_cylinder_side(v, radius, half)  # noqa: E731
    elif kind == mujoco.mjtGeom.mjGEOM_BOX:
        mesh = trimesh.creation.box(extents=2 * size[:3])
        project = None
    elif kind == mujoco.mjtGeom.mjGEOM_MESH:
        mesh_id = model.geom_dataid[geom_id]
        v0, nv = model.mesh_vertadr[mesh_id], model.mesh_vertnum[mesh_id]
        f0, nf = model.mesh_faceadr[mesh_id], model.mesh_facenum[mesh_id]
        mesh = trimesh.Trimesh(vertices=model.mesh_vert[v0:v0 + nv].copy(),
                               faces=model.mesh_face[f0:f0 + nf].copy(), process=True)
        project = None
    else:
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, geom_id) or f'#{geom_id}'
        raise ValueError(f'geom {name}: type {kind.name} cannot carry RFT '
                         'plates (use sphere, capsule, cylinder, box, ellipsoid or mesh)')
    mesh = refine(mesh, edge)
    if project is not None:
        mesh.vertices = project(np.asarray(mesh.vertices))
    return mesh


def _onto_capsule(vertices, radius, half):
    axial = np.clip(vertices[:, 2], -half, half)
    radial = vertices - np.outer(axial, [0.0, 0.0, 1.0])
    return np.outer(axial, [0.0, 0.0, 1.0]) + radius * radial / np.linalg.norm(
        radial, axis=1)[:, None]


def _onto_cylinder_side(vertices, radius, half):
    """Side vertices onto the cylinder; cap vertices (|z| = half) stay on their plane."""
    out = vertices.copy()
    side = np.abs(vertices[:, 2]) < half * (1 - 1e-9)
    rho = np.linalg.norm(vertices[side, :2], axis=1)
    out[side, :2] *= (radius / rho)[:, None]
    return out


def inside_geom(model, geom_id, points_in_body):
    """Mask of points (body frame, m) strictly inside geom `geom_id` of the same body."""
    local = (points_in_body - model.geom_pos[geom_id]) @ _geom_rotation(model, geom_id)
    size = model.geom_size[geom_id]
    kind = mujoco.mjtGeom(int(model.geom_type[geom_id]))
    if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        return np.linalg.norm(local, axis=1) < size[0] - _INSIDE_MARGIN
    if kind == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
        return np.sum((local / size[:3]) ** 2, axis=1) < (1.0 - _INSIDE_MARGIN / max(size)) ** 2
    if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
        axial = np.clip(local[:, 2], -size[1], size[1])
        off_axis = local - np.outer(axial, [0.0, 0.0, 1.0])
        return np.linalg.norm(off_axis, axis=1) < size[0] - _INSIDE_MARGIN
    if kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
        return ((np.abs(local[:, 2]) < size[1] - _INSIDE_MARGIN)
                & (np.linalg.norm(local[:, :2], axis=1) < size[0] - _INSIDE_MARGIN))
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        return np.all(np.abs(local) < size[:3] - _INSIDE_MARGIN, axis=1)
    if kind == mujoco.mjtGeom.mjGEOM_MESH:  # MuJoCo collides meshes as convex hulls
        hull = geom_mesh(model, geom_id, edge=np.inf).convex_hull
        distances = np.einsum('pfk,fk->pf', local[:, None, :] - hull.triangles[None, :, 0, :],
                              hull.face_normals)
        return np.all(distances < -_INSIDE_MARGIN, axis=1)
    return np.zeros(len(points_in_body), dtype=bool)


def body_geoms(model, body_id):
    """Ids of the geoms attached to body `body_id`."""
    start, count = model.body_geomadr[body_id], model.body_geomnum[body_id]
    return list(range(start, start + count)) if start >= 0 else []


def body_triangles(model, body_id, edge):
    """Surface triangles of body `body_id` ((T, 3, 3), m, body frame) with edges <= ~`edge`:
    its geoms' surfaces without the parts inside another geom of the body."""
    geoms = body_geoms(model, body_id)
    parts = []
    for geom_id in geoms:
        rotation = _geom_rotation(model, geom_id)
        triangles = (np.asarray(geom_mesh(model, geom_id, edge).triangles) @ rotation.T
                     + model.geom_pos[geom_id])
        centroids = triangles.mean(axis=1)
        hidden = np.zeros(len(triangles), dtype=bool)
        for other in geoms:
            if other != geom_id:
                hidden |= inside_geom(model, other, centroids)
        parts.append(triangles[~hidden])
    return np.concatenate(parts) if parts else np.zeros((0, 3, 3))


def body_plates_at_edge(model, body_id, edge):
    """Plates of body `body_id` (body frame) with triangle edges <= ~`edge` (m)."""
    return Plates.from_triangles(body_triangles(model, body_id, edge))


def body_plates(model, body_id, count=None, density_per_mm2=None):
    """Plates of body `body_id` in its body frame, sized by a target count or density.

    count: number of plates on the body. density_per_mm2: plates per mm^2 of surface (the
    paper's unit), i.e. a count of density x area. Give one. The count is met exactly
    (above the coarsest tessellation of the body's geoms): the finest refinement that stays
    within it is found by bisecting the edge length, then its largest triangles are halved.
    """
    if (count is None) == (density_per_mm2 is None):
        raise ValueError('give exactly one of count or density_per_mm2')
    if not body_geoms(model, body_id):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body_id)
        raise ValueError(f'body {name!r} has no geoms to make RFT plates from')
    coarsest = body_triangles(model, body_id, np.inf)
    area = Plates.from_triangles(coarsest).total_area
    if density_per_mm2 is not None:
        if not density_per_mm2 > 0:
            raise ValueError(f'plate density must be > 0 plates/mm^2, got {density_per_mm2}')
        count = max(1, int(round(density_per_mm2 * area * 1e6)))
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
        raise ValueError(f'plate count must be a positive integer, got {count!r}')
    best = coarsest  # the most triangles found that do not exceed `count`
    edge = edge_for_plate_area(area / count)
    fine, coarse = None, None  # edges known to give too many / at most `count` triangles
    for _ in range(14):  # bracket, then bisect in log(edge); counts fall as the edge grows
        triangles = body_triangles(model, body_id, edge)
        if len(triangles) > count:
            fine = edge
        else:
            coarse = edge
            if len(triangles) > len(best):
                best = triangles
            if len(triangles) == count:
                break
        edge = (np.sqrt(fine * coarse) if fine and coarse
                else edge * (1.5 if coarse is None else 1 / 1.5))
    return Plates.from_triangles(top_up(best, count) if len(best) < count else best)
