"""The bundled quadruped's leg kinematics and trot (rft_sim_ros.scenes.quadruped), checked
against the model itself (models/quadruped/quadruped.urdf.xacro) and analytically."""
import mujoco
import numpy as np
import pytest

from rft_sim_ros import resources
from rft_sim_ros.robot import load_description
from rft_sim_ros.ros.gait_trajectory import GaitTrajectories
from rft_sim_ros.scenes.quadruped import (JOINT_NAMES, LEGS, STAND_HIP, STAND_KNEE, TrotGait,
                                          leg_forward, leg_inverse)

MODEL = resources.models_dir() / 'quadruped' / 'quadruped.urdf.xacro'


@pytest.fixture(scope='module')
def quadruped():
    description = load_description(MODEL, log=lambda notice: None)
    model = description.spec.compile()
    return description, model, mujoco.MjData(model)


def test_model_has_the_joints_pose_and_feet_the_gait_assumes(quadruped):
    description, model, data = quadruped
    hinges = [model.joint(j).name for j in range(model.njnt)
              if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    assert tuple(hinges) == JOINT_NAMES
    assert description.initial_positions == {
        name: {'hip_abduction': 0.0, 'hip_pitch': STAND_HIP, 'knee': STAND_KNEE}[
            name.split('_', 1)[1]] for name in JOINT_NAMES}
    assert model.body_subtreemass[model.body('base').id] == pytest.approx(9.8)
    rng = np.random.default_rng(1)
    for hip, knee in [(STAND_HIP, STAND_KNEE), *rng.uniform([-0.5, -2.4], [1.5, -0.4], (5, 2))]:
        for leg in LEGS:
            data.joint(f'{leg}_hip_pitch').qpos[0] = hip
            data.joint(f'{leg}_knee').qpos[0] = knee
        mujoco.mj_kinematics(model, data)
        for leg in LEGS:  # base at the origin, level: base frame = world frame
            axis = data.xanchor[model.joint(f'{leg}_hip_pitch').id]
            foot = data.xpos[model.body(f'{leg}_foot').id] - axis
            assert foot[[0, 2]] == pytest.approx(leg_forward(hip, knee), abs=1e-9)


def test_inverse_kinematics_inverts_forward():
    rng = np.random.default_rng(0)
    hip, knee = rng.uniform(-0.5, 1.5, 50), rng.uniform(-2.5, -0.1, 50)
    x, z = leg_forward(hip, knee)
    assert np.allclose(leg_inverse(x, z), (hip, knee), atol=1e-9)
    with pytest.raises(ValueError, match='reach'):
        leg_inverse(0.0, -0.5)


def test_trot_holds_the_pose_then_moves_diagonal_pairs_together():
    gait = TrotGait(start_time_s=1.0, frequency_hz=2.0)
    stand = np.tile([0.0, STAND_HIP, STAND_KNEE], 4)
    assert gait.targets(0.5) == pytest.approx(stand)
    for t in np.linspace(1.6, 3.0, 15):
        targets = gait.targets(t).reshape(4, 3)  # fl, fr, rl, rr
        assert targets[0] == pytest.approx(targets[3]) and targets[1] == pytest.approx(targets[2])
        assert np.all(targets[:, 0] == 0.0)
    assert gait.phases(2.0)[[0, 1]] == pytest.approx([0.0, 0.5])


def test_stance_feet_move_back_at_the_stroke_speed_and_targets_are_continuous():
    gait = TrotGait(frequency_hz=2.0, stance_fraction=0.5, step_length_m=0.08, ramp_time_s=0.0)
    times = np.arange(0.0, 2.0, 1e-3)
    targets = np.array([gait.targets(t) for t in times])
    assert np.max(np.abs(np.diff(targets, axis=0))) < 0.02  # rad per ms: no jumps
    x, z = leg_forward(targets[:, 1], targets[:, 2])  # front left foot
    stance = gait.phases(times[:, None])[:, 0] < 0.5
    speed = np.gradient(x, times)[stance]
    interior = np.abs(speed - speed.mean()) < 1.0  # leave the phase-switch samples out
    assert np.median(speed[interior]) == pytest.approx(-0.08 * 2.0 / 0.5, rel=1e-3)
    assert np.ptp(z[stance]) < 1e-9  # stance at the standing height
    assert z[~stance].max() == pytest.approx(z[stance][0] + 0.05, abs=1e-3)


def test_unreachable_trot_is_refused():
    with pytest.raises(ValueError, match='knee range'):
        TrotGait(step_length_m=0.5)
    with pytest.raises(ValueError, match='stance_fraction'):
        TrotGait(stance_fraction=1.0)


def test_trot_as_ros_trajectories():
    trajectories = GaitTrajectories(lambda start: TrotGait(start_time_s=start), horizon_s=0.25,
                                    spacing_s=0.05, start_delay_s=0.0)
    command = trajectories.command(2.0)
    assert command.joint_names == JOINT_NAMES and len(command.points) == 6
    assert command.points[3].positions == pytest.approx(trajectories.gait.targets(2.15).tolist())
