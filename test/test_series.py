"""The run's time series (sim/series.py) from a real run: what each column holds, checked
against the states and metrics of the same run."""
import csv
import json
from types import SimpleNamespace

import pytest

from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sim.runner import run_scene
from rft_sim_ros.sim.series import SeriesRows


@pytest.fixture(scope='module')
def hexapod_run(tmp_path_factory):
    """A short hexapod drop (0.3 s, coarse plates): its folder."""
    out = tmp_path_factory.mktemp('hexapod')
    run_scene(load_scene('hexapod', {'rft.plates_per_body': 40}), out, duration=0.3,
              progress=False, plots=False)
    return out


def _rows(out):
    with open(out / 'timeseries.csv', newline='') as handle:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(handle)]


def test_joint_angles_and_torques_are_recorded_per_joint(hexapod_run):
    rows = _rows(hexapod_run)
    summary = json.loads((hexapod_run / 'summary.json').read_text())
    joints = [f'{leg}_{part}' for leg in ('L1', 'L2', 'L3', 'R1', 'R2', 'R3')
              for part in ('knee', 'ankle')]
    assert summary['joint_legs'] == {joint: joint[:2] for joint in joints}
    assert summary['robot_model']['name'] == 'hexapod'
    assert summary['robot_model']['file'].endswith('hexapod.xml')
    for joint in joints:
        angles = [row[f'angle_rad_{joint}'] for row in rows]
        torques = [row[f'torque_Nm_{joint}'] for row in rows]
        assert all(abs(a) < 3.2 for a in angles)
        assert max(abs(t) for t in torques) > 0         # the servos hold the stance


def test_sinkage_per_leg_is_its_deepest_body_and_attitude_stays_level(hexapod_run):
    rows = _rows(hexapod_run)
    summary = json.loads((hexapod_run / 'summary.json').read_text())
    depths = summary['generic_metrics']
    for leg in ('L1', 'R3'):
        deepest = max(depths[f'max_sinkage_m_{leg}_dactyl'], depths[f'max_sinkage_m_{leg}_mid'])
        sinkage = [row[f'sinkage_m_{leg}'] for row in rows]
        assert max(sinkage) == pytest.approx(deepest, rel=1e-6) and deepest > 0.005
        assert sinkage[0] == 0.0                          # dropped from above the sand
    for angle in ('roll', 'pitch'):                     # a symmetric drop lands level
        assert max(abs(row[f'base_{angle}_rad']) for row in rows) < 0.05


def test_a_leg_without_a_sand_body_is_refused():
    """A leg whose bodies carry no plates has no sinkage: refused when the rows are set
    up, not read off another leg's body."""
    sim = SimpleNamespace(sand_bodies=('A', 'C'), legs={'a': ('A',), 'x': ('O',), 'c': ('C',)})
    with pytest.raises(ValueError, match=r"legs without a sand body have no sinkage: \['x'\]"):
        SeriesRows(sim)
