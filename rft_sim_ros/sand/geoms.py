"""Plates for a MuJoCo body, made from what touches the sand: its collision geoms (contype or
conaffinity nonzero, MuJoCo's own test of whether a geom can collide; the group numbers vary
between model sources), or all its geoms when it has none. No sites in the XML, no hand
remeshing.

Each geom (sphere, capsule, cylinder, box, ellipsoid, mesh) is tessellated with trimesh at a
target edge length, refined so that no edge is longer, and expressed in the body frame (the
frame of mjData.xpos / xmat). Plates whose centroid lies inside another geom of the same body
are dropped, so overlapping geoms contribute their outer surface only. A body given by
contact points only (separate small spheres, `contact_spheres`) carries plates on their
convex hull, the sole the points mark. A target plate count
per body is met by searching the edge length; a target density (plates/mm^2) sets it directly.
A mesh far finer than its share of the count is first simplified (quadric decimation,
trimesh with fast_simplification), so the count asked is the count made. Plates of an
unchanged body are cached on disk (`plate_cache_dir`; key: the geometry and the count).
"""
import hashlib
import os

import mujoco
import numpy as np

from ..resources import user_cache_dir
from ..rft.plates import Plates, edge_for_plate_area, refine, top_up

_INSIDE_MARGIN = 1e-7  # m; centroids closer than this to another geom's surface are kept


def _geom_rotation(model, geom_id):
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, model.geom_quat[geom_id])
    return rotation.reshape(3, 3)


def geom_mesh(model, geom_id, edge, mesh=None):
    """Surface of geom `geom_id` as a trimesh in the geom's own frame, edges <= `edge` (m).

    Primitives start from a coarse tessellation that is refined by edge bisection; the new
    vertices are then put back on the exact curved surface, so area and normals converge at
    second order in the plate size. Mesh geoms are refined as given, or from `mesh` (their
    simplified surface, `simplified_meshes`).
    """
    import trimesh  # (here: ~0.5 s to import, and runs with cached plates never need it)
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
        mesh = mesh if mesh is not None else model_mesh(model, geom_id)
        project = None
    else:
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, geom_id) or f'#{geom_id}'
        raise ValueError(f'geom {name}: type {kind.name} cannot carry RFT '
                         'plates (use sphere, capsule, cylinder, box, ellipsoid or mesh)')
    mesh = refine(mesh, edge)
    if project is not None:
        mesh.vertices = project(np.asarray(mesh.vertices))
    return mesh


def model_mesh(model, geom_id):
    """The mesh of mesh geom `geom_id` as MuJoCo compiled it (geom frame), a trimesh."""
    import trimesh
    mesh_id = model.geom_dataid[geom_id]
    v0, nv = model.mesh_vertadr[mesh_id], model.mesh_vertnum[mesh_id]
    f0, nf = model.mesh_faceadr[mesh_id], model.mesh_facenum[mesh_id]
    return trimesh.Trimesh(vertices=model.mesh_vert[v0:v0 + nv].copy(),
                           faces=model.mesh_face[f0:f0 + nf].copy(), process=True)


def mesh_vertices(model, geom_id):
    """(V, 3) vertices (m, geom frame) of mesh geom `geom_id`: those of the convex hull
    MuJoCo made of it (what it collides), else all of its mesh's."""
    mesh = model.geom_dataid[geom_id]
    start = model.mesh_vertadr[mesh]
    vertices = model.mesh_vert[start:start + model.mesh_vertnum[mesh]]
    graph = model.mesh_graphadr[mesh]
    if graph < 0:
        return vertices
    count = model.mesh_graph[graph]
    return vertices[model.mesh_graph[graph + 2 + count:graph + 2 + 2 * count]]


#: Directions (unit vectors, the 42 vertices of a once-subdivided icosahedron, about 30 deg
#: apart) in which a mesh geom's outline takes its extreme points (`collided_outline`).
_OUTLINE_SUBDIVISIONS = 1


