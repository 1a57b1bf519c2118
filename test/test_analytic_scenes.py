"""The analytic scenes end to end (scene YAML -> Simulation -> metrics) and the `rft-sim` CLI."""
import json

import numpy as np
import pytest

from rft_sim_ros.cli import main
from rft_sim_ros.sim.runner import SettingChange, run_scene
from rft_sim_ros.scenes.config import SceneError, load_scene
from rft_sim_ros.scenes.scenarios.plate_drop import expected_impact_depth

SUMMARY_FIELDS = {'scene', 'zeta', 'timestep_s', 'sim_time_s', 'wall_time_s',
                  'real_time_factor', 'steps', 'plates_total', 'plates_active_mean', 'stable',
                  'reason', 'metrics'}


def test_plate_press_slope_is_zeta_times_area():
    summary = run_scene(load_scene('plate_press', {'speed': 0.02}), duration=1.2, progress=False)
    metrics = summary['metrics']
    assert metrics['expected_force_per_sinkage_N_per_m'] == pytest.approx(3.75e6 * 0.01)
    assert metrics['force_per_sinkage_N_per_m'] == pytest.approx(
        metrics['expected_force_per_sinkage_N_per_m'], rel=0.01)
    assert metrics['max_sinkage_m'] > 0.015
    assert metrics['max_lateral_force_N'] < 1e-6 * metrics['max_force_N']


def test_plate_press_force_is_the_same_at_1_and_15_cm_per_s():
    slow = run_scene(load_scene('plate_press', {'speed': 0.01}), duration=2.5, progress=False)
    fast = run_scene(load_scene('plate_press', {'speed': 0.15}), duration=0.2, progress=False)
    assert fast['metrics']['force_per_sinkage_N_per_m'] == pytest.approx(
        slow['metrics']['force_per_sinkage_N_per_m'], rel=1e-3)


def test_plate_drop_from_10_cm_stops_at_the_energy_balance_depth_and_rests():
    summary = run_scene(load_scene('plate_drop'), duration=2.0, progress=False)
    metrics = summary['metrics']
    expected = expected_impact_depth(1.0, 0.01, 3.75, 0.1)
    assert metrics['expected_max_sinkage_m'] == pytest.approx(expected)
    assert metrics['max_sinkage_m'] == pytest.approx(expected, rel=0.03)
    assert metrics['final_sinkage_m'] > 0.9 * metrics['max_sinkage_m']  # stays in the sand
    assert metrics['rebound_m'] < 1e-4
    assert metrics['settled_speed_mps'] < 1e-3
    assert summary['stable'] and summary['reason'] is None
    # the implicit treatment settles in about one solve per step, without anti-cycling
    assert 0.5 < summary['implicit_solves_per_step'] < 2.0
    assert summary['implicit_unsettled_steps'] == 0


def test_a_drop_that_ends_before_the_plate_reaches_the_sand_compares_nothing():
    """(0.05 s of a 10 cm fall: the plate is still in the air, 8.8 cm above the sand.)"""
    metrics = run_scene(load_scene('plate_drop'), duration=0.05, progress=False)['metrics']
    assert metrics['max_sinkage_m'] < 0.0
    assert metrics['expected_max_sinkage_m'] is None and metrics['max_sinkage_error'] is None


def test_expected_values_use_the_zeta_the_plate_met():
    """A zeta map of factor 0.5 under the plate: the press's slope is 0.5 zeta A, as
    expected; a drop whose zeta changes after the impact: the expected impact depth is the
    one at the impact's zeta, the static depth the one at the end's."""
    half = {'sand.zeta_map.regions': [{'x': [-1, 1], 'y': [-1, 1], 'factor': 0.5}]}
    press = run_scene(load_scene('plate_press', {'speed': 0.05, **half}), duration=0.5,
                      progress=False)['metrics']
    assert press['expected_force_per_sinkage_N_per_m'] == pytest.approx(0.5 * 3.75e6 * 0.01)
    assert abs(press['force_per_sinkage_error']) < 0.01
    changed = run_scene(load_scene('plate_drop'), duration=1.0, progress=False,
                        schedule=[(0.6, SettingChange('zeta', 1.0))])['metrics']
    assert changed['expected_max_sinkage_m'] == pytest.approx(
        expected_impact_depth(1.0, 0.01, 3.75, 0.1))
    assert changed['static_sinkage_m'] == pytest.approx(1.0 * 9.81 / (1e6 * 0.01))


def test_expected_impact_depth_solves_the_energy_balance():
    m, area, zeta, h, g = 2.0, 0.004, 1.5, 0.3, 9.81
    z = expected_impact_depth(m, area, zeta, h, g)
    assert m * g * (h + z) == pytest.approx(zeta * 1e6 * area * z ** 2 / 2)


