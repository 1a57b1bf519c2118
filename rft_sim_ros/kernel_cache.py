"""The package's compiled kernels in numba's on-disk cache: which are there, and warming it.

The sand engine's kernels (`rft.kernel`, `sand.coupling`, `sand.deformable`) and the gaits'
(`scenes.gaits`, `scenes.leg_kinematics`) are numba functions compiled with cache=True: the
first run after an install (or after their source changed) compiles them, about 12 s on two
cores (`BackgroundCompile` puts a share in a second process); every later run loads them
from the cache in a fraction of a second. numba checks only the source file of each kernel:
after editing a module that a kernel inlines from another file (e.g. `sand/surface_kernels.py`
into the gather kernels of `sand/coupling.py`), clear the cache (`__pycache__/*.nb*`) or touch
that file. `sand.engine.kernels_cached` (and `sim.simulation.compile_notice`, which the CLI and
the node show) asks `is_cached` about the kernels one engine needs (one gather kernel per
kind of surface); `warm_up()` compiles every kernel ahead (`rft-sim warmup`).

The cache is numba's: `__pycache__` beside the sources, or NUMBA_CACHE_DIR. A kernel counts as
cached when numba's index for it holds at least one compiled signature for its current source.
"""
import importlib
from pathlib import Path

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
    """Compile (or load) every kernel: short runs of the scenes and settings that use them,
    with the gather kernels of the other surfaces compiled meanwhile in a second process.
    Returns the qualified names still not cached (none, unless a kernel went unused)."""
    import tempfile

    import numpy as np

    from .rft.kernel import plate_forces_compiled
    from .sand import coupling
    from .sand.array_table import TABLE_SIGNATURE
    from .scenes.config import load_scene
    from .sim.simulation import Simulation
    others = [(kernel, TABLE_SIGNATURE) for kernel in (
        coupling.gather_slope, coupling.gather_grid, coupling.gather_deformable)]

    def run(scene, overrides):
        log(f'warmup: {scene} {overrides or ""}'.rstrip())
        Simulation(load_scene(scene, overrides)).step(2)

    with tempfile.TemporaryDirectory() as folder, BackgroundCompile(others) as compiling:
        run('hexapod', {})                      # implicit engine step (plane), tripod gait
        run('articulated_leg', {})              # leg inverse kinematics
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
    return uncached()


class BackgroundCompile:
    """Kernels compiled into numba's on-disk cache by another Python process, while this one
    goes on (compiling others): on two cores a cold start takes about as long as its
    longest share instead of the sum. numba compiles in pure Python under a process-wide
    lock, so threads cannot do this.

    kernels: (numba dispatcher with cache=True, signature) pairs; signature: numba's text of
    the argument types, e.g. '(float64, int64[:, ::1])'. The child sees the same cache
    (it inherits NUMBA_CACHE_DIR) and runs this module (`python -m rft_sim_ros.kernel_cache
    module:name=signature ...`). `wait()` returns once it is done; a kernel it could not
    compile is then simply compiled here, at its first call, so a failed child costs time,
    never correctness; so does a child that cannot start (no usable `sys.executable`, e.g.
    in an embedding application). Used as a context manager, a child still running when the
    block ends (e.g. this process is interrupted while compiling its own share) is killed.
    """

    def __init__(self, kernels):
        import subprocess
        import sys
        self.kernels = [kernel for kernel, _ in kernels]
        specs = [f'{kernel.py_func.__module__}:{kernel.py_func.__name__}={signature}'
                 for kernel, signature in kernels]
        self._child, self._not_started = None, None
        try:
            self._child = subprocess.Popen(
                [sys.executable, '-m', 'rft_sim_ros.kernel_cache', *specs],
                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        except OSError as error:
            self._not_started = f'no compiling process: {error}'

    def __enter__(self):
        return self

    def __exit__(self, *exception):
        if self._child is not None and self._child.poll() is None:
            self._child.kill()
            self._child.communicate()

    def wait(self):
        """Wait for the child; (True, '') when it compiled every kernel and the cache now
        holds them, else (False, why: its error output, the kernels the cache lacks, or why
        it did not start)."""
        if self._child is None:
            return False, self._not_started
        try:
            _, error = self._child.communicate()
        except BaseException:  # e.g. KeyboardInterrupt: do not leave the child compiling
            self._child.kill()
            self._child.wait()
            raise
        missing = [kernel.py_func.__qualname__ for kernel in self.kernels
                   if not is_cached(kernel)]
        if self._child.returncode == 0 and not missing:
            return True, ''
        why = error.decode(errors='replace').strip().splitlines()[-1:] or [
            f'not cached: {", ".join(missing)}']
        return False, why[0]


def load(kernel, signature):
    """Load `kernel` (a numba dispatcher) for `signature` (numba's text of the argument
    types) from the cache, or compile it, without running it. (The text is turned into
    types first: numba keys its cache by the argument types a call would give, and would
    miss an entry under the text.)"""
    from numba.core import sigutils
    arguments, _ = sigutils.normalize_signature(signature)
    kernel.compile(arguments)


def _compile_main(specs):
    """The child of `BackgroundCompile`: compile each 'module:name=signature' of `specs`."""
    for spec in specs:
        target, signature = spec.split('=', 1)
        module_name, name = target.split(':')
        load(getattr(importlib.import_module(module_name), name), signature)


if __name__ == '__main__':
    import sys
    _compile_main(sys.argv[1:])
