"""The bundled hexapod MJCF (models/hexapod.xml) against the paper's robot (the published
model of RFT-SiM) and against rft_sim_ros.scenes.hexapod, plus short plain-MuJoCo runs on the
rigid floor."""
from pathlib import Path

import mujoco
import numpy as np
import pytest

from rft_sim_ros.scenes import hexapod
from rft_sim_ros.scenes.gaits import make_gait
from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sand.engine import can_collide
from rft_sim_ros.sim.simulation import Simulation

MODELS = Path(__file__).resolve().parent.parent / 'models'
ROBOT = MODELS / hexapod.MODEL_FILE
FLOOR = MODELS / hexapod.RIGID_FLOOR_SCENE


@pytest.fixture(scope='module')
def robot():
    return mujoco.MjModel.from_xml_path(str(ROBOT))


def feet_in_base(model, data):
    """(6, 3) foot sites in the base_link frame, m."""
    base = data.body('base_link')
    rot = base.xmat.reshape(3, 3)
    return np.array([(data.site(s).xpos - base.xpos) @ rot for s in hexapod.FOOT_SITES])


def run(model, gait, duration_s, base_z=None):
    """Step plain MuJoCo with the gait's targets from the keyframe 'home' (the neutral
    stance); return base positions (n, 3) and data."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key('home').id)
    if base_z is not None:
        data.qpos[2] = base_z
    positions = []
    for _ in range(int(round(duration_s / model.opt.timestep))):
        data.ctrl[:] = gait.targets(data.time)
        mujoco.mj_step(model, data)
        positions.append(data.qpos[:3].copy())
    return np.array(positions), data


def test_total_mass_is_the_papers(robot):
    assert sum(robot.body_mass) == pytest.approx(hexapod.MASS_KG, abs=1e-9)
    assert hexapod.MASS_KG == pytest.approx(4.04)
    parts = {'base_link': 1.0, 'payload': 1.0}
    for leg in hexapod.LEG_NAMES:
        parts.update({f'{leg}_coxa': 0.10, f'{leg}_mid': 0.14, f'{leg}_dactyl': 0.10})
    for body, mass in parts.items():
        assert robot.body(body).mass[0] == pytest.approx(mass), body
    # the published inertias: the plate's principal ones, the box's kept at 1e-5 kg m^2
    assert sorted(robot.body('base_link').inertia) == pytest.approx([0.00146, 0.00614, 0.00759])
    assert robot.body('payload').inertia == pytest.approx(np.full(3, 1e-5))
    assert robot.body('payload').pos == pytest.approx([0.0, 0.0, 0.06])  # 6 cm above the plate


@pytest.mark.parametrize('payload_kg', [0.0, 1.0, 2.277])
def test_payload_is_added_to_the_box_through_mjspec(payload_kg):
    spec = mujoco.MjSpec.from_file(str(FLOOR))
    spec.body(hexapod.PAYLOAD_BODY).mass += payload_kg
    model = spec.compile()
    assert sum(model.body_mass) == pytest.approx(hexapod.MASS_KG + payload_kg)
    assert model.body('payload').mass[0] == pytest.approx(1.0 + payload_kg)
    assert model.body('payload').inertia == pytest.approx(np.full(3, 1e-5))


def test_joint_actuator_and_body_names(robot):
    assert robot.joint(0).name == 'base_free'
    assert robot.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
    assert robot.body(robot.jnt_bodyid[0]).name == 'base_link'
    hinges = tuple(robot.joint(j).name for j in range(1, robot.njnt))
    assert hinges == hexapod.JOINT_NAMES
    assert all(robot.jnt_type[1:] == mujoco.mjtJoint.mjJNT_HINGE)
    assert robot.nu == 12
    for a, name in enumerate(hexapod.JOINT_NAMES):
        assert robot.actuator(a).name == name
        assert robot.joint(robot.actuator_trnid[a, 0]).name == name
    for leg, (coxa, mid, dactyl) in hexapod.LEG_BODIES.items():
        parent = {body: robot.body(robot.body(body).parentid[0]).name
                  for body in (coxa, mid, dactyl)}
        assert parent == {coxa: 'base_link', mid: coxa, dactyl: mid}
        assert robot.body(robot.joint(f'{leg}_knee').bodyid[0]).name == mid
        assert robot.body(robot.joint(f'{leg}_ankle').bodyid[0]).name == dactyl
        assert robot.body(coxa).jntnum[0] == 0  # the knee servo is fixed to the plate
    for body in hexapod.SAND_BODIES:  # every sand body carries a geom for the RFT plates
        assert robot.body(body).geomnum[0] >= 1


def test_published_servos_joints_and_axes(robot):
    for a, name in enumerate(hexapod.JOINT_NAMES):
        joint = robot.joint(name)
        assert robot.actuator_gainprm[a, 0] == pytest.approx(200.0)
        assert robot.actuator_biasprm[a, :3] == pytest.approx([0.0, -200.0, 0.0])
        assert not robot.actuator_forcelimited[a]  # no force limit
        assert robot.actuator_ctrlrange[a] == pytest.approx(joint.range)
        expected = hexapod.LEGS.knee_range if name.endswith('knee') else hexapod.LEGS.ankle_range
        assert joint.range == pytest.approx(expected)
        assert robot.jnt_stiffness[joint.id] == pytest.approx(1.0)  # N m/rad
        assert joint.damping[0] == pytest.approx(1.0)  # N m s/rad
        assert joint.armature[0] == 0.0
    data = mujoco.MjData(robot)
    mujoco.mj_kinematics(robot, data)
    for j in range(1, robot.njnt):  # every hinge turns about the body's long axis (x)
        assert np.abs(data.xaxis[j]) == pytest.approx([1.0, 0.0, 0.0], abs=1e-12)
    assert robot.opt.timestep == pytest.approx(0.0008)
    assert robot.opt.integrator == mujoco.mjtIntegrator.mjINT_EULER


def test_zero_pose_and_home_keyframe_match_the_published_layout(robot):
    data = mujoco.MjData(robot)
    mujoco.mj_kinematics(robot, data)
    for leg in hexapod.LEG_NAMES:  # knee and ankle axes 0.275 and 0.35 m out, hip plane
        side = 1.0 if leg[0] == 'L' else -1.0
        assert data.body(f'{leg}_mid').xpos[1:] == pytest.approx([side * 0.275, 0.176])
        assert data.body(f'{leg}_dactyl').xpos[1:] == pytest.approx([side * 0.35, 0.176])
    feet = feet_in_base(robot, data)
    assert np.abs(feet[:, 1]) == pytest.approx(np.full(6, 0.458), abs=1e-9)
    assert feet[:, 2] == pytest.approx(np.full(6, -0.015), abs=1e-9)
    assert feet[:, 0] == pytest.approx([0.14, 0.0, -0.14] * 2, abs=1e-9)
    mujoco.mj_resetDataKeyframe(robot, data, robot.key('home').id)
    mujoco.mj_kinematics(robot, data)
    assert feet_in_base(robot, data) == pytest.approx(hexapod.LEGS.neutral_feet(), abs=1e-7)
    assert data.ctrl == pytest.approx(data.qpos[7:])
    assert data.qpos[7:] == pytest.approx(make_gait('none').targets(0.0), abs=1e-7)


def test_pointed_dactyl_mesh_ends_at_the_foot_site(robot):
    data = mujoco.MjData(robot)
    data.qpos[7:] = np.linspace(-1.4, 0.3, 12)
    mujoco.mj_kinematics(robot, data)
    for leg in hexapod.LEG_NAMES:
        geom = robot.geom(f'{leg}_dactyl')
        mesh = geom.dataid[0]
        start = robot.mesh_vertadr[mesh]
        vertices = robot.mesh_vert[start:start + robot.mesh_vertnum[mesh]]
        world = data.geom(geom.id).xpos + vertices @ data.geom(geom.id).xmat.reshape(3, 3).T
        ankle = data.body(f'{leg}_dactyl').xpos
        apex = world[np.argmax(np.linalg.norm(world - ankle, axis=1))]
        assert apex == pytest.approx(data.site(f'{leg}_foot').xpos, abs=1e-6)
        assert np.linalg.norm(apex - ankle) == pytest.approx(hexapod.LEGS.dactyl_length, abs=1e-6)


def test_forward_kinematics_matches_mujoco(robot):
    rng = np.random.default_rng(0)
    data = mujoco.MjData(robot)
    legs = hexapod.LEGS
    for _ in range(50):
        knee = rng.uniform(*legs.knee_range, 6)
        ankle = rng.uniform(*legs.ankle_range, 6)
        data.qpos[7:] = np.stack([knee, ankle], axis=-1).ravel()
        data.qpos[3:7] = rng.normal(size=4) / 2 + [1, 0, 0, 0]  # any base pose
        data.qpos[3:7] /= np.linalg.norm(data.qpos[3:7])
        mujoco.mj_kinematics(robot, data)
        assert feet_in_base(robot, data) == pytest.approx(legs.forward(knee, ankle), abs=1e-9)


def test_gait_inverse_kinematics_puts_mujoco_feet_where_intended(robot):
    gait = make_gait('tripod')
    data = mujoco.MjData(robot)
    for t in np.linspace(0.0, 2.0, 161):
        data.qpos[7:] = gait.targets(t)
        mujoco.mj_kinematics(robot, data)
        feet = feet_in_base(robot, data)
        assert feet[:, [1, 2]] == pytest.approx(gait.foot_targets(t), abs=1e-9), t
        assert feet[:, 0] == pytest.approx([0.14, 0.0, -0.14] * 2, abs=1e-9)


def test_robot_collides_with_nothing_but_a_rigid_floor_does():
    spec = mujoco.MjSpec.from_file(str(ROBOT))
    plane = spec.worldbody.add_geom()  # a default world geom (e.g. a visual sand surface)
    plane.type = mujoco.mjtGeom.mjGEOM_PLANE
    plane.size = [0, 0, 1]
    plane.pos = [0, 0, 0.1]  # cuts through the legs
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert data.ncon == 0
    floor = mujoco.MjModel.from_xml_path(str(FLOOR))
    data = mujoco.MjData(floor)
    mujoco.mj_resetDataKeyframe(floor, data, floor.key('home').id)
    data.qpos[2] = 0.170  # feet 6 mm into the floor
    mujoco.mj_forward(floor, data)
    touching = sorted(floor.geom(c.geom2).name for c in data.contact[:data.ncon])
    assert touching == sorted(f'{leg}_dactyl' for leg in hexapod.LEG_NAMES)


def test_collision_is_skipped_only_where_no_rigid_contact_can_happen():
    assert not can_collide(mujoco.MjModel.from_xml_path(str(ROBOT)))
    assert can_collide(mujoco.MjModel.from_xml_path(str(FLOOR)))
    spec = mujoco.MjSpec.from_file(str(ROBOT))
    spec.add_pair(geomname1='L1_dactyl', geomname2='R1_dactyl')
    assert can_collide(spec.compile())
    sand = Simulation(load_scene('plate_press', {}))
    assert sand.model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT


def test_stands_on_six_dactyls_after_a_drop_on_the_rigid_floor():
    model = mujoco.MjModel.from_xml_path(str(FLOOR))
    positions, data = run(model, make_gait('none'), 1.5, base_z=0.276)  # dropped from 10 cm
    assert positions[-1, 2] == pytest.approx(0.176, abs=0.002)
    assert np.abs(positions[-1] - positions[-250]).max() < 1e-4  # still over the last 0.2 s
    assert np.abs(data.qvel).max() < 1e-3
    feet = {model.geom_bodyid[c.geom2] for c in data.contact[:data.ncon]}
    assert sorted(model.body(b).name for b in feet) == sorted(
        f'{leg}_dactyl' for leg in hexapod.LEG_NAMES)


def test_tripod_walks_sideways_on_the_rigid_floor():
    model = mujoco.MjModel.from_xml_path(str(FLOOR))
    gait = make_gait('tripod')
    positions, data = run(model, gait, 5.0)  # 5 cycles at 1 Hz, 0.8 ms steps
    assert np.isfinite(data.qpos).all()
    along_x, sideways = positions[-1, :2] - positions[0, :2]
    # ideal: 2 strokes of 0.05 m per cycle, less the 0.5 s ramp-in; towards +y, like a crab
    assert 0.40 < sideways < 0.50
    assert abs(along_x) < 0.02
    assert positions[:, 2].min() > 0.17  # body never drops
    up = data.body('base_link').xmat.reshape(3, 3)[:, 2]
    assert up[2] > np.cos(np.radians(5))
