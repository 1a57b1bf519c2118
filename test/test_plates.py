"""Plates made from MuJoCo geoms: geometry, refinement and mesh convergence of the force."""
import mujoco
import numpy as np
import pytest
import trimesh

from rft_sim_ros.rft import Plates, body_wrench, refine
from rft_sim_ros.sand.geoms import (body_geoms, body_plates, body_plates_at_edge, contact_spheres,
                                   mesh_vertices)

GEOMS = """
<mujoco><asset><mesh name="cone" vertex="{cone_vertices}" face="{cone_faces}"/></asset>
<worldbody>
  <body name="sphere"><geom type="sphere" size="0.03"/></body>
  <body name="capsule"><geom type="capsule" size="0.01 0.04" euler="0 30 0"/></body>
  <body name="cylinder"><geom type="cylinder" size="0.02 0.03" pos="0.01 0 0"/></body>
  <body name="box"><geom type="box" size="0.05 0.04 0.005"/></body>
  <body name="ellipsoid"><geom type="ellipsoid" size="0.03 0.02 0.015"/></body>
  <body name="cone"><geom type="mesh" mesh="cone" euler="180 0 0"/></body>
  <body name="union"><geom type="sphere" size="0.02"/><geom type="sphere" pos="0.02 0 0" size="0.02"/></body>
  <body name="plane_body"><geom type="plane" size="1 1 0.1"/></body>
  <body name="twin_boxes"><geom type="box" size="0.05 0.04 0.005"/><geom type="box" size="0.05 0.04 0.005"/></body>
  <body name="twin_cones"><geom type="mesh" mesh="cone" euler="180 0 0"/><geom type="mesh" mesh="cone" euler="180 0 0"/></body>
  <body name="near_twin_cones"><geom type="mesh" mesh="cone"/><geom type="mesh" mesh="cone" pos="1e-6 0 0"/></body>
</worldbody></mujoco>"""

AREAS = {'sphere': 4 * np.pi * 0.03 ** 2,
         'capsule': 2 * np.pi * 0.01 * 0.08 + 4 * np.pi * 0.01 ** 2,
         'cylinder': 2 * np.pi * 0.02 * 0.06 + 2 * np.pi * 0.02 ** 2,
         'box': 2 * (0.1 * 0.08 + 0.1 * 0.01 + 0.08 * 0.01)}


@pytest.fixture(scope='module')
def model():
    cone = trimesh.creation.cone(radius=0.02, height=0.06, sections=64)
    xml = GEOMS.format(cone_vertices=' '.join(map(str, cone.vertices.ravel())),
                       cone_faces=' '.join(map(str, cone.faces.ravel())))
    return mujoco.MjModel.from_xml_string(xml)


@pytest.mark.parametrize('name', sorted(AREAS))
def test_plate_area_converges_to_the_surface_area(model, name):
    plates = body_plates(model, model.body(name).id, count=6000)
    assert plates.total_area == pytest.approx(AREAS[name], rel=5e-3)


@pytest.mark.parametrize('name', ['sphere', 'capsule', 'cylinder', 'box', 'ellipsoid'])
def test_normals_are_unit_and_outward(model, name):
    body = model.body(name).id
    plates = body_plates(model, body, count=800)
    assert np.allclose(np.linalg.norm(plates.normals, axis=1), 1.0)
    geom = model.body_geomadr[body]
    outward = np.einsum('ij,ij->i', plates.centroids - model.geom_pos[geom], plates.normals)
    assert np.all(outward > 0)


def test_overlapping_geoms_keep_only_the_outer_surface(model):
    plates = body_plates(model, model.body('union').id, count=2000)
    to_first = np.linalg.norm(plates.centroids, axis=1)
    to_second = np.linalg.norm(plates.centroids - [0.02, 0, 0], axis=1)
    # every plate lies on one sphere (chord sag < 0.5 mm) and none deep inside the other
    assert np.all(np.minimum(to_first, to_second) > 0.02 - 5e-4)
    exact = 2 * 4 * np.pi * 0.02 ** 2 - 2 * 2 * np.pi * 0.02 * 0.01  # two spheres minus caps
    assert plates.total_area == pytest.approx(exact, rel=0.03)


