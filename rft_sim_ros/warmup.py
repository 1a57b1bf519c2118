"""`rft-sim warmup`: every compiled kernel of the package into numba's on-disk cache ahead of
a first run, by short runs of the scenes and settings that use them; then the kernels a run
calls built ahead of time for this machine (`prebuild`, `prebuilt`).

This sits beside the CLI, above the simulation it runs; the cache bookkeeping the kernel
modules themselves need (`kernel_cache`) sits below them and imports none of the package.
"""
import contextlib
import importlib
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from .kernel_cache import KERNEL_MODULES, PACKAGE, BackgroundCompile, is_cached, module_kernels
from .kernel_names import GATHER_DEFORMABLE, GATHERS, STEPS, TABLE_KERNELS
from .prebuilt import SWITCH, dispatcher, load
from .rft.kernel import plate_forces_compiled
from .scenes.config import load_scene
from .sim.simulation import Simulation


#: The table kernels (`kernel_names.TABLE_KERNELS`) that `warm_up`'s first runs do not step
#: with: the other surfaces' gathers and the implicit step with elliptic cones, compiled in
#: a second process while those runs compile theirs (the runs after load them).
BACKGROUND = (GATHERS['slope'], GATHERS['grid'], GATHER_DEFORMABLE, STEPS['cones'])


def cached_kernels():
    """{qualified name: numba dispatcher} of every cached, separately compiled kernel."""
    kernels = {}
    for module_name in KERNEL_MODULES:
        module = importlib.import_module(module_name)
        kernels.update({f'{module_name}.{name}': kernel
                        for name, kernel in module_kernels(module_name, vars(module)).items()})
    return kernels


def uncached():
    """Qualified names of the kernels that the cache does not hold."""
    return [name for name, kernel in cached_kernels().items() if not is_cached(kernel)]


@contextlib.contextmanager
def _numba_kernels_only():
    """Runs within call numba's kernels, not prebuilt ones (which would leave those out of
    numba's cache, from which the build takes them)."""
    previous = os.environ.get(SWITCH)
    os.environ[SWITCH] = '0'
    load.cache_clear()
    try:
        yield
    finally:
        if previous is None:
            del os.environ[SWITCH]
        else:
            os.environ[SWITCH] = previous
        load.cache_clear()


def warm_up(log=print):
    """Compile (or load) every kernel: short runs of the scenes and settings that use them,
    with the gather kernels of the other surfaces and the implicit step with elliptic cones
    compiled meanwhile in a second process; the message types a bag records into the user's
    cache (`ros.jazzy_types`, so that a first recorded run does not load rosbags' whole
    Jazzy store).
    Then builds the prebuilt kernels (`prebuild`); where that fails (e.g. no C
    compiler), says why and goes on: runs then load them from numba's cache, as before.
    Returns (the qualified names still not cached (none, unless a kernel went unused),
    one line on the prebuilt kernels: `prebuilt.state`, or why the build failed)."""
    signatures = dict(TABLE_KERNELS)
    others = [(dispatcher(name), signatures[name]) for name in BACKGROUND]

    def run(scene, overrides):
        log(f'warmup: {scene} {overrides or ""}'.rstrip())
        Simulation(load_scene(scene, overrides)).step(2)

    with tempfile.TemporaryDirectory() as folder, BackgroundCompile(others) as compiling, \
            _numba_kernels_only():
        run('hexapod', {})                      # implicit step with rows (plane), tripod gait
        run('articulated_leg', {})              # leg inverse kinematics
        run('quadruped', {})                    # the trot's targets
        run('plate_drop', {})                   # the implicit step without rows
        run('plate_drop', {'rft.low_velocity.method': 'ema'})  # the explicit path
        compiling.wait()  # (a kernel it did not cache compiles in its run below)
        level = Path(folder) / 'level.npy'  # a height grid (of the plane's height)
        np.save(level, np.zeros((3, 3)))
        run('plate_drop', {'sand.surface.type': 'slope'})  # the other surfaces' gathers
        run('plate_drop', {'sand.surface.type': 'grid', 'sand.surface.file': str(level),
                           'sand.surface.size': [1.0, 1.0]})
        run('plate_drop', {'sand.deformable.enabled': True})  # and deformable sand's
    down = np.array([[0.0, 0.0, -1.0]])  # the compiled law on its own (one plate)
    plate_forces_compiled(np.zeros((1, 3)), down, np.ones(1), down, 1.0, 0.0, 1.0, 1.0, 0.0)
    from .ros.jazzy_types import typestore_for  # (the bag's types, into the user's cache)
    from .ros.topics import RECORDABLE_TYPES
    typestore_for(RECORDABLE_TYPES)
    log('warmup: the kernels a run calls, ahead of time for this CPU')
    return uncached(), prebuild()


def prebuild():
    """Build the prebuilt kernels in a second process (`python -m rft_sim_ros.prebuild`:
    it loads the kernels from numba's cache, which this process has compiled some of); one
    line: what it printed (`prebuilt.state`), or why it failed (e.g. no C compiler: runs then
    load the kernels from numba's cache)."""
    try:
        done = subprocess.run([sys.executable, '-m', 'rft_sim_ros.prebuild'],
                              capture_output=True, text=True, stdin=subprocess.DEVNULL,
                              cwd=PACKAGE.parent)  # (this package, not one in the cwd)
    except OSError as error:  # (no usable sys.executable, e.g. an embedding application)
        return f'prebuilt kernels: not built (no building process: {error})'
    load.cache_clear()
    if done.returncode == 0:
        return done.stdout.strip().splitlines()[-1]
    why = done.stderr.strip().splitlines()[-1:] or [f'exit status {done.returncode}']
    return f'prebuilt kernels: not built ({why[0]})'
