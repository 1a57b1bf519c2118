"""The 3-DOF stepping leg: kinematics, its stepping path and the articulated_leg scene."""
import mujoco
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from rft_sim_ros.scenes.config import SceneError, load_scene
from rft_sim_ros.sim.simulation import Simulation
from rft_sim_ros.scenes.stepping_leg import LegGeometry, SteppingPath

LEG = LegGeometry()
PATH = SteppingPath(stroke=0.15, reach=0.12, stance_z=-0.04, lift_z=0.01, abduction=0.03,
                    period=2.0)
#: One step, coarse plates, 0.5 ms.
QUICK = {'rft.plates_per_body': 300, 'timestep': 0.0005, 'steps': 1}


@given(st.floats(-1.0, 1.0), st.floats(-0.8, 1.0), st.floats(-0.3, 1.2))
def test_inverse_kinematics_undoes_forward_kinematics(yaw, femur, tibia):
    foot = LEG.forward([yaw, femur, tibia])
    assert LEG.inverse(foot) == pytest.approx([yaw, femur, tibia], abs=1e-7)


def test_leg_kinematics_match_the_mjcf():
    sim = Simulation(load_scene('articulated_leg', QUICK))
    m, d = sim.model, sim.data
    base = d.body('coxa').xpos.copy()
    for q in ([0, 0, 0], [0.4, 0.3, -0.2], [-0.6, -0.2, 0.5]):
        d.qpos[[m.joint(j).qposadr[0] for j in ('coxa', 'femur', 'tibia')]] = q
        mujoco.mj_kinematics(m, d)
        tibia = d.body('tibia')
        foot = tibia.xpos - LEG.tibia * tibia.xmat.reshape(3, 3)[:, 2]
        assert foot - base == pytest.approx(LEG.forward(q), abs=1e-9)


def test_stepping_path_plunges_sweeps_back_lifts_and_returns_in_3d():
    t = np.linspace(0.0, 2.0, 4001)
    foot = PATH.foot(t)
    assert np.abs(np.diff(foot, axis=0)).max() < 1e-3  # continuous (0.5 ms apart)
    stance = (t >= 0.2) & (t < 1.4)
    assert foot[stance, 2] == pytest.approx(-0.04)
    assert foot[stance, 1] == pytest.approx(0.12)
    assert foot[stance, 0].max() - foot[stance, 0].min() == pytest.approx(0.15, abs=1e-4)
    assert np.all(np.diff(foot[stance, 0]) <= 0)  # straight back
    returning = t >= 1.6
    assert foot[returning, 2] == pytest.approx(0.01)
    assert foot[returning, 1].max() == pytest.approx(0.15, abs=1e-4)  # outward: 3D
    assert foot[0] == pytest.approx(PATH.foot([2.0])[0])  # closed loop
    with pytest.raises(ValueError, match='reach'):
        LEG.inverse(SteppingPath(0.6, 0.12, -0.04, 0.01, 0.0, 2.0).foot(t))


def test_one_step_pulls_the_carriage_most_of_the_stroke_and_loose_sand_does_not():
    travel = {}
    for zeta in (3.75, 0.1):
        sim = Simulation(load_scene('articulated_leg', {**QUICK, 'zeta': zeta}))
        sim.step(int(round(2.2 / sim.timestep)))
        m = sim.scenario.metrics(sim)
        assert m['steps_completed'] == 1
        assert m['max_foot_sinkage_m'] == pytest.approx(0.03, abs=0.003)
        assert np.isfinite(sim.data.qpos).all()
        travel[zeta] = m['carriage_displacement_per_step_m']
    assert 0.7 * 0.15 < travel[3.75] < 0.15
    assert abs(travel[0.1]) < 0.2 * travel[3.75]  # 1 N of rail friction outweighs the sand


@pytest.mark.parametrize('overrides, message', [
    ({'stroke': 0.6}, 'leaves the reach'),
    ({'steps': 0}, 'steps must be > 0'),
    ({'scoop_thickness': 0.03}, 'scoop_thickness must be in'),
    ({'stance_fraction': 0.9}, 'stance_fraction'),
])
def test_bad_leg_values_give_a_clear_scene_error(overrides, message):
    with pytest.raises(SceneError, match=message):
        Simulation(load_scene('articulated_leg', {**QUICK, **overrides}))
