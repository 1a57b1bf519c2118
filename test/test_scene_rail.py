"""Rail rig scenes (rotating_intruder, rail_flat, rail_open_c, rail_closed_c): geometry,
the torque measurement against the RFT law, speed independence, shape ordering, errors."""
import math

import numpy as np
import pytest
import trimesh

from rft_sim_ros.rft import plate_forces
from rft_sim_ros.scenes.intruders import arc_mesh
from rft_sim_ros.sim.runner import run_scene
from rft_sim_ros.scenes.config import SceneError, load_scene
from rft_sim_ros.sim.simulation import Simulation

COARSE = {'rft.plates_per_body': 300}


def rotation_time(speed):
    """Sim time for one 180 deg rotation at `speed` rad/s plus 0.3 s to come to rest, s."""
    return math.pi / speed + 0.3


def test_arc_mesh_is_a_closed_half_ring_with_outward_normals():
    vertices, faces = arc_mesh(0.063, 0.02, 0.004)
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume == pytest.approx(math.pi * 0.0315 * 0.004 * 0.02, rel=2e-3)  # > 0: outward
    lowest = np.argmin(mesh.triangles_center[:, 2])
    assert mesh.face_normals[lowest][2] < -0.99  # the bulge's outside faces down (-z)
    centre_line = np.linalg.norm(mesh.vertices[:, [0, 2]], axis=1)
    assert centre_line.max() == pytest.approx(0.063 + 0.002, abs=1e-9)  # the tip is farthest


@pytest.mark.parametrize('scene, reach', [('rail_flat', 0.063), ('rail_closed_c', 0.082),
                                          ('rail_open_c', 0.082)])
def test_axle_height_puts_the_tip_max_depth_below_the_sand(scene, reach):
    """The paper's intruders: the flat plate reaches 6.3 cm from its axle, the C 8.2 cm (its
    tip speed 16.4 cm/s at 2 rad/s); each axle sits where the tip reaches 5.5 cm deep."""
    sim = Simulation(load_scene(scene, COARSE))
    axle = sim.data.body('intruder').xpos
    assert axle[2] == pytest.approx(reach - 0.055)
    assert sim.data.body('carriage').xpos[2] == pytest.approx(0.09)
    assert sim.servo_joint_names == ('servo',)
    plates = sim.engine.local_pos
    assert np.linalg.norm(plates[:, [0, 2]], axis=1).max() == pytest.approx(reach, abs=0.003)


def test_fixed_base_torque_increase_is_the_rft_torque_and_speed_independent():
    runs = {}
    for speed in (0.5, 2.0):
        sim = Simulation(load_scene('rotating_intruder', {**COARSE, 'speed': speed}))
        sim.step(int(round(rotation_time(speed) / sim.timestep)))
        runs[speed] = sim
    m = {speed: sim.scenario.metrics(sim) for speed, sim in runs.items()}
    for metrics in m.values():
        assert metrics['rotation_deg'] == pytest.approx(180.0, abs=0.5)
        assert metrics['max_sinkage_m'] == pytest.approx(0.055, abs=5e-4)
        # servo-in-sand minus servo-in-air is the sand's torque on the axle
        assert metrics['peak_torque_increase_Nm'] == pytest.approx(
            metrics['peak_sand_torque_Nm'], rel=0.02)
    assert m[2.0]['peak_torque_increase_Nm'] == pytest.approx(
        m[0.5]['peak_torque_increase_Nm'], rel=0.02)
    assert m[2.0]['peak_servo_torque_air_Nm'] > m[0.5]['peak_servo_torque_air_Nm']

    # the recorded sand torque at 60 deg equals the RFT law on the same plates, rigidly rotated
    sim = runs[0.5]
    s = sim.scenario.series()
    angle = math.radians(60.0)
    recorded = np.interp(angle, s['angle_rad'], s['sand_torque_Nm'])
    rotation = np.array([[math.cos(angle), 0, math.sin(angle)], [0, 1, 0],
                         [-math.sin(angle), 0, math.cos(angle)]])  # about +y
    axle = sim.data.body('intruder').xpos
    lever = sim.engine.local_pos @ rotation.T
    velocity = np.cross([0.0, 0.5, 0.0], lever)
    forces = plate_forces(axle + lever, sim.engine.local_normal @ rotation.T, sim.engine.areas,
                          velocity, sim.zeta)
    expected = -np.cross(lever, forces).sum(axis=0)[1]  # against the motion (+y rotation)
    assert expected > 1.0
    assert recorded == pytest.approx(expected, rel=0.03)


def test_closed_c_progresses_most_and_the_carriage_then_stops():
    """The paper's closed C > flat, with exact coupling; the open C below flat comes from the
    paper's one-step-lag loop (test_paper_coupling.py), not from the force law."""
    travel = {}
    for scene in ('rail_flat', 'rail_open_c', 'rail_closed_c'):
        summary = run_scene(load_scene(scene, {**COARSE, 'speed': 2.0}),
                            duration=rotation_time(2.0), progress=False)
        m = summary['metrics']
        assert summary['stable'], summary['reason']
        assert m['rotation_deg'] == pytest.approx(180.0, abs=0.5)
        assert m['carriage_displacement_m'] == pytest.approx(
            m['carriage_displacement_rotation_m'], abs=1e-3)  # no coasting: sand + friction
        travel[scene] = m['carriage_displacement_m']
    assert 0.03 < travel['rail_open_c'] < travel['rail_closed_c']
    assert 0.03 < travel['rail_flat'] < travel['rail_closed_c'] < 0.082 * math.pi


def test_mirrored_rotation_drives_the_carriage_the_other_way_by_the_same_amount():
    ahead = Simulation(load_scene('rail_flat', {**COARSE, 'speed': 2.0}))
    back = Simulation(load_scene('rail_flat', {**COARSE, 'speed': 2.0, 'direction': -1}))
    for sim in (ahead, back):
        sim.step(int(round(rotation_time(2.0) / sim.timestep)))
    assert back.data.body('carriage').xpos[0] < -0.03
    assert back.scenario.metrics(back)['carriage_displacement_m'] == pytest.approx(
        ahead.scenario.metrics(ahead)['carriage_displacement_m'], rel=0.03)


def test_rail_friction_and_damping_reach_the_model():
    sim = Simulation(load_scene('rail_flat', {**COARSE, 'rail_friction': 2.5,
                                              'rail_damping': 0.7}))
    dof = sim.model.joint('rail').dofadr[0]
    assert sim.engine.joint_friction == {dof: pytest.approx(2.5)}  # solved with the sand
    assert sim.model.dof_frictionloss[dof] == 0.0  # (not by MuJoCo a second time)
    assert sim.model.dof_damping[dof] == pytest.approx(0.7)
    fixed = Simulation(load_scene('rotating_intruder', COARSE))
    assert 'rail' not in fixed.joint_names


@pytest.mark.parametrize('overrides, message', [
    ({'shape': 'square'}, 'shape must be one of'),
    ({'direction': 0}, 'direction must be 1 or -1'),
    ({'max_depth': 0.1}, 'max_depth must be <= 0.063'),
    ({'rail_height': 0.005}, 'must be below the rail'),
    ({'thickness': 0.05, 'shape': 'c'}, 'does not fit a c intruder'),
    ({'speed': -1.0}, 'speed must be > 0'),
])
def test_bad_rail_values_give_a_clear_scene_error(overrides, message):
    with pytest.raises(SceneError, match=message):
        Simulation(load_scene('rail_flat', {**COARSE, **overrides}))
