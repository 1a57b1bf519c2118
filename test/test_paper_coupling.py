"""The RFT-SiM code's loop as a mode (rft.coupling: paper, rft_sim_ros/sand/paper_loop.py):
the one-step lag, finite-difference velocities, the EMA whose history survives leaving the
sand, its errors, and what it changes on the paper's rail (the open C below flat)."""
import math

import numpy as np
import pytest

from rft_sim_ros.rft import plate_forces
from rft_sim_ros.sand.paper_loop import PAPER_SETTINGS, PaperLoopEngine
from rft_sim_ros.scenes.config import SceneError, load_scene
from rft_sim_ros.sim.runner import run_scene
from rft_sim_ros.sim.simulation import Simulation

DROP = {**PAPER_SETTINGS, 'rft.plates_per_body': 100, 'drop_height': 0.0}


def world_plates(sim):
    """Plate positions and normals (world, m) of the plate_drop body in the current poses."""
    engine, body = sim.engine, sim.model.body('plate').id
    rotation = sim.data.xmat[body].reshape(3, 3)
    return (sim.data.xpos[body] + engine.local_pos @ rotation.T,
            engine.local_normal @ rotation.T)


def test_forces_come_from_the_last_steps_poses_and_are_applied_one_step_late():
    sim = Simulation(load_scene('plate_drop', {**DROP, 'rft.low_velocity.method': 'none',
                                               'drop_height': 0.05}))
    assert isinstance(sim.engine, PaperLoopEngine)
    sim.step(104)  # falls 5 cm in 0.1 s, then ploughs into the sand at about 1 m/s
    before, _ = world_plates(sim)  # the poses mjData holds after this step
    sim.step(1)
    after, normals = world_plates(sim)  # (the state the step started from)
    dt = sim.timestep
    expected = plate_forces(after, normals, sim.engine.areas, (after - before) / dt,
                            sim.zeta, normalisation='rft_sim').sum(axis=0)
    assert expected[2] > 1.0  # in the sand, pushed up
    assert sim.engine._pending[0, :3] == pytest.approx(expected, rel=1e-9)  # computed now ...
    applied = sim.engine._pending.copy()
    sim.step(1)
    assert sim.engine.body_wrenches[0] == pytest.approx(applied[0])  # ... applied next step
    assert sim.data.xfrc_applied[sim.model.body('plate').id] == pytest.approx(applied[0])


def test_moving_average_keeps_its_history_when_a_plate_leaves_the_sand():
    sim = Simulation(load_scene('plate_drop', DROP))
    engine = sim.engine
    sim.step(40)
    inside = engine._has_history.copy()
    assert inside.any()
    remembered = engine._smoothed.copy()
    body = sim.model.body('plate').id
    sim.data.qpos[2] += 0.05  # lift the plate out of the sand (a free joint: x y z first)
    sim.data.qvel[:] = 0.0
    sim.step(3)
    assert engine.plates_active == 0
    assert engine.body_wrenches[0] == pytest.approx(np.zeros(6))  # out of the sand: no force
    assert (engine._has_history == inside).all()  # ... but the history stays
    assert engine._smoothed == pytest.approx(remembered)
    assert sim.data.xfrc_applied[body] == pytest.approx(np.zeros(6))


@pytest.mark.parametrize('overrides, message', [
    ({'rft.low_velocity.method': 'implicit'}, "set rft.low_velocity.method to 'ema' or 'none'"),
    ({'sand.deformable.enabled': True}, 'no deformable sand'),
    ({'rft.coupling': 'lagged'}, 'rft.coupling'),
])
def test_paper_coupling_refuses_what_it_cannot_do(overrides, message):
    with pytest.raises(SceneError, match=message):
        Simulation(load_scene('plate_drop', {**DROP, **overrides}))


def test_the_open_c_falls_below_flat_only_with_the_papers_loop():
    """The paper's shape ordering (closed C > flat > open C) on its rail at its 1 ms timestep:
    with exact coupling the open C progresses more than flat; with the authors' loop (the
    one-step lag) less."""
    travel = {}
    for mode, settings in (('exact', {}), ('paper', PAPER_SETTINGS)):
        for scene in ('rail_flat', 'rail_open_c', 'rail_closed_c'):
            overrides = {**settings, 'rft.plates_per_body': 300, 'speed': 2.0,
                         'timestep': 0.001}
            summary = run_scene(load_scene(scene, overrides), duration=math.pi / 2.0 + 0.3,
                                progress=False, plots=False)
            assert summary['stable'], summary['reason']
            assert summary['metrics']['rotation_deg'] == pytest.approx(180.0, abs=0.5)
            travel[mode, scene] = summary['metrics']['carriage_displacement_m']
    assert travel['exact', 'rail_flat'] < travel['exact', 'rail_open_c']
    assert travel['exact', 'rail_open_c'] < travel['exact', 'rail_closed_c']
    assert travel['paper', 'rail_open_c'] < travel['paper', 'rail_flat']
    assert travel['paper', 'rail_flat'] < travel['paper', 'rail_closed_c']
