"""The kernels a run calls from Python compiled ahead of time for this machine, and whether a
run can use them. `rft-sim warmup` builds them (`prebuild`); a run that finds them current
calls them from a plain extension module and compiles, loads or imports nothing of numba's.

Which kernels: every numba kernel the sand engine and the built-in gaits call from Python
(`kernel_names.PREBUILT`): the gather kernels, the implicit steps and the plates' forces,
which take their arrays as one `sand.array_table` table, and the constraint rows' and the
gaits' kernels, which take arrays and numbers. A function compiled ahead has no dispatcher
that checks the types of its arguments: numba's unboxing of an array checks only its item
size, not its dtype, rank or layout (given another it reads the wrong memory). So each is
called through a check of every argument against the types it was built for (`checked`),
and arguments of other types go to its numba dispatcher, as a call from Python always has;
a table's own entries are checked by the kernel as it reads them. They include the kernels
that take longest to compile (the implicit step alone: 14 to 18 s of CPU on an AMD EPYC VM).

Where: `_prebuilt/<toolchain key>/` in the package's folder, one folder per `toolchain()`
(numba, numpy and Python versions, the CPU name and instruction-set features, numba's CPU
settings), so that environments sharing a checkout keep their own: an extension named by the
fingerprint of the kernels' sources (`kernel_cache.sources_fingerprint`) and `build.json`,
which names it and records those sources' fingerprint, their files' times and sizes, and
each kernel's argument types. A run uses the extension only where all of that still holds
(`load`); otherwise, with RFT_SIM_PREBUILT=0 in the environment, under numba's debugging
settings (NUMBA_DISABLE_JIT, NUMBA_BOUNDSCHECK, which the extension was not built with) and
with a numba configuration file in the working folder, the numba dispatchers run, as
without it (`state` says why).

This module imports neither numba nor the kernels' modules (llvmlite only, for the CPU), so
that a run whose kernels are all prebuilt starts without numba (its import, 0.3 to 0.5 s,
and its first load of a kernel, as much again): kernels are named by their dotted path
(`kernel_names`), and `dispatcher` imports one's module where a run needs numba's. Standard
library, numpy and kernel_cache besides: the engine and the gaits import this.
"""
import functools
import hashlib
import importlib.machinery
import importlib.util
import json
import os
import re
import sys
from pathlib import Path

import numpy as np

from .kernel_cache import PACKAGE, sources_fingerprint, sources_unchanged
from .kernel_names import PREBUILT
from .kernel_names import function as function_name

#: The folder of the built extensions, one subfolder per `toolchain_key`.
FOLDER = PACKAGE / '_prebuilt'
#: The record of what an extension was built from, in its toolchain's folder.
RECORD = 'build.json'
#: Environment variable that turns the prebuilt kernels off where it is '0'.
SWITCH = 'RFT_SIM_PREBUILT'
#: numba's configuration file, read from the working folder.
CONFIG_FILE = '.numba_config.yaml'
#: numba's environment settings that change the machine code it generates: another value,
#: another extension (`toolchain`).
CODE_SETTINGS = ('NUMBA_CPU_NAME', 'NUMBA_CPU_FEATURES', 'NUMBA_ENABLE_AVX', 'NUMBA_OPT',
                 'NUMBA_LOOP_VECTORIZE', 'NUMBA_SLP_VECTORIZE')


def symbol(name):
    """The name the extension exports kernel `name` ('package.module.function') under."""
    return name.replace('.', '__')


def dispatcher(name):
    """The numba dispatcher of kernel `name` ('package.module.function'): imports its module,
    and so numba."""
    module, _, function = name.rpartition('.')
    return getattr(importlib.import_module(module), function)


def module_name(fingerprint):
    """The extension's module name for sources of `fingerprint` (its file: this name and
    the interpreter's extension suffix)."""
    return f'rft_sim_ros_kernels_{fingerprint[:16]}'


