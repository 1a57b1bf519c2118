"""One hexapod walking on one surface, stepping its sand engine on request and reporting the
CPU time of each step: the worker process of `terrain_cost`.

Run as a script (`python -P engine_step_worker.py OVERRIDES_JSON`, `-P` so that this folder
does not shadow imports) with PYTHONPATH naming the code to measure, which may be an older
checkout of this package (the code before the terrain work names its scene loader
`rft_sim_ros.sim.scene.load_scene`). It builds the `hexapod` scene with the overrides (its
walk made long enough for any run), steps it to `WALKING_S` into the walk, prints one JSON
line (the package it imported, plate count, steps per gait cycle), then answers each input
line `chunk` with one JSON line: the CPU time per engine step (s) of one gait cycle, and the
world x and y extents (m) the sand bodies' bounding spheres reached in all the worker's
cycles so far.

A chunk first runs the cycle as the scene does (`Simulation.step`, untimed), recording the
servo targets each engine step met, then replays those targets through the engine alone
(`SandEngine.step`: sand + MuJoCo) for the next cycle, timed with this process's CPU clock.
The gait is periodic, so the replayed targets are the ones the scene would have written.
"""
import json
import sys
import time

import numpy as np

#: s of sim time from the drop into the walk where measuring starts (settled and walking).
WALKING_S = 1.5


def _load_scene(name, overrides):
    try:
        from rft_sim_ros.scenes.config import load_scene
    except ImportError:  # the code before the terrain work
        from rft_sim_ros.sim.scene import load_scene
    return load_scene(name, overrides)


def main(overrides):
    answers, sys.stdout = sys.stdout, sys.stderr  # anything the code prints goes to stderr
    import rft_sim_ros
    from rft_sim_ros.sim.simulation import Simulation
    sim = Simulation(_load_scene('hexapod', {'cycles': 10000, **overrides}))
    engine, ctrl = sim.engine, sim.data.ctrl
    cycle = int(round(1.0 / (float(sim.scene.params['frequency']) * sim.timestep)))
    sim.step(int(round(WALKING_S / sim.timestep)))
    targets = np.zeros((cycle, ctrl.size))
    step = engine.step
    recorded = [0]
    radii = getattr(engine, 'radii', 0.0)  # (the code before the terrain work: origins)
    extent = np.array([[np.inf, -np.inf], [np.inf, -np.inf]])  # world [x, y] x [low, high]

    def note_extent():
        xy = sim.data.xpos[engine.body_ids, :2].T
        extent[:, 0] = np.minimum(extent[:, 0], np.min(xy - radii, axis=1))
        extent[:, 1] = np.maximum(extent[:, 1], np.max(xy + radii, axis=1))

    def recording_step():
        targets[recorded[0]] = ctrl
        recorded[0] += 1
        step()
        note_extent()

    print(json.dumps({'package': rft_sim_ros.__file__, 'plates': int(engine.plates_total),
                      'cycle_steps': cycle}), file=answers, flush=True)
    for line in sys.stdin:
        if line.strip() != 'chunk':
            break
        recorded[0] = 0
        engine.step = recording_step
        sim.step(cycle)
        engine.step = step
        started = time.process_time()
        for row in targets:
            ctrl[:] = row
            step()
        step_s = (time.process_time() - started) / cycle
        note_extent()  # (the timed cycle's end; its course is the next chunk's first cycle's)
        print(json.dumps({'step_s': step_s, 'extent_m': extent.tolist()}), file=answers,
              flush=True)


if __name__ == '__main__':
    main(json.loads(sys.argv[1]))
