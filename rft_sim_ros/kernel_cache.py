"""The package's compiled kernels in numba's on-disk cache: which are there, and warming it.

The sand engine's kernels (`rft.kernel`, `sand.coupling`, `sand.deformable`) and the gaits'
(`scenes.gaits`, `scenes.leg_kinematics`) are numba functions compiled with cache=True: the
first run after an install (or after their source changed) compiles them, which takes tens of seconds; every
later run loads them from the cache in about a second. `sand.engine.kernels_cached` (and
`sim.simulation.compile_notice`, which the CLI and the node show) asks `is_cached` about the
kernels one engine needs; `warm_up()` compiles every kernel ahead (`rft-sim warmup`).

The cache is numba's: `__pycache__` beside the sources, or NUMBA_CACHE_DIR. A kernel counts as
cached when numba's index for it holds at least one compiled signature for its current source.
"""
import importlib

#: Modules holding the package's cached numba kernels.
KERNEL_MODULES = ('rft_sim_ros.rft.kernel', 'rft_sim_ros.sand.coupling',
                  'rft_sim_ros.sand.deformable', 'rft_sim_ros.scenes.gaits',
                  'rft_sim_ros.scenes.leg_kinematics')


def is_cached(kernel):
    """Whether numba's on-disk index holds a compiled signature of the numba dispatcher
    `kernel` for its current source (an index left by older source or another numba version
    counts as none)."""
    return bool(kernel._cache._cache_file._load_index())


def cached_kernels():
    """{qualified name: numba dispatcher} of every cached, separately compiled kernel (numba
    never compiles inline='always' helpers on their own: they are left out)."""
    from numba.core.caching import NullCache
    from numba.core.dispatcher import Dispatcher
    kernels = {}
    for module_name in KERNEL_MODULES:
        module = importlib.import_module(module_name)
        for name, value in vars(module).items():
            if (isinstance(value, Dispatcher) and value.__module__ == module_name
                    and not isinstance(value._cache, NullCache)
                    and value.targetoptions.get('inline', 'never') == 'never'):
                kernels[f'{module_name}.{name}'] = value
    return kernels


def uncached():
    """Qualified names of the kernels that the cache does not hold."""
    return [name for name, kernel in cached_kernels().items() if not is_cached(kernel)]


def warm_up(log=print):
    """Compile (or load) every kernel: short runs of the scenes and settings that use them.
    Returns the qualified names still not cached (none, unless a kernel went unused)."""
    import numpy as np

    from .rft.kernel import plate_forces_compiled
    from .scenes.config import load_scene
    from .sim.simulation import Simulation
    runs = (('hexapod', {}),                      # implicit engine step, tripod gait
            ('articulated_leg', {}),              # leg inverse kinematics
            ('plate_drop', {'rft.low_velocity.method': 'ema'}),  # the explicit path
            ('plate_drop', {'sand.deformable.enabled': True}))  # deformable sand
    for scene, overrides in runs:
        log(f'warmup: {scene} {overrides or ""}'.rstrip())
        Simulation(load_scene(scene, overrides)).step(2)
    down = np.array([[0.0, 0.0, -1.0]])  # the compiled law on its own (one plate)
    plate_forces_compiled(np.zeros((1, 3)), down, np.ones(1), down, 1.0, 0.0, 1.0, 1.0, 0.0)
    return uncached()
