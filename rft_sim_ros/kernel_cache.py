"""Is numba's on-disk cache of the compiled kernels cold? (ROS-free; the CLI and the node ask.)

The sand engine's kernels (`rft.kernel`, `sand.coupling`) and the gaits' (`scenes.gaits`,
`scenes.leg_kinematics`) are numba functions compiled with cache=True: the first run after
an install (or after their source changed) compiles them, which takes tens of seconds and
prints nothing; every later run loads them from the cache in about a second. `cold()` tells,
without compiling anything, whether the engine's start-up kernels are missing from the cache,
so that a caller can say so at once (`notice()`); `warm_up()` compiles every kernel ahead
(`rft-sim warmup`).

The cache is numba's: `__pycache__` beside the sources, or NUMBA_CACHE_DIR. A kernel counts as
cached when numba's index for it holds at least one compiled signature for its current source.
"""
import importlib

#: Modules holding the package's cached numba kernels.
KERNEL_MODULES = ('rft_sim_ros.rft.kernel', 'rft_sim_ros.sand.coupling',
                  'rft_sim_ros.scenes.gaits', 'rft_sim_ros.scenes.leg_kinematics')

#: The kernels every scene's engine loads at start-up (`SandEngine._load_kernels`; they call
#: the rest of the implicit step's kernels): what a cold start spends its time compiling.
START_UP_KERNELS = ('rft_sim_ros.sand.coupling.gather_plates',
                    'rft_sim_ros.sand.coupling.implicit_sand_step')

#: Seconds a cold start takes on the development machine (2-core AMD EPYC VM: a plate_drop
#: run, cold cache, 52 s in all against 2.6 s warm); said in the notice as an order of size.
COLD_START_S = 50


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


def _is_cached(dispatcher):
    """Whether numba's on-disk index holds a compiled signature of `dispatcher` for its
    current source (an index left by older source or another numba version counts as none).
    Where numba's cache cannot be read this way, True: nothing is claimed."""
    try:
        return bool(dispatcher._cache._cache_file._load_index())
    except (AttributeError, OSError, EOFError, ValueError):
        return True


def uncached(names=None):
    """Qualified names (of `names`, default: all kernels) that the cache does not hold."""
    kernels = cached_kernels()
    return [name for name in (names or kernels) if not _is_cached(kernels[name])]


def cold():
    """Whether the engine's start-up kernels still have to be compiled (first run)."""
    return bool(uncached(START_UP_KERNELS))


def notice():
    """The line to show before a cold start, or None when the cache is warm."""
    if not cold():
        return None
    return (f'compiling kernels, first run only, ~{COLD_START_S} s '
            '(`rft-sim warmup` does it ahead)')


def warm_up(log=print):
    """Compile (or load) every kernel: short runs of the scenes and settings that use them.
    Returns the qualified names still not cached (none, unless a kernel went unused)."""
    import numpy as np

    from .rft.kernel import plate_forces_compiled
    from .scenes.config import load_scene
    from .sim.simulation import Simulation
    runs = (('hexapod', {}),                      # implicit engine step, tripod gait
            ('articulated_leg', {}),              # leg inverse kinematics
            ('plate_drop', {'rft.low_velocity.method': 'ema'}))  # the explicit path
    for scene, overrides in runs:
        log(f'warmup: {scene} {overrides or ""}'.rstrip())
        Simulation(load_scene(scene, overrides)).step(2)
    down = np.array([[0.0, 0.0, -1.0]])  # the compiled law on its own (one plate)
    plate_forces_compiled(np.zeros((1, 3)), down, np.ones(1), down, 1.0, 0.0, 1.0, 1.0, 0.0)
    return uncached()
