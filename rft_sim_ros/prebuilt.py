"""The engine's table kernels compiled ahead of time for this machine, and whether a run can
use them. `rft-sim warmup` builds them (`prebuild`); a run that finds them current calls them
from a plain extension module and compiles or loads none of them through numba.

Which kernels: those that take their arrays as one `sand.array_table` table (the gather
kernels, the implicit steps; `sand.engine.TABLE_KERNELS`). A kernel compiled ahead has no
dispatcher that checks the types of its arguments (given an array of another dtype or rank it
would read the wrong memory), but a table's accessors check each entry's element type and rank
as the kernel reads it, so these are safe to call from Python. They are also the kernels that
take longest to compile: the implicit step alone takes 14-18 s of CPU on an AMD EPYC VM.

Where: `_prebuilt/` in the package's folder: the extension (built by numba's ahead-of-time
compiler for this machine's CPU) and `build.json`, what it was built from: the fingerprint of
the kernels' sources (`kernel_cache.sources_fingerprint`) and their modification times and
sizes, numba's, numpy's and Python's versions, and the CPU (model and features). A run uses the
extension only where all of those still hold (`load`): otherwise, and with RFT_SIM_PREBUILT=0
in the environment, the numba dispatchers, as without it (`state` says why). Standard library
and kernel_cache only: the engine imports this.
"""
import functools
import hashlib
import importlib.machinery
import importlib.util
import json
import os
import platform
import sys
from pathlib import Path

from .kernel_cache import PACKAGE, source_stats, sources_fingerprint, sources_unchanged

#: The folder of the built extension and its record.
FOLDER = PACKAGE / '_prebuilt'
#: The extension's module name (its file: this and the interpreter's extension suffix).
MODULE_NAME = 'rft_sim_ros_kernels'
#: The record of what the extension was built from.
RECORD = 'build.json'
#: Environment variable that turns the prebuilt kernels off where it is '0'.
SWITCH = 'RFT_SIM_PREBUILT'


def symbol(kernel):
    """The name the extension exports numba dispatcher `kernel` under."""
    return f'{kernel.py_func.__module__}.{kernel.py_func.__name__}'.replace('.', '__')


def cpu_identity():
    """A short hash of this machine's CPU model and instruction-set features (what code
    compiled for this CPU may use): /proc/cpuinfo where there is one."""
    try:
        with open('/proc/cpuinfo') as info:
            lines = [line for line in info.read().splitlines()
                     if line.split(':')[0].strip() in ('model name', 'flags', 'Features')]
        text = '\n'.join(sorted(set(lines)))
    except OSError:
        text = f'{platform.machine()} {platform.processor()}'
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def toolchain():
    """{name: version} of what the extension's code depends on besides its sources."""
    import numba
    import numpy
    return {'numba': numba.__version__, 'numpy': numpy.__version__,
            'python': sys.version.split()[0], 'cpu': cpu_identity()}


def record(folder, built_s):
    """The record a build from the current sources keeps (`RECORD`): fingerprint, sources'
    modification times and sizes, `toolchain()`, and how long the build took (wall s)."""
    from .kernel_cache import kernel_sources
    return {'fingerprint': sources_fingerprint(), 'stats': source_stats(kernel_sources()),
            **toolchain(), 'module': extension_file(folder).name, 'built_s': round(built_s, 1)}


def extension_file(folder=FOLDER):
    """The extension's path in `folder`."""
    return Path(folder) / (MODULE_NAME + importlib.machinery.EXTENSION_SUFFIXES[0])


def _stale(kept):
    """Why the extension of record `kept` does not fit this process ('' when it does)."""
    now = toolchain()
    for name in ('numba', 'numpy', 'python', 'cpu'):
        if kept.get(name) != now[name]:
            return f'built for another {name} ({kept.get(name)}, now {now[name]})'
    if not sources_unchanged(kept.get('stats') or {}) and (
            kept.get('fingerprint') != sources_fingerprint()):
        return 'built from other sources (they changed since)'
    return ''


@functools.lru_cache(maxsize=None)
def load(folder=None):
    """(the extension module or None, why not: '' when loaded) in `folder` (default
    `FOLDER`). Cached: the first answer holds for the process."""
    folder = FOLDER if folder is None else folder
    if os.environ.get(SWITCH, '1') == '0':
        return None, f'off ({SWITCH}=0)'
    try:
        kept = json.loads((Path(folder) / RECORD).read_text())
    except (OSError, ValueError):
        return None, 'not built (`rft-sim warmup` builds them)'
    why = _stale(kept)
    if why:
        return None, f'{why}: `rft-sim warmup` builds them again'
    path = extension_file(folder)
    try:
        spec = importlib.util.spec_from_file_location(MODULE_NAME, path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    except (ImportError, OSError) as error:
        return None, f'not loadable: {error}'
    return module, ''


def kernel(dispatcher):
    """The prebuilt function of numba dispatcher `dispatcher` where the current extension
    has it, else the dispatcher itself (same arguments, same results)."""
    module, _ = load()
    return getattr(module, symbol(dispatcher), dispatcher) if module else dispatcher


def has(dispatcher):
    """Whether a run calls `dispatcher`'s prebuilt function (`kernel`)."""
    return kernel(dispatcher) is not dispatcher


def state():
    """One line: whether runs use the prebuilt kernels, and why not."""
    module, why = load()
    return 'prebuilt kernels: in use' if module else f'prebuilt kernels: {why}'
