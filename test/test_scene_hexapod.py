"""The hexapod scene (config/hexapod.yaml): payload, drop, gait wiring and a short walk."""
import numpy as np
import pytest

from rft_sim_ros.scenes import hexapod
from rft_sim_ros.sim.runner import run_scene
from rft_sim_ros.scenes.config import SceneError, load_scene
from rft_sim_ros.sim.simulation import Simulation

#: Coarse and short: 120 plates per body, settle 0.4 s, two gait cycles.
QUICK = {'rft.plates_per_body': 120, 'settle_time': 0.4, 'cycles': 2}


@pytest.mark.parametrize('payload', [0.0, 1.0, 2.277])
def test_payload_changes_the_total_mass(payload):
    sim = Simulation(load_scene('hexapod', {**QUICK, 'payload': payload}))
    assert np.sum(sim.model.body_mass) == pytest.approx(hexapod.MASS_KG + payload)
    assert sim.scenario.metrics(sim)['total_mass_kg'] == pytest.approx(4.04 + payload)


def test_robot_is_released_with_its_feet_drop_height_above_the_sand():
    sim = Simulation(load_scene('hexapod', {**QUICK, 'drop_height': 0.07}))
    tips = sim.data.site_xpos[[sim.model.site(s).id for s in hexapod.FOOT_SITES], 2]
    assert tips == pytest.approx(np.full(6, 0.07), abs=1e-9)
    assert sim.servo_joint_names == hexapod.JOINT_NAMES


def test_hexapod_walks_sideways_at_zeta_3_75_without_nan():
    summary = run_scene(load_scene('hexapod', QUICK), duration=2.4, progress=False)
    m = summary['metrics']
    assert summary['stable'], summary['reason']
    assert m['walk_time_s'] == pytest.approx(2.0, abs=0.01)
    # 2 cycles at a 50 mm stroke, the first one ramping up: clearly along +y (the walking
    # direction, "forward" in the metrics), < the no-slip 0.2 m
    assert 0.04 < m['forward_distance_m'] < 0.2
    assert summary['generic_metrics']['base_displacement_xyz_m'][1] > 0.04
    assert abs(m['lateral_drift_m']) < 0.3 * m['forward_distance_m']
    assert 0.0 < m['mean_sinkage_m'] < 0.176  # in the sand, base_link above it
    assert m['settled_base_height_m'] > 0.03  # the plate stays clear of the sand
    weight = 9.81 * m['total_mass_kg']
    peaks = [m[f'walk_peak_force_z_N_{leg}'] for leg in hexapod.LEG_NAMES]
    assert all(weight / 6 < p < 3 * weight for p in peaks)  # each leg carries load


def test_no_gait_stands_still():
    summary = run_scene(load_scene('hexapod', {**QUICK, 'gait': 'none'}), duration=2.4,
                        progress=False)
    m = summary['metrics']
    assert summary['stable'], summary['reason']
    assert abs(m['forward_distance_m']) < 2e-3
    assert m['mean_sinkage_m'] > 0.0
    assert m['backward_fraction'] == 0.0  # nanometre jitter is not motion (was 61 here)


@pytest.mark.parametrize('overrides, message', [
    ({'gait': 'crawl'}, "gait must be one of"),
    ({'payload': -1.0}, 'payload must be >= 0'),
    ({'step_length': 0.5}, 'out of reach'),
    ({'frequency': 0.0}, 'frequency must be > 0'),
    ({'drop_height': 'high'}, 'drop_height must be a finite number'),
])
def test_bad_hexapod_values_give_a_clear_scene_error(overrides, message):
    with pytest.raises(SceneError, match=message):
        Simulation(load_scene('hexapod', {**QUICK, **overrides}))