def collided_outline(model, geom_id):
    """Mesh geom `geom_id`'s convex outline, a trimesh (geom frame): the convex hull of the
    vertices MuJoCo collides (`mesh_vertices`) that lie farthest in each of 42 directions,
    at most 80 triangles. It touches the collided hull at its extreme points, so wherever
    the body lies its lowest point is on the outline or within a few per cent of its size
    below it, where a vendor's link mesh decimated to a few dozen triangles shrank inward by
    up to 11 cm (Unitree G1's shoulder). A flat or degenerate mesh: its mesh as given."""
    import trimesh
    vertices = np.asarray(mesh_vertices(model, geom_id), dtype=float)
    directions = trimesh.creation.icosphere(subdivisions=_OUTLINE_SUBDIVISIONS).vertices
    extreme = vertices[np.unique(np.argmax(vertices @ directions.T, axis=0))]
    try:
        outline = trimesh.convex.convex_hull(extreme)
    except Exception:  # (qhull: coplanar or too few points)
        return model_mesh(model, geom_id)
    return outline if outline.area > 0 else model_mesh(model, geom_id)


def collided_outlines(model, body_id):
    """{geom id: `collided_outline`} of the mesh geoms of body `body_id`."""
    return {g: collided_outline(model, g) for g in body_geoms(model, body_id)
            if int(model.geom_type[g]) == mujoco.mjtGeom.mjGEOM_MESH}


def _hull_planes(model, geom_id):
    """(outward unit normals (F, 3), offsets (F,)) of the convex hull MuJoCo made for mesh geom
    `geom_id` (geom frame): a point p is inside when normals @ p < offsets everywhere."""
    mesh_id = model.geom_dataid[geom_id]
    v0, nv = model.mesh_vertadr[mesh_id], model.mesh_vertnum[mesh_id]
    vertices = model.mesh_vert[v0:v0 + nv]
    graph = model.mesh_graph[model.mesh_graphadr[mesh_id]:]
    numvert, numface = graph[0], graph[1]
    faces = graph[2 + 3 * numvert + 3 * numface:][:3 * numface].reshape(-1, 3)
    corners = vertices[faces]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    offsets = np.einsum('fk,fk->f', normals, corners[:, 0])
    inward = offsets < normals @ vertices.mean(axis=0)  # orient every face outward
    normals[inward], offsets[inward] = -normals[inward], -offsets[inward]
    return normals, offsets


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
        if model.mesh_graphadr[model.geom_dataid[geom_id]] < 0:  # no hull made: hide nothing
            return np.zeros(len(points_in_body), dtype=bool)
        normals, offsets = _hull_planes(model, geom_id)
        return np.all(local @ normals.T < offsets - _INSIDE_MARGIN, axis=1)
    return np.zeros(len(points_in_body), dtype=bool)


#: conaffinity bit that marks a geom as its body's sand surface: visual geoms that carry
#: plates (`robot.sand_bodies.keep_sand_visuals`). No geom has it in contype, so nothing
#: collides with them, but MuJoCo's discardvisual, which drops geoms with contype =
#: conaffinity = 0, keeps them.
SAND_SURFACE_BIT = 1 << 30


def is_sand_surface_geom(model, geom_id):
    """Whether geom `geom_id` is marked as its body's sand surface (SAND_SURFACE_BIT only)."""
    return (model.geom_contype[geom_id] == 0
            and model.geom_conaffinity[geom_id] == SAND_SURFACE_BIT)


def is_collision_geom(model, geom_id):
    """Whether MuJoCo may collide geom `geom_id` (contype or conaffinity nonzero)."""
    return bool(model.geom_contype[geom_id] or model.geom_conaffinity[geom_id])


def moving_collision_geoms(model):
    """Ids of the collision geoms (`is_collision_geom`) of the moving bodies of `model`
    (those not welded to the world)."""
    return [g for g in range(model.ngeom) if model.body_weldid[model.geom_bodyid[g]] != 0
            and is_collision_geom(model, g)]


def bodies_without_collision(model):
    """Ids of the moving bodies of `model` (each the top body of its weld group, those
    welded to it standing in for it; mocap bodies left out) welded to no collision geom: the
    model gives them none, or only visual geoms, so nothing but their origin tells where
    they are, and they pass through the sand."""
    held = {int(model.body_weldid[model.geom_bodyid[g]]) for g in moving_collision_geoms(model)}
    return [b for b in range(1, model.nbody)
            if model.body_weldid[b] == b and b not in held and model.body_mocapid[b] < 0]


def body_geoms(model, body_id):
    """Ids of the geoms that carry the plates of body `body_id`: those marked as its sand
    surface (`is_sand_surface_geom`), else its collision geoms, else all its geoms; a copy
    of an earlier one (`same_geom`: a visual twin left
    colliding, common in vendors' models) is left out, since twin surfaces would carry
    plates twice, or, for meshes, hide each other (`body_triangles`)."""
    start, count = model.body_geomadr[body_id], model.body_geomnum[body_id]
    geoms = list(range(start, start + count)) if start >= 0 else []
    geoms = ([g for g in geoms if is_sand_surface_geom(model, g)]
             or [g for g in geoms if is_collision_geom(model, g)] or geoms)
    kept = []
    for g in geoms:
        if not any(same_geom(model, g, other) for other in kept):
            kept.append(g)
    return kept