def test_explicit_rft_bounces_where_the_default_treatment_rests():
    """Why the default exists: raw explicit RFT throws the plate back up after impact."""
    raw = run_scene(load_scene('plate_drop', {'rft.low_velocity.method': 'none'}),
                    duration=1.0, progress=False)['metrics']
    assert raw['rebound_m'] > 1e-3


@pytest.mark.parametrize('overrides, message', [
    ({'rft.sand_bodies': ['plate', 'no_such_body']}, "sand body 'no_such_body' matches no body"),
    ({'model': 'missing.xml'}, "--set model: file 'missing.xml' not found"),
    ({'zeta': 0.0}, '--set zeta: must be > 0'),
    ({'zeta': float('nan')}, '--set zeta: must be finite'),
    ({'timestep': -0.001}, '--set timestep: must be > 0'),
    ({'mass': -1.0}, 'mass must be > 0'),
    ({'no_such_key': 1}, "unknown setting 'no_such_key'"),
    ({'rft.low_velocity.method': 'magic'}, '--set rft.low_velocity.method: must be one of'),
])
def test_bad_scene_input_gives_one_clear_error(overrides, message, tmp_path, capsys):
    with pytest.raises(SceneError, match=message):
        run_scene(load_scene('plate_drop', overrides), duration=0.01, progress=False)
    args = ['run', 'plate_drop', '--duration', '0.01', '--out', str(tmp_path)]
    for key, value in overrides.items():
        args += ['--set', f'{key}={json.dumps(value) if not isinstance(value, float) else value}']
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('rft-sim: error:') and 'Traceback' not in err[0]


def test_cli_run_writes_summary_timeseries_and_plot(tmp_path, capsys):
    out = tmp_path / 'run'
    code = main(['run', 'plate_drop', '--duration', '0.4', '--zeta', '2.5', '--timestep',
                 '0.0005', '--plates-per-body', '150', '--set', 'drop_height=0.05',
                 '--out', str(out), '--quiet', '--json'])
    assert code == 0
    summary = json.loads((out / 'summary.json').read_text())
    assert SUMMARY_FIELDS <= set(summary)
    assert summary['zeta'] == 2.5 and summary['timestep_s'] == 0.0005
    assert summary['steps'] == 800 and summary['sim_time_s'] == pytest.approx(0.4)
    assert summary['scene_config']['params']['drop_height'] == 0.05
    assert 100 <= summary['plates_total'] <= 250
    assert (out / 'timeseries.png').stat().st_size > 1000
    rows = (out / 'timeseries.csv').read_text().splitlines()
    assert len(rows) == 1 + 40  # header + publish_rate (100 Hz) x 0.4 s
    header = rows[0].split(',')
    assert {'base_roll_rad', 'force_z_N_plate', 'sinkage_m_plate'} <= set(header)
    sinkage = [float(row.split(',')[header.index('sinkage_m_plate')]) for row in rows[1:]]
    assert sinkage[0] == 0 and max(sinkage) == pytest.approx(
        summary['generic_metrics']['max_sinkage_m_plate'], rel=1e-6)
    page = (out / 'report.html').read_text()
    assert 'src="timeseries.png"' in page and 'href="summary.json"' in page
    printed = json.loads(capsys.readouterr().out)
    assert printed['metrics']['max_sinkage_m'] > 0


def test_cli_lists_the_bundled_scenes(capsys):
    assert main(['scenes']) == 0
    names = [line.split()[0] for line in capsys.readouterr().out.splitlines()]
    assert {'plate_drop', 'plate_press'} <= set(names)


def test_output_piped_into_a_reader_that_leaves_is_not_an_error():
    """`rft-sim scenes hexapod | head -1`: the reader closes the pipe (here before the
    command has written anything); no traceback, status 0."""
    import subprocess
    import sys
    process = subprocess.Popen([sys.executable, '-m', 'rft_sim_ros', 'scenes', 'hexapod'],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    process.stdout.close()
    assert process.wait(timeout=60) == 0
    assert b'Traceback' not in process.stderr.read()


def test_zeta_change_mid_run_changes_the_resting_depth():
    from rft_sim_ros.sim.simulation import Simulation
    sim = Simulation(load_scene('plate_drop', {'drop_height': 0.0}))
    sim.step(500)
    depth_stiff = -sim.data.body('plate').xpos[2]
    sim.zeta = 0.5
    sim.step(1)
    assert sim.engine.zeta == 0.5
    sim.step(1500)
    assert -sim.data.body('plate').xpos[2] > 3 * depth_stiff
    assert np.isfinite(sim.data.qpos).all()
