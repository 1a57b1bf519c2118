"""How step cost grows with plates: linear in plates in the sand, ~zero for plates above it.

A thin square slab (the plate_press scene, 0.5 m side) carries N plates; pressed into the
sand about half of them (its bottom face) lead, and the step cost is timed against that
count. The same slab held 1 m above the sand measures what plates out of the sand cost.
A second check doubles the plates of hexapod bodies that never reach the sand.
"""
import time

import numpy as np

from ..scenes.hexapod import LEG_NAMES
from ..scenes.config import load_scene
from ..sim.simulation import Simulation


def _time_steps(sim, steps, repeats=5):
    """Median wall time per step (s) over `repeats` chunks of `steps`."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        sim.step(steps)
        times.append((time.perf_counter() - start) / steps)
    return float(np.median(times))


def slab_scaling(plate_counts=(1000, 2000, 5000, 10000, 20000, 50000), steps=200):
    """Step cost (s) against plates in the sand, and with the same slab above the sand."""
    rows = []
    for count in plate_counts:
        common = {'side': 0.5, 'rft.plates_per_body': count}
        pressed = Simulation(load_scene('plate_press', {**common, 'start_height': 0.0,
                                                        'speed': 0.01}))
        pressed.step(int(round(0.5 / pressed.timestep)))  # 5 mm deep
        in_sand = _time_steps(pressed, steps)
        active = int(pressed.engine.plates_active)
        above = Simulation(load_scene('plate_press', {**common, 'start_height': 1.0,
                                                      'speed': 1e-6}))
        rows.append({'plates_total': pressed.engine.plates_total, 'plates_in_sand': active,
                     'step_s_in_sand': in_sand, 'step_s_above_sand': _time_steps(above, steps)})
    active = np.array([r['plates_in_sand'] for r in rows], dtype=float)
    cost = np.array([r['step_s_in_sand'] for r in rows])
    slope, intercept = np.polyfit(active, cost, 1)
    fitted = slope * active + intercept
    r_squared = 1.0 - np.sum((cost - fitted) ** 2) / np.sum((cost - cost.mean()) ** 2)
    return {'rows': rows, 'seconds_per_plate_in_sand': float(slope),
            'fixed_step_s': float(intercept), 'linear_fit_r2': float(r_squared)}


def idle_plates_cost(extra_plates=(500, 1000), chunks=7, chunk_steps=500, settle_steps=2500):
    """Hexapod step cost with its base, payload box and coxas (bodies that never reach the
    sand) also carrying plates, at each count in `extra_plates` per such body: the cost
    must not grow with plates that stay out of the sand."""
    idle = ['base_link', 'payload'] + [f'{leg}_coxa' for leg in LEG_NAMES]
    sims = []
    for count in extra_plates:
        scene = load_scene('hexapod')
        overrides = {'rft.sand_bodies': list(scene.sand_bodies) + idle,
                     'rft.plates': {body: count for body in idle}}
        sim = Simulation(load_scene('hexapod', overrides))
        sim.step(settle_steps)
        sims.append(sim)
    times = [[] for _ in sims]
    for _ in range(chunks):  # interleaved, so that machine noise hits all alike
        for sim, record in zip(sims, times):
            start = time.perf_counter()
            sim.step(chunk_steps)
            record.append((time.perf_counter() - start) / chunk_steps)
    medians = [float(np.median(t)) for t in times]
    return {'idle_bodies': idle, 'plates_per_idle_body': list(extra_plates),
            'idle_plates_total': [len(idle) * n for n in extra_plates],
            'step_s': medians, 'ratio_last_to_first': medians[-1] / medians[0]}