def same_geom(model, a, b):
    """Whether geoms a and b have the same surface: type, mesh, size and pose (to 1e-9 m)."""
    qa, qb = model.geom_quat[a], model.geom_quat[b]
    return bool(model.geom_type[a] == model.geom_type[b]
                and model.geom_dataid[a] == model.geom_dataid[b]
                and np.allclose(model.geom_size[a], model.geom_size[b], rtol=0, atol=1e-9)
                and np.allclose(model.geom_pos[a], model.geom_pos[b], rtol=0, atol=1e-9)
                and abs(abs(float(np.dot(qa, qb))) - 1.0) < 1e-12)


def contact_spheres(model, geoms):
    """Whether `geoms` (ids, one body's) are contact points: two or more spheres and nothing
    else, none touching another. Vendors give a foot that way for rigid ground (Unitree's
    G1: four 5 mm spheres at the corners of each sole), where the ground meets the convex
    hull of a body's geoms; sand meets a surface, and 6 cm^2 of spheres bear a 33 kg robot
    only 15 cm deep, so the plates of such a body are made on that hull (the sole they
    mark, `body_triangles`)."""
    spheres = int(mujoco.mjtGeom.mjGEOM_SPHERE)
    if len(geoms) < 2 or any(int(model.geom_type[g]) != spheres for g in geoms):
        return False
    centres = np.array([model.geom_pos[g] for g in geoms])
    radii = np.array([model.geom_size[g, 0] for g in geoms])
    apart = np.linalg.norm(centres[:, None] - centres[None], axis=2) > radii[:, None] + radii
    return bool(apart[~np.eye(len(geoms), dtype=bool)].all())


def _hull_triangles(model, geoms, edge):
    """Triangles ((T, 3, 3), m, body frame, edges <= ~`edge`) of the convex hull of the
    sphere geoms `geoms`: their tessellations' vertices hulled (the caps as fine as the
    spheres'), the flat parts between them refined."""
    import trimesh
    points = np.concatenate([np.asarray(geom_mesh(model, g, edge).vertices) + model.geom_pos[g]
                             for g in geoms])
    return np.asarray(refine(trimesh.convex.convex_hull(points), edge).triangles)


def body_triangles(model, body_id, edge, meshes=None):
    """Surface triangles of body `body_id` ((T, 3, 3), m, body frame) with edges <= ~`edge`:
    its geoms' surfaces without the parts inside another geom of the body, or the convex
    hull of its contact points (`contact_spheres`). meshes: {geom id: simplified trimesh}
    to use for mesh geoms (`simplified_meshes`)."""
    geoms = body_geoms(model, body_id)
    if contact_spheres(model, geoms):
        return _hull_triangles(model, geoms, edge)
    meshes = meshes or {}
    parts = []
    for geom_id in geoms:
        rotation = _geom_rotation(model, geom_id)
        mesh = geom_mesh(model, geom_id, edge, meshes.get(geom_id))
        triangles = np.asarray(mesh.triangles) @ rotation.T + model.geom_pos[geom_id]
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


def simplified_meshes(model, body_id, count):
    """{geom id: trimesh} of the mesh geoms of body `body_id` with more triangles than half
    their share (by area) of `count` plates, decimated to that half share (quadric error
    decimation), so that refinement, not the mesh, sets the plate count."""
    geoms = body_geoms(model, body_id)
    meshes = {g: model_mesh(model, g) for g in geoms
              if int(model.geom_type[g]) == mujoco.mjtGeom.mjGEOM_MESH}
    if not meshes:
        return {}
    areas = {g: geom_mesh(model, g, np.inf, meshes.get(g)).area for g in geoms}
    total = sum(areas.values())
    simplified = {}
    for geom_id, mesh in meshes.items():
        budget = max(8, int(0.5 * count * areas[geom_id] / total))
        if len(mesh.faces) > budget:
            simplified[geom_id] = mesh.simplify_quadric_decimation(face_count=budget)
    return simplified


def plate_cache_dir():
    """Where plates are cached: $XDG_CACHE_HOME/rft_sim_ros/plates (default ~/.cache/...)."""
    return user_cache_dir('plates')


