"""Start-up time of a scene: imports, model, plates, and compiling or loading the kernels.

Measured in fresh Python processes: "cold" with an empty numba cache (the kernels compile),
"warm" with the cache the cold run left (what every later start sees).
"""
import json
import os
import subprocess
import sys
import tempfile

_PROBE = r'''
import json, sys, time
started = time.perf_counter()
from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sim.simulation import Simulation
imported = time.perf_counter()
sim = Simulation(load_scene(sys.argv[1]))
built = time.perf_counter()
sim.step(2)
stepped = time.perf_counter()
print(json.dumps({'import_s': imported - started, 'build_s': built - imported,
                  'first_steps_s': stepped - built, 'total_s': stepped - started}))
'''


def startup_times(scene='hexapod', warm_runs=3):
    """{'cold': {...}, 'warm': [{...}, ...]}: seconds to import, build the scene and take the
    first steps, in fresh processes with an empty and then a filled numba cache."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)

        def probe():
            done = subprocess.run([sys.executable, '-c', _PROBE, scene], env=env, check=True,
                                  capture_output=True, text=True)
            return json.loads(done.stdout.strip().splitlines()[-1])

        cold = probe()
        warm = [probe() for _ in range(warm_runs)]
    return {'scene': scene, 'cold': cold, 'warm': warm,
            'warm_total_median_s': sorted(w['total_s'] for w in warm)[len(warm) // 2]}
