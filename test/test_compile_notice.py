"""The start-up notice that the kernels compile: shown exactly when numba's cache lacks them."""
import os
import subprocess
import sys

from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sim.simulation import Simulation, compile_notice

_PROBE = ('from rft_sim_ros.scenes.config import load_scene\n'
          'from rft_sim_ros.sim.simulation import compile_notice\n'
          'print(compile_notice(load_scene("plate_drop")))\n')


def test_an_empty_cache_gets_the_notice(tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    done = subprocess.run([sys.executable, '-c', _PROBE], env=env, capture_output=True,
                          text=True, check=True, timeout=120)
    assert done.stdout.strip().startswith('compiling kernels, first run only, ~')
    assert done.stdout.strip().endswith(' s')


def test_a_filled_cache_gets_none():
    scene = load_scene('plate_drop')
    Simulation(scene)               # loads (or compiles and caches) the kernels
    assert compile_notice(scene) is None
    ema = load_scene('plate_drop', {'rft.low_velocity.method': 'ema'})
    Simulation(ema)
    assert compile_notice(ema) is None