#: Bump when the plate-making changes, so that old cache entries are not used.
_CACHE_VERSION = 2  # (2: contact spheres' hull; outlines)


def _geometry_key(model, body_id, count, density_per_mm2, outline):
    """A hash of everything body_plates reads: the surface geoms' types, sizes, poses and
    meshes, and the count or density and the surface asked."""
    digest = hashlib.sha256(repr((_CACHE_VERSION, count, density_per_mm2, outline)).encode())
    for g in body_geoms(model, body_id):
        for array in (model.geom_type[g:g + 1], model.geom_size[g], model.geom_pos[g],
                      model.geom_quat[g]):
            digest.update(np.ascontiguousarray(array).tobytes())
        if int(model.geom_type[g]) == mujoco.mjtGeom.mjGEOM_MESH:
            mesh_id = model.geom_dataid[g]
            v0, nv = model.mesh_vertadr[mesh_id], model.mesh_vertnum[mesh_id]
            f0, nf = model.mesh_faceadr[mesh_id], model.mesh_facenum[mesh_id]
            digest.update(model.mesh_vert[v0:v0 + nv].tobytes())
            digest.update(model.mesh_face[f0:f0 + nf].tobytes())
    return digest.hexdigest()


def body_plates(model, body_id, count=None, density_per_mm2=None, cache=True, outline=False):
    """Plates of body `body_id` in its body frame, sized by a target count or density.

    count: number of plates on the body. density_per_mm2: plates per mm^2 of surface (the
    paper's unit), i.e. a count of density x area. Give one. The count is met exactly
    (above the coarsest tessellation of the body's geoms): the finest refinement that stays
    within it is found by bisecting the edge length, then its largest triangles are halved.
    outline: mesh geoms carry plates on their convex outline (`collided_outline`, what
    MuJoCo collides, coarsely: the other bodies' plates, there so that nothing passes
    through the sand), not on their mesh as drawn (a foot's shape: the paper's C-legs).
    cache: read and write the plate cache (`plate_cache_dir`).
    """
    if (count is None) == (density_per_mm2 is None):
        raise ValueError('give exactly one of count or density_per_mm2')
    if not body_geoms(model, body_id):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body_id)
        raise ValueError(f'body {name!r} has no geoms to make RFT plates from')
    if count is not None and (isinstance(count, bool)
                              or not isinstance(count, (int, np.integer)) or count < 1):
        raise ValueError(f'plate count must be a positive integer, got {count!r}')
    if density_per_mm2 is not None and not density_per_mm2 > 0:
        raise ValueError(f'plate density must be > 0 plates/mm^2, got {density_per_mm2}')
    key = _geometry_key(model, body_id, count, density_per_mm2, outline)
    path = plate_cache_dir() / f'{key}.npz'
    if cache and path.is_file():
        try:
            with np.load(path) as stored:
                return Plates(stored['centroids'], stored['normals'], stored['areas'])
        except (OSError, KeyError, ValueError):
            pass  # unreadable entry: make the plates again
    plates = _make_plates(model, body_id, count, density_per_mm2, outline)
    if cache:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            partial = path.with_suffix(f'.{os.getpid()}.tmp.npz')
            np.savez(partial, centroids=plates.centroids, normals=plates.normals,
                     areas=plates.areas)
            os.replace(partial, path)
        except OSError:
            pass  # a read-only cache only costs time
    return plates


def _make_plates(model, body_id, count, density_per_mm2, outline):
    meshes = {}
    if outline:
        meshes = collided_outlines(model, body_id)
    elif count is not None:
        meshes = simplified_meshes(model, body_id, count)
    coarsest = body_triangles(model, body_id, np.inf, meshes)
    area = Plates.from_triangles(coarsest).total_area
    if not area > 0:
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body_id)
        raise ValueError(f'body {name!r}: its geoms leave no surface outside one another '
                         'to make RFT plates from (each lies inside another)')
    if density_per_mm2 is not None:
        count = max(1, int(round(density_per_mm2 * area * 1e6)))
        if not outline:
            meshes = simplified_meshes(model, body_id, count)
            coarsest = body_triangles(model, body_id, np.inf, meshes)
    best = coarsest  # the most triangles found that do not exceed `count`
    edge = edge_for_plate_area(area / count)
    fine, coarse = None, None  # edges known to give too many / at most `count` triangles
    for _ in range(14):  # bracket, then bisect in log(edge); counts fall as the edge grows
        triangles = body_triangles(model, body_id, edge, meshes)
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