def extension_file(folder, name):
    """The path of extension module `name` in `folder`."""
    return Path(folder) / (name + importlib.machinery.EXTENSION_SUFFIXES[0])


def toolchain():
    """{name: version} of what compiled code depends on besides its sources: numba, numpy,
    Python, the CPU name and instruction-set features LLVM finds on this machine, and
    numba's settings in the environment that change the code it generates (`CODE_SETTINGS`;
    None where unset, which numba tells from set and empty), without importing numba:
    numba's version from its installed distribution, the CPU from llvmlite (0.05 s)."""
    from importlib.metadata import version

    import llvmlite.binding
    return {'numba': version('numba'), 'numpy': np.__version__,
            'python': sys.version.split()[0], 'cpu': llvmlite.binding.get_host_cpu_name(),
            'cpu_features': llvmlite.binding.get_host_cpu_features().flatten(),
            **{setting.lower(): os.environ.get(setting) for setting in CODE_SETTINGS}}


def toolchain_key(tools):
    """A short hash of `tools` (a `toolchain()`): the name of their folder."""
    return hashlib.sha256(json.dumps(tools, sort_keys=True).encode()).hexdigest()[:16]


def settings_refusal():
    """Why numba's settings rule the extension out, or '': a debugging setting it was not
    built with (NUMBA_DISABLE_JIT, NUMBA_BOUNDSCHECK: read from the environment as numba reads
    them, so that numba is not imported), or a numba configuration file in the working folder
    (which may set anything)."""
    for name in ('NUMBA_DISABLE_JIT', 'NUMBA_BOUNDSCHECK'):
        try:
            if int(os.environ.get(name) or 0):
                return f'{name} is set'
        except ValueError:
            return f'{name} is set'
    if Path(CONFIG_FILE).is_file():
        return f"numba's {CONFIG_FILE} in the working folder sets its options"
    return ''


def _stale(kept):
    """Why the extension of record `kept` is not that of the current sources ('' when it
    is): their files' times and sizes as recorded, or else the same fingerprint."""
    stats = kept.get('stats')
    if not (stats and sources_unchanged(stats)) and kept.get('fingerprint') != (
            sources_fingerprint()):
        return 'built from other sources (they changed since)'
    return ''


#: {(kernel name, why): calls}: this process's calls of prebuilt kernels with arguments of
#: other types than they were built for, which numba's dispatcher ran (`checked`); why: the
#: first argument that did not match, as `fallbacks_since` says it.
_FALLBACKS = {}


@functools.lru_cache(maxsize=None)
def load():
    """({kernel name: its prebuilt function, `checked`}, why there are none: '' when
    loaded), for this process's `toolchain()` in `FOLDER`. Cached: the first answer holds
    for the process."""
    if os.environ.get(SWITCH, '1') == '0':
        return {}, f'off ({SWITCH}=0)'
    refused = settings_refusal()
    if refused:
        return {}, f'off ({refused})'
    try:
        folder = FOLDER / toolchain_key(toolchain())
    except Exception as error:  # (e.g. numba installed without its distribution's record)
        return {}, f'no toolchain to match: {type(error).__name__}: {error}'
    try:
        kept = json.loads((folder / RECORD).read_text())
    except (OSError, ValueError):
        return {}, ('not built for this numba, numpy, Python and CPU (`rft-sim warmup` '
                    'builds them)')
    if not isinstance(kept, dict):
        return {}, f'not loadable: {RECORD} holds no record'
    why = _stale(kept)
    if why:
        return {}, f'{why}: `rft-sim warmup` builds them again'
    try:
        name = module_name(kept['fingerprint'])
        spec = importlib.util.spec_from_file_location(name, extension_file(folder, name))
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        current = dict(PREBUILT)  # (a kernel now called with other types: numba's)
        return {kernel: checked(getattr(module, symbol(kernel)), kernel, signature)
                for kernel, signature in kept['kernels'].items()
                if current.get(kernel) == signature}, ''
    except Exception as error:  # (a damaged extension or record: numba's kernels run)
        return {}, f'not loadable: {type(error).__name__}: {error}'


