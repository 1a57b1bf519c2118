"""The largest timestep the sand coupling resolves (sand/timestep.py), and runs beyond it
reported as not stable, with the bound in the reason."""
import json
import math

import pytest

from rft_sim_ros.cli import main
from rft_sim_ros.sand.timestep import sand_time_scales, timestep_bound, timestep_problem
from rft_sim_ros.scenes.config import bundled_scenes, load_scene
from rft_sim_ros.sim.simulation import Simulation


def test_a_free_plate_has_the_time_scale_of_its_sand_spring():
    scene = load_scene('plate_drop')
    sim = Simulation(scene)
    mass, side = scene.params['mass'], scene.params['side']
    k = scene.zeta * 1e6 * side ** 2                    # zeta A, N/m (zeta N/cm^3 -> N/m^3)
    bound, body = timestep_bound(sim.engine, scene.zeta)
    assert body == 'plate'
    assert bound == pytest.approx(math.sqrt(mass / k), rel=1e-9)
    # stiffer sand, shorter bound: tau ~ zeta^-1/2
    assert sand_time_scales(sim.engine, 4 * scene.zeta)['plate'] == pytest.approx(bound / 2)


@pytest.mark.parametrize('name', sorted(bundled_scenes()))
def test_every_bundled_scene_runs_within_its_bound(name):
    scene = load_scene(name)
    sim = Simulation(scene)
    bound, _ = timestep_bound(sim.engine, scene.zeta)
    assert scene.timestep <= 0.7 * bound


def test_plate_drop_at_a_1_s_timestep_is_not_stable(tmp_path, capsys):
    out = tmp_path / 'run'
    assert main(['run', 'plate_drop', '--timestep', '1', '--duration', '3', '--out', str(out),
                 '--no-bag']) == 1
    summary = json.loads((out / 'summary.json').read_text())
    assert summary['stable'] is False
    assert 'longer than the 5.16 ms the sand coupling resolves' in summary['reason']
    assert summary['timestep_bound_s'] == pytest.approx(5.164e-3, rel=1e-3)
    assert 'rft-sim: warning: timestep 1000 ms' in capsys.readouterr().err


def test_a_hexapod_at_50_ms_is_flagged(tmp_path, capsys):
    out = tmp_path / 'run'
    assert main(['run', 'hexapod', '--timestep', '0.05', '--duration', '0.5', '--out',
                 str(out), '--quiet', '--no-bag']) == 1
    summary = json.loads((out / 'summary.json').read_text())
    # the run diverges; the reason names the divergence and the timestep bound beside it,
    # set by the stiffest body for its mass: the payload box, whose plates meet the sand if
    # the robot falls
    assert not summary['stable'] and summary['reason'].startswith('diverged at t = ')
    assert "ms the sand coupling resolves (sqrt(m/k) of body 'payload'" in summary['reason']
    assert "rft-sim: error: " in capsys.readouterr().err  # said, --quiet as it is


def test_a_zeta_raised_during_the_run_counts(tmp_path):
    out = tmp_path / 'run'  # 4 ms is within the bound at 3.75 N/cm^3, not at 4 x 3.75
    assert main(['run', 'plate_drop', '--timestep', '0.004', '--duration', '0.1',
                 '--set-at', '0.05:zeta=15', '--out', str(out), '--quiet', '--no-bag']) == 1
    assert 'at zeta 15 N/cm^3' in json.loads((out / 'summary.json').read_text())['reason']


def test_a_timestep_at_the_bound_is_within_it_and_one_past_it_says_by_how_much():
    """plate_drop at zeta 100 has its bound at 1 ms, computed as 0.9999999999999996 ms: its
    own 1 ms timestep is within it (rounding), not 'longer than the 1 ms'; a timestep past
    it is told with the digits that tell the two apart."""
    engine = Simulation(load_scene('plate_drop')).engine
    assert timestep_bound(engine, 100.0)[0] == pytest.approx(1e-3, rel=1e-12)
    assert timestep_problem(engine, 1e-3, 100.0) is None
    assert timestep_problem(engine, 1.0001e-3, 100.0).startswith(
        'timestep 1.0001 ms is longer than the 1 ms the sand coupling resolves')
