"""The engine's table kernels compiled ahead of time for this machine, and whether a run can
use them. `rft-sim warmup` builds them (`prebuild`); a run that finds them current calls them
from a plain extension module and compiles or loads none of them through numba.

Which kernels: those that take their arrays as one `sand.array_table` table (the gather
kernels, the implicit steps, the plates' forces; `sand.engine.TABLE_KERNELS`). A function
compiled ahead has no dispatcher that checks the types of its arguments: numba's unboxing of
an array checks only its item size, not its dtype, rank or layout (given another it reads the
wrong memory). A table is always an int64 C-contiguous matrix, and its accessors check each
entry's element type and rank as the kernel reads it, so these are safe to call from Python.
They are also the kernels that take longest to compile: the implicit step alone takes 14 to
18 s of CPU on an AMD EPYC VM.

Where: `_prebuilt/<toolchain key>/` in the package's folder, one folder per `toolchain()`
(numba, numpy and Python versions, and the CPU name and instruction-set features numba
compiles for), so that environments sharing a checkout keep their own: an extension named
by the fingerprint of the kernels' sources (`kernel_cache.sources_fingerprint`) and
`build.json`, which names it and records those sources' fingerprint and their files' times
and sizes. A run uses the extension only where all of that still holds (`load`); otherwise,
with RFT_SIM_PREBUILT=0 in the environment, and under numba's debugging settings
(NUMBA_DISABLE_JIT, NUMBA_BOUNDSCHECK, which the extension was not built with), the numba
dispatchers run, as without it (`state` says why). Standard library, numba's configuration
and kernel_cache only: the engine imports this.
"""
import functools
import hashlib
import importlib.machinery
import importlib.util
import json
import os
import sys
from pathlib import Path

from .kernel_cache import PACKAGE, sources_fingerprint, sources_unchanged

#: The folder of the built extensions, one subfolder per `toolchain_key`.
FOLDER = PACKAGE / '_prebuilt'
#: The record of what an extension was built from, in its toolchain's folder.
RECORD = 'build.json'
#: Environment variable that turns the prebuilt kernels off where it is '0'.
SWITCH = 'RFT_SIM_PREBUILT'


def symbol(kernel):
    """The name the extension exports numba dispatcher `kernel` under."""
    return f'{kernel.py_func.__module__}.{kernel.py_func.__name__}'.replace('.', '__')


def module_name(fingerprint):
    """The extension's module name for sources of `fingerprint` (its file: this name and
    the interpreter's extension suffix)."""
    return f'rft_sim_ros_kernels_{fingerprint[:16]}'


def extension_file(folder, name):
    """The path of extension module `name` in `folder`."""
    return Path(folder) / (name + importlib.machinery.EXTENSION_SUFFIXES[0])


def toolchain():
    """{name: version} of what compiled code depends on besides its sources: numba, numpy,
    Python, and the CPU name and features numba compiles for (those of this machine, or
    NUMBA_CPU_NAME and NUMBA_CPU_FEATURES)."""
    import llvmlite.binding
    import numba
    import numpy
    from numba.core.codegen import get_host_cpu_features
    return {'numba': numba.__version__, 'numpy': numpy.__version__,
            'python': sys.version.split()[0],
            'cpu': numba.config.CPU_NAME or llvmlite.binding.get_host_cpu_name(),
            'cpu_features': get_host_cpu_features()}


def toolchain_key(tools):
    """A short hash of `tools` (a `toolchain()`): the name of their folder."""
    return hashlib.sha256(json.dumps(tools, sort_keys=True).encode()).hexdigest()[:16]


def _debugging():
    """The numba debugging setting in force that the extension was not built with, or ''."""
    import numba
    for name in ('DISABLE_JIT', 'BOUNDSCHECK'):
        if getattr(numba.config, name):
            return f'NUMBA_{name}'
    return ''


def _stale(kept):
    """Why the extension of record `kept` is not that of the current sources ('' when it
    is): their files' times and sizes as recorded, or else the same fingerprint."""
    stats = kept.get('stats')
    if not (stats and sources_unchanged(stats)) and kept.get('fingerprint') != (
            sources_fingerprint()):
        return 'built from other sources (they changed since)'
    return ''


@functools.lru_cache(maxsize=None)
def load():
    """(the extension module or None, why not: '' when loaded), for this process's
    `toolchain()` in `FOLDER`. Cached: the first answer holds for the process."""
    if os.environ.get(SWITCH, '1') == '0':
        return None, f'off ({SWITCH}=0)'
    debugging = _debugging()
    if debugging:
        return None, f'off ({debugging} is set)'
    folder = FOLDER / toolchain_key(toolchain())
    try:
        kept = json.loads((folder / RECORD).read_text())
    except (OSError, ValueError):
        return None, ('not built for this numba, numpy, Python and CPU (`rft-sim warmup` '
                      'builds them)')
    why = _stale(kept)
    if why:
        return None, f'{why}: `rft-sim warmup` builds them again'
    name = module_name(kept['fingerprint'])
    try:
        spec = importlib.util.spec_from_file_location(name, extension_file(folder, name))
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    except (ImportError, OSError) as error:
        return None, f'not loadable: {error}'
    return module, ''


def kernel(dispatcher):
    """The prebuilt function of numba dispatcher `dispatcher` where the current extension
    has it, else the dispatcher itself (same arguments, same results). Call it with what
    `sand.engine.TABLE_KERNELS` says only: it does not check its arguments' types."""
    module, _ = load()
    return getattr(module, symbol(dispatcher), dispatcher) if module else dispatcher


def has(dispatcher):
    """Whether a run calls `dispatcher`'s prebuilt function (`kernel`)."""
    return kernel(dispatcher) is not dispatcher


def state(*dispatchers):
    """One line: whether runs use the prebuilt kernels, and why not; given numba dispatchers,
    whether those are all prebuilt (an extension built before one of them was made a table
    kernel lacks it)."""
    module, why = load()
    if not module:
        return f'prebuilt kernels: {why}'
    lacking = [kernel.py_func.__name__ for kernel in dispatchers if not has(kernel)]
    return (f'prebuilt kernels: not built for {", ".join(lacking)} (`rft-sim warmup` builds '
            'them)' if lacking else 'prebuilt kernels: in use')