#: numba's scalar types a prebuilt kernel may take, and the Python and numpy types numba
#: types as each (`checked`).
_SCALARS = {'float64': (float, np.float64), 'int64': (int, np.int64),
            'boolean': (bool, np.bool_)}
#: A C-contiguous array in numba's text: float64[:, ::1] (writeable), or
#: Array(float64, 2, 'C', readonly=True).
_ARRAY = re.compile(r"(\w+)\[([:, ]*)::1\]")
_READ_ONLY = re.compile(r"Array\((\w+), (\d), 'C', readonly=True\)")


def _arguments(signature):
    """The argument types in numba's text of a signature, '(type, type, ...)': split at the
    commas outside brackets and parentheses."""
    arguments, depth, current = [], 0, ''
    for char in signature.strip()[1:-1] + ',':
        depth += (char in '([') - (char in ')]')
        if char == ',' and depth == 0:
            arguments.append(current.strip())
            current = ''
        else:
            current += char
    return [argument for argument in arguments if argument]


def checked(function, name, signature):
    """`function` (kernel `name`'s prebuilt function, compiled for `signature`, numba's text
    of its argument types) called only with arguments numba would type as that signature,
    and kernel `name`'s numba dispatcher (`dispatcher`) with any others, each such call
    counted with the argument that did not match (`fallbacks_since`). A function compiled
    ahead does not check its arguments (numba's unboxing of an array checks only its item
    size: given another dtype, rank or layout it reads the wrong memory): the check is made
    here, per call, on each argument's exact type: for a scalar Python's or numpy's type that
    numba types as it (float or numpy.float64 for float64; int or numpy.int64 for int64;
    bool or numpy.bool_ for boolean), for an array a numpy.ndarray of that dtype and rank,
    C-contiguous, aligned, and writeable or not as built (numba's read-only arrays are
    another type). Scalars and C-contiguous arrays only (ValueError otherwise). The check is
    one generated expression (0.1 to 0.3 us an argument)."""
    arguments = _arguments(signature)
    tests, constants = [], {'function': function, 'ndarray': np.ndarray}
    for i, argument in enumerate(arguments):
        writeable, read_only = _ARRAY.fullmatch(argument), _READ_ONLY.fullmatch(argument)
        if argument in _SCALARS:
            constants[f't{i}'], constants[f'u{i}'] = _SCALARS[argument]
            tests.append(f'(type(a{i}) is t{i} or type(a{i}) is u{i})')
        elif writeable or read_only:
            element = (writeable or read_only).group(1)
            constants[f'd{i}'] = np.dtype('bool' if element == 'boolean' else element)
            rank = (writeable.group(2).count(':') + 1 if writeable
                    else int(read_only.group(2)))
            tests.append(f'(type(a{i}) is ndarray and a{i}.dtype == d{i} and a{i}.ndim == {rank}'
                         f' and (f := a{i}.flags).c_contiguous and f.aligned and '
                         f'{"" if writeable else "not "}f.writeable)')
        else:
            raise ValueError(f'{name}: argument type {argument!r}: a prebuilt kernel takes '
                             'float64, int64, boolean and C-contiguous arrays')
    names = ', '.join(f'a{i}' for i in range(len(arguments)))
    matches = [generated(f'a{i}', f'return {test}', constants)
               for i, test in enumerate(tests)]
    constants['fallback'] = _fallback(name, arguments, matches)
    call = generated(names, f'if {" and ".join(tests) or "True"}:\n'
                            f'        return function({names})\n'
                            f'    return fallback({names})', constants)
    call.__name__ = call.__qualname__ = function_name(name)
    call.__doc__ = f'The prebuilt {name}{signature}, its arguments checked (`prebuilt.checked`).'
    return call


