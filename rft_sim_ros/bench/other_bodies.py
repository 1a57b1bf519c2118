"""What the other bodies' plates (rft.other_bodies_density_per_mm2) cost while they stay
above the sand: step cost of a robot with them against the same robot without (null), both
built in one process and stepped in alternating chunks so that a loaded machine's noise hits
both alike; process CPU time per chunk, the median of the per-pair ratios and the ratio of
the least per-step times (the chunks least disturbed) reported, and the start-up (building
the Simulation) of each.

    python -m rft_sim_ros.bench.other_bodies [scene-or-robot-file ...]

Default cases: the hexapod and the bundled quadruped standing (gait none) and walking, and
the bipedal test robot (test/robots/biped) standing from its keyframe and walking (its
scenario march.py).
"""
import statistics
import sys
import time
from pathlib import Path

from ..scenes.config import load_scene
from ..sim.simulation import Simulation

#: (label, scene or robot file, overrides, sim seconds stepped before measuring)
CASES = (
    ('hexapod standing', 'hexapod', {'gait': 'none'}, 1.5),
    ('hexapod walking', 'hexapod', {}, 2.0),
    ('quadruped standing', 'quadruped', {'gait': 'none'}, 1.5),
    ('quadruped walking', 'quadruped', {}, 2.0),
)
BIPED = Path(__file__).resolve().parents[2] / 'test' / 'robots' / 'biped' / 'biped.xml'
if BIPED.is_file():  # (a source checkout)
    CASES += (('biped standing', str(BIPED), {'robot.keyframe': 'stand'}, 1.0),
              ('biped walking', str(BIPED), {'robot.keyframe': 'stand',
                                             'scenario': str(BIPED.with_name('march.py'))},
               1.5))
WITHOUT = {'rft.other_bodies_density_per_mm2': None}


def _build(scene, overrides):
    started = time.process_time()
    sim = Simulation(load_scene(scene, overrides))
    return sim, time.process_time() - started


def step_cost_ratio(scene, overrides, warm_s, chunks=20, chunk_steps=300):
    """{'ratio': median over chunk pairs of the CPU time per step with / without the other
    bodies' plates, 'least_ratio': the least CPU time per step with / the least without,
    'with_us', 'without_us': median CPU us per step, 'startup_first_s': CPU s of a first
    build with them (their plates made where not cached yet), 'startup_with_s',
    'startup_without_s': CPU s to build each (plates cached), 'other_plates': the other
    bodies' plates, 'others_in_sand': largest plates in the sand during the chunks of the
    run with them, minus the run without (0: they stayed above it)}."""
    first = _build(scene, overrides)[1]  # (the other bodies' plates made, if not cached)
    with_sim, startup_with = _build(scene, overrides)
    without_sim, startup_without = _build(scene, {**overrides, **WITHOUT})
    for sim in (with_sim, without_sim):
        sim.step(int(round(warm_s / sim.timestep)))
    costs = {id(with_sim): [], id(without_sim): []}
    extra = 0
    for _ in range(chunks):
        for sim in (with_sim, without_sim):
            started = time.process_time()
            sim.step(chunk_steps)
            costs[id(sim)].append((time.process_time() - started) / chunk_steps)
        extra = max(extra, with_sim.engine.plates_active - without_sim.engine.plates_active)
    ratios = [a / b for a, b in zip(costs[id(with_sim)], costs[id(without_sim)])]
    return {'ratio': statistics.median(ratios),
            'least_ratio': min(costs[id(with_sim)]) / min(costs[id(without_sim)]),
            'with_us': 1e6 * statistics.median(costs[id(with_sim)]),
            'without_us': 1e6 * statistics.median(costs[id(without_sim)]),
            'startup_first_s': first, 'startup_with_s': startup_with, 'startup_without_s': startup_without,
            'other_plates': with_sim.engine.plates_total - without_sim.engine.plates_total,
            'others_in_sand': extra}


def main(argv):
    cases = [(name, name, {}, 1.5) for name in argv] or CASES
    print('| case | other plates | in sand | CPU us/step with | without | median ratio | '
          'least ratio | start-up first / with / without (CPU s) |')
    print('|---|---|---|---|---|---|---|---|')
    for label, scene, overrides, warm_s in cases:
        r = step_cost_ratio(scene, overrides, warm_s)
        print(f"| {label} | {r['other_plates']} | {r['others_in_sand']} | {r['with_us']:.1f} | "
              f"{r['without_us']:.1f} | {r['ratio']:.3f} | {r['least_ratio']:.3f} | "
              f"{r['startup_first_s']:.2f} / "
              f"{r['startup_with_s']:.2f} / {r['startup_without_s']:.2f} |", flush=True)


if __name__ == '__main__':
    main(sys.argv[1:])
