"""The run's time series (sim/series.py) from a real run: what each column holds, checked
against the states and metrics of the same run."""
import csv
import json
from types import SimpleNamespace

import numpy as np
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


WHEEL = """<mujoco><worldbody><body name="hub" pos="0 0 0.5">
  <geom type="box" size="0.05 0.05 0.05" mass="1"/>
  <body name="wheel" pos="0 0.1 0"><joint name="axle" axis="0 1 0"/>
    <geom type="cylinder" size="0.1 0.02" euler="90 0 0" mass="1"/></body>
</body></worldbody></mujoco>"""


def test_a_joint_effort_is_its_mean_over_the_publish_period_not_one_step_of_a_sawtooth(
        tmp_path):
    """A wheel spinning in the air at a commanded speed: its servo target moves at control
    ticks (every 2 steps), so the servo's force swings about its mean, zero, from step to
    step; the published effort is that mean over the steps since the last state (as the leg
    wrenches are), not the last step's, which a publish in phase with the ticks would read
    on one side only."""
    from rft_sim_ros.sim.simulation import Simulation
    path = tmp_path / 'wheel.xml'
    path.write_text(WHEEL)
    sim = Simulation(load_scene(path, {'rft.sand_bodies': ['wheel'],
                                       'rft.plates_per_body': 50}))
    sim.commands.set_velocities([20.0], sim.time)
    sim.step(500)
    sim.state()  # (at a steady speed: the mean restarts here)
    per_step = []
    for _ in range(10):
        sim.step(1)
        per_step.append(float(sim.data.qfrc_actuator[0]))
    effort = float(sim.state().joint_efforts[0])
    assert effort == pytest.approx(np.mean(per_step), abs=1e-12)
    assert min(per_step) < -0.03 and max(per_step) > 0.03  # (N m: the sawtooth)
    assert abs(effort) < 0.02 * max(abs(f) for f in per_step)
    assert sim.data.qvel[0] == pytest.approx(20.0, rel=0.01)