@pytest.mark.parametrize('twins, single', [('twin_boxes', 'box'), ('twin_cones', 'cone')])
def test_a_geoms_twin_carries_no_plates(model, twins, single):
    """A visual copy of a collision geom left colliding (a vendor's model) must neither
    double the surface (boxes) nor hide it (meshes, simplified inside their twin's hull)."""
    for count in (40, 2000):  # the cone's mesh decimated, then refined
        plates = body_plates(model, model.body(twins).id, count=count, cache=False)
        alone = body_plates(model, model.body(single).id, count=count, cache=False)
        assert len(plates) == count
        assert plates.total_area == pytest.approx(alone.total_area, rel=1e-12)


def test_geoms_that_hide_one_another_are_refused_not_refined_forever(model):
    with pytest.raises(ValueError, match="'near_twin_cones': its geoms leave no surface"):
        body_plates(model, model.body('near_twin_cones').id, count=40, cache=False)


@pytest.mark.parametrize('name', ['capsule', 'union', 'cone'])
@pytest.mark.parametrize('count', [200, 500, 5237])
def test_plate_count_target_is_met_exactly(model, name, count):
    plates = body_plates(model, model.body(name).id, count=count)
    assert len(plates) == count
    if name != 'union':  # a smooth surface: halving plates keeps its area
        coarse = body_plates(model, model.body(name).id, count=count // 4)
        assert plates.total_area == pytest.approx(coarse.total_area, rel=0.02)
    # even plates: none more than 4x the mean area
    assert plates.areas.max() < 4 * plates.areas.mean()


def test_density_target_sets_plate_size(model):
    plates = body_plates(model, model.body('box').id, density_per_mm2=0.03)
    assert len(plates) / (plates.total_area * 1e6) == pytest.approx(0.03, rel=0.01)


def test_unsupported_geom_and_bad_targets_are_refused(model):
    with pytest.raises(ValueError, match='cannot carry RFT plates'):
        body_plates(model, model.body('plane_body').id, count=10)
    with pytest.raises(ValueError, match='exactly one'):
        body_plates(model, model.body('box').id)
    with pytest.raises(ValueError, match='> 0'):
        body_plates(model, model.body('box').id, density_per_mm2=-1.0)


def test_refine_bisects_slivers_into_well_shaped_plates():
    sliver = trimesh.Trimesh(vertices=[[0, 0, 0], [0.1, 0, 0], [0.05, 0.001, 0]],
                             faces=[[0, 1, 2]])
    refined = refine(sliver, 0.005)
    assert refined.area == pytest.approx(sliver.area, rel=1e-12)
    assert refined.edges_unique_length.max() <= 0.005
    assert np.allclose(refined.face_normals, sliver.face_normals[0])
    plates = Plates.from_mesh(refined)
    centroid = (plates.centroids * plates.areas[:, None]).sum(0) / plates.total_area
    assert np.allclose(centroid, sliver.triangles_center[0], atol=1e-12)


@pytest.mark.parametrize('name, position', [('sphere', [0, 0, 0.0123]), ('cylinder', [0, 0, 0.0137]),
                                            ('cone', [0, 0, 0.0071])])
def test_mesh_convergence_of_the_body_force(model, name, position):
    """Force on a partly buried body moving down and sideways: the two finest plate sets
    agree within 2 %."""
    forces = []
    for edge in (0.004, 0.002, 0.001):
        plates = body_plates_at_edge(model, model.body(name).id, edge)
        force, _ = body_wrench(plates, position, np.eye(3), [0.05, 0.02, -0.05], [0, 0, 0], 3.75)
        forces.append(force)
    change = np.linalg.norm(forces[2] - forces[1]) / np.linalg.norm(forces[2])
    assert change < 0.02
    assert np.linalg.norm(forces[2]) > 1.0


CONTACT_POINTS = """
<mujoco><asset><mesh name="link" vertex="{vertices}"/></asset>
<worldbody>
  <body name="points">{spheres}</body>
  <body name="touching"><geom type="sphere" size="0.01"/><geom type="sphere" pos="0.015 0 0" size="0.01"/></body>
  <body name="sphere_and_box"><geom type="sphere" size="0.01" pos="0.1 0 0"/><geom type="box" size="0.02 0.02 0.02"/></body>
  <body name="link"><geom type="mesh" mesh="link" euler="10 20 30"/></body>
</worldbody></mujoco>"""


@pytest.fixture(scope='module')
def contact_model():
    spheres = ''.join(f'<geom type="sphere" size="0.005" pos="{x} {y} -0.03"/>'
                      for x in (-0.05, 0.12) for y in (-0.03, 0.03))
    # a vendor's link: a fine, lumpy, elongated mesh (MuJoCo collides its convex hull)
    ball = trimesh.creation.icosphere(subdivisions=4)
    lumps = 1.0 + 0.1 * np.sin(7 * ball.vertices[:, 0]) * np.cos(5 * ball.vertices[:, 1])
    vertices = ball.vertices * lumps[:, None] * [0.15, 0.04, 0.03]
    return mujoco.MjModel.from_xml_string(CONTACT_POINTS.format(
        spheres=spheres, vertices=' '.join(map(str, vertices.ravel()))))


def test_contact_spheres_carry_plates_on_their_hull(contact_model):
    """Separate spheres (a vendor's foot: four 5 mm contact points) carry their plates on
    their convex hull, the sole they mark: its bottom face spans the spheres' lowest points;
    spheres that touch, or a sphere beside another geom, keep their own surfaces."""
    m = contact_model
    assert contact_spheres(m, body_geoms(m, m.body('points').id))
    assert not contact_spheres(m, body_geoms(m, m.body('touching').id))
    assert not contact_spheres(m, body_geoms(m, m.body('sphere_and_box').id))
    plates = body_plates(m, m.body('points').id, count=300, cache=False)
    assert len(plates) == 300
    sole = plates.normals[:, 2] < -0.999
    assert plates.areas[sole].sum() == pytest.approx(0.17 * 0.06, rel=0.02)
    assert plates.centroids[:, 2].min() == pytest.approx(-0.035, abs=1e-9)
    hull_area = trimesh.convex.convex_hull(np.concatenate([
        trimesh.creation.icosphere(subdivisions=4, radius=0.005).vertices + [x, y, -0.03]
        for x in (-0.05, 0.12) for y in (-0.03, 0.03)])).area
    assert plates.total_area == pytest.approx(hull_area, rel=0.02)
    touching = body_plates(m, m.body('touching').id, count=300, cache=False)
    assert touching.total_area < 2 * 4 * np.pi * 0.01 ** 2  # their outer surfaces only


def test_outline_plates_cover_the_collided_hull_of_a_mesh(contact_model):
    """outline=True (the other bodies'): a fine mesh carries plates on its convex outline:
    in every direction their centroids reach within a facet's centroid offset of the hull
    MuJoCo collides (its lowest point, however it lies), with at most 80 triangles at a
    coarse density; the mesh itself, decimated to the same count, shrinks further inward."""
    m = contact_model
    body = m.body('link').id
    geom = body_geoms(m, body)[0]
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, m.geom_quat[geom])
    hull = mesh_vertices(m, geom) @ rotation.reshape(3, 3).T + m.geom_pos[geom]
    directions = trimesh.creation.icosphere(subdivisions=3).vertices
    reach = (hull @ directions.T).max(axis=0)

    def gap(plates):
        return (reach - (plates.centroids @ directions.T).max(axis=0)).max()

    outline = body_plates(m, body, density_per_mm2=0.001, outline=True, cache=False)
    assert len(outline) <= 80
    assert gap(outline) < 0.08 * 0.15  # (1 cm: the centroids of 5 cm triangles)
    decimated = body_plates(m, body, count=len(outline), cache=False)
    assert gap(decimated) > 1.5 * gap(outline)  # (2.3 cm; Unitree G1's shoulder: 11 cm)
