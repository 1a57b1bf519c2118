"""The bipedal test robot (test/robots/biped, MJCF written by make_biped.py) in zeta 3.75
sand: it stands from its keyframe, its spring-toed variant too, and pushed over it lands on
its side, lies on the sand and comes to rest, and its `outcome` says so."""
import importlib.util
from pathlib import Path

import mujoco
import numpy as np
import pytest

from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sim.outcome import TILT_LIMIT_DEG
from rft_sim_ros.sim.simulation import Simulation

BIPED = Path(__file__).parent / 'robots' / 'biped'


def _generator():
    spec = importlib.util.spec_from_file_location('make_biped', BIPED / 'make_biped.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize('toes', [False, True])
def test_the_committed_biped_files_are_what_the_generator_writes(toes):
    name = 'biped_spring_toes.xml' if toes else 'biped.xml'
    assert (BIPED / name).read_text() == _generator().biped_xml(toes=toes)


def _run(name, seconds, **overrides):
    sim = Simulation(load_scene(BIPED / name, {'zeta': 3.75, **overrides}))
    sim.step(int(round(seconds / sim.timestep)))
    return sim


@pytest.mark.parametrize('name', ['biped.xml', 'biped_spring_toes.xml'])
def test_the_biped_stands_from_its_keyframe_on_the_sand(name):
    """Set down from keyframe `stand` (spawn rest), its servos holding the pose: 2 s on its
    feet, upright, the feet a few millimetres in the sand (zeta A z = m g: 13 kg on 2 soles
    of 0.022 m^2 sinks ~1.5 mm), no other body touching it."""
    sim = _run(name, 2.0, **{'robot.keyframe': 'stand'})
    outcome = sim.outcome()
    assert not outcome['fell'] and outcome['fell_at_s'] is None
    assert outcome['max_tilt_deg'] < 5.0 and outcome['final_tilt_deg'] < 5.0
    deepest = outcome['deepest']
    assert deepest['body'].endswith(('_foot', '_toe')) and deepest['has_plates']
    assert 0.0005 < deepest['sinkage_m'] < 0.01
    assert outcome['max_uncovered_sinkage_m'] is None  # every collision body has plates
    assert outcome['words'].startswith('upright: base turned at most ')
    assert set(sim.sand_bodies) >= {'left_foot', 'right_foot'}
    assert {'trunk', 'left_shin', 'right_thigh'} <= set(sim.other_bodies)
    assert 'trunk' not in {b for bodies in sim.legs.values() for b in bodies}


def test_a_biped_pushed_over_lands_on_its_side_and_lies_on_the_sand():
    """Keyframe `leaning` (rolled 25 deg, beyond its feet), set down on the sand: it falls
    onto its side, where its trunk, thigh and shin carry it on their coarser plates: at
    rest (< 1 mm/s) with its lowest point within 3 cm of the surface, not under it, and the
    outcome says it fell, and when."""
    sim = _run('biped.xml', 3.0, **{'robot.keyframe': 'leaning', 'robot.spawn': 'drop:0'})
    outcome = sim.outcome()
    assert outcome['fell'] and 0.1 < outcome['fell_at_s'] < 2.0
    assert outcome['final_tilt_deg'] > 60.0 > TILT_LIMIT_DEG  # on its side
    lowest = sim._outcome.depths(sim.data, sim.engine.surface).max()
    assert -0.03 < lowest < 0.03
    assert outcome['deepest']['sinkage_m'] < 0.03 and outcome['deepest']['has_plates']
    base = sim.model.body('trunk').id
    speeds = []  # of each body's origin, m/s
    for body in range(1, sim.model.nbody):
        velocity = np.zeros(6)
        mujoco.mj_objectVelocity(sim.model, sim.data, mujoco.mjtObj.mjOBJ_BODY, body,
                                 velocity, 0)
        speeds.append(np.linalg.norm(velocity[3:]))
    assert max(speeds) < 1e-3, speeds  # at rest (~1e-5 m/s)
    assert sim.data.xpos[base, 2] < 0.25  # lying, not standing (0.74 m)
    assert outcome['words'].startswith(f"fell at t = {outcome['fell_at_s']:.2f} s: base turned ")
    assert outcome['words'].split('; ')[1] == 'lying on the sand'


def test_without_plates_on_its_other_bodies_a_fallen_biped_sinks_and_says_so():
    """rft.other_bodies_density_per_mm2: null, the old way: only the feet carry plates, so
    the fallen trunk passes through the sand; the outcome says how deep, of which body
    without plates."""
    sim = _run('biped.xml', 1.5, **{'robot.keyframe': 'leaning', 'robot.spawn': 'drop:0',
                                    'rft.other_bodies_density_per_mm2': None})
    outcome = sim.outcome()
    assert sim.other_bodies == () and outcome['fell']
    assert outcome['max_uncovered_sinkage_m'] > 0.05
    assert not outcome['deepest']['has_plates']
    assert '(no plates: it passed through)' in outcome['words']


def test_summary_json_carries_the_outcome_next_to_stable(tmp_path):
    """run_scene writes `outcome` (sim/outcome.py) with the keys others read, beside
    `stable`; the run's words are what it says."""
    import json

    from rft_sim_ros.sim.runner import run_scene
    run_scene(load_scene(BIPED / 'biped.xml', {'robot.keyframe': 'stand'}), tmp_path,
              duration=0.3, progress=False, plots=False)
    summary = json.loads((tmp_path / 'summary.json').read_text())
    keys = list(summary)
    assert keys.index('outcome') == keys.index('stable') + 1
    outcome = summary['outcome']
    assert set(outcome) == {'fell', 'fell_at_s', 'tilt_limit_deg', 'max_tilt_deg',
                            'final_tilt_deg', 'collapsed', 'collapsed_at_s', 'collapse_share',
                            'stance_height_set_down_m', 'min_stance_height_m', 'sank',
                            'sank_at_s', 'max_base_depth_m', 'final_base_speed_mps',
                            'deepest', 'unsettled_step_share', 'rows_handed_back_step_share',
                            'max_uncovered_sinkage_m', 'upside_down', 'upside_down_at_s',
                            'up_angle_set_down_deg', 'max_up_angle_deg', 'final_up_angle_deg',
                            'joint_past_limit', 'words'}
    assert set(outcome['deepest']) == {'body', 'sinkage_m', 'time_s', 'has_plates'}
    assert outcome['fell'] is False and outcome['tilt_limit_deg'] == 45.0
    assert outcome['collapsed'] is False and outcome['sank'] is False
    assert 0.5 < outcome['stance_height_set_down_m'] < 0.8  # (a 0.74 m trunk on its legs)
    assert summary['other_bodies'] and 'trunk' in summary['plates_per_body']


def test_the_walking_scenario_walks_the_biped_upright():
    """march.py (the humanoid walking case of the other bodies' cost bench): from keyframe
    `stand` it walks forward on the sand, upright, each foot in turn lifted out of it (its
    plates leave the sand) and set down, no other body touching it."""
    sim = _run('biped.xml', 1.0, **{'robot.keyframe': 'stand',
                                    'scenario': str(BIPED / 'march.py')})
    start = sim.data.xpos[sim.model.body('trunk').id].copy()
    feet = [sim.model.body(name).id for name in ('left_foot', 'right_foot')]
    lowest, highest = np.full(2, np.inf), np.full(2, -np.inf)
    for _ in range(40):  # 2 s, two gait cycles
        sim.step(int(round(0.05 / sim.timestep)))
        lowest = np.minimum(lowest, sim.data.xpos[feet, 2])
        highest = np.maximum(highest, sim.data.xpos[feet, 2])
    outcome = sim.outcome()
    assert not outcome['fell'] and outcome['max_tilt_deg'] < 10.0
    assert sim.data.xpos[sim.model.body('trunk').id, 0] - start[0] > 0.15  # ~0.12 m/s
    assert (highest - lowest > 0.015).all()  # each foot lifted
    assert outcome['deepest']['body'].endswith('_foot')
    assert outcome['deepest']['sinkage_m'] < 0.02  # (one sole bearing 13 kg, pushing off)