def generated(arguments, body, constants):
    """A function of `arguments` (their names, one text: 'a0, a1') whose `body` (its
    statements, one text, lines after the first indented by 4) reads the names of
    `constants` (a dict) as its globals: what `checked` and `prebuild` generate, a call of
    named arguments (which numba compiles, and checks cost least in; not *args)."""
    exec(f'def call({arguments}):\n    {body}\n', constants)
    return constants.pop('call')


def _fallback(name, arguments, matches):
    """The numba dispatcher call of kernel `name` for arguments its prebuilt function was not
    built for (`checked`), counted in _FALLBACKS with the first argument that does not match
    its type (`arguments`, numba's text of each; `matches`, a test of each)."""
    def call(*values):
        wrong = next((i for i, (match, value) in enumerate(zip(matches, values))
                      if not match(value)), None)
        why = ('called with other arguments' if wrong is None else
               f'argument {wrong + 1} is {_described(values[wrong], arguments[wrong])}, '
               f'built for {arguments[wrong]}')
        _FALLBACKS[name, why] = _FALLBACKS.get((name, why), 0) + 1
        return dispatcher(name)(*values)
    return call


def _described(value, built_for):
    """`value`'s type as a fallback says it, against `built_for` (numba's text of the type
    it was built for): an array's dtype and rank, its class where it is numpy's subclass, and
    what of its layout does not match; or another type's module and name."""
    kind = type(value)
    if not isinstance(value, np.ndarray):
        return f'a {kind.__module__.replace("builtins", "Python")} {kind.__name__}'
    flags, read_only = value.flags, bool(_READ_ONLY.fullmatch(built_for))
    notes = [text for text, off in (
        (f'a {kind.__name__}', kind is not np.ndarray),
        ('not C-contiguous', not flags.c_contiguous), ('not aligned', not flags.aligned),
        ('writeable' if read_only else 'read-only', flags.writeable == read_only)) if off]
    return f'a {value.ndim}-D {value.dtype} array' + (f' ({", ".join(notes)})' if notes
                                                       else '')


def kernel(name):
    """The prebuilt function of kernel `name` ('package.module.function', `kernel_names`)
    where the current extension has it (`checked`: arguments of other types run numba's),
    else its numba dispatcher (`dispatcher`; same arguments, same results)."""
    functions, _ = load()
    return functions.get(name) or dispatcher(name)


def has(name):
    """Whether a run calls kernel `name`'s prebuilt function (`kernel`)."""
    return name in load()[0]


def fallback_calls():
    """{(kernel name, why): calls so far} of the prebuilt kernels this process has called
    with arguments of other types than they were built for, so that numba's dispatcher ran
    them (`checked`; why: the first argument that did not match): a copy, which later calls
    are told from (`fallbacks_since`)."""
    return dict(_FALLBACKS)


def fallbacks_since(since=None):
    """[(kernel name, why)] of the calls `fallback_calls` counts that came after `since` (a
    `fallback_calls()`; None: all), in the order they first came."""
    since = since or {}
    return [key for key, calls in _FALLBACKS.items() if calls > since.get(key, 0)]


def fallback_line(since=None):
    """'; numba's for KERNEL (why)' for each of `fallbacks_since(since)`, or '': what a state
    line (`state`) adds."""
    return ''.join(f"; numba's for {function_name(name)} ({why})"
                   for name, why in fallbacks_since(since))


def state(*names):
    """One line: whether runs use the prebuilt kernels, and why not; given kernels' names,
    whether those are all prebuilt (an extension built before one of them was made one
    lacks it)."""
    functions, why = load()
    if not functions and why:
        return f'prebuilt kernels: {why}'
    lacking = [function_name(name) for name in names if not has(name)]
    return (f'prebuilt kernels: not built for {", ".join(lacking)} (`rft-sim warmup` builds '
            'them)' if lacking else 'prebuilt kernels: in use')
