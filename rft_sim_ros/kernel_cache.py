"""Bookkeeping of the package's compiled kernels in numba's on-disk cache: whether they are
there, whether they are still those of the package's sources, and compiling some of them in a
second process. It imports nothing of the package: every kernel module imports it.

The sand engine's kernels (`rft.kernel`, `sand.gather`, `sand.implicit_solve`,
`sand.deformable_kernels`, `sand.surface_kernels`, ...) and the gaits'
(`scenes.gait_kernels`) are numba functions compiled with cache=True: the
first run after an install (or after their source changed) compiles them (`BackgroundCompile`
puts a share in a second process); every later run loads them from the cache in a fraction of
a second. `sand.engine.kernels_cached` (and
`sim.simulation.compile_notice`, which the CLI and the node show) asks `is_cached` about the
kernels one engine needs (one gather kernel per kind of surface); `rft-sim warmup`
(`rft_sim_ros.warmup`, beside the CLI) compiles every kernel ahead.

numba checks a cached kernel against its own source file only, but a kernel compiles in
helpers and constants from other files too (`sand/surface_kernels.py`,
`sand/deformable_kernels.py` and `sand/table_readers.py` into the gather kernels of
`sand/gather.py`): an upgrade or an
edit that changed only those would load kernels compiled from the old code. So each kernel
module ends by calling `forget_stale(globals())`, before any of its kernels can load: the
fingerprint of every source the kernels are compiled from (`kernel_sources`, read as text,
never imported) is kept in a marker file beside the module's cached kernels, and where it
differs, their cache entries are dropped and compile afresh. The marker also keeps those
sources' modification times and sizes, so that a start whose sources have not changed since
does not compute the fingerprint.

The cache is numba's: `__pycache__` beside the sources, or NUMBA_CACHE_DIR. A kernel counts as
cached when numba's index for it holds at least one compiled signature for its current source.
"""
import ast
import functools
import hashlib
import importlib
import importlib.util
import json
import sys
from pathlib import Path

#: Modules holding the package's cached numba kernels.
KERNEL_MODULES = ('rft_sim_ros.rft.kernel', 'rft_sim_ros.sand.constraint_rows',
                  'rft_sim_ros.sand.deformable_kernels', 'rft_sim_ros.sand.elliptic_cones',
                  'rft_sim_ros.sand.explicit', 'rft_sim_ros.sand.gather',
                  'rft_sim_ros.sand.implicit_law', 'rft_sim_ros.sand.implicit_solve',
                  'rft_sim_ros.sand.joint_friction', 'rft_sim_ros.sand.mujoco_terms',
                  'rft_sim_ros.sand.surface_kernels', 'rft_sim_ros.sand.tree_solve',
                  'rft_sim_ros.scenes.gait_kernels')
#: The package's folder.
PACKAGE = Path(__file__).resolve().parent


def _module_file(name):
    """The source file of the package's module `name` (dotted), or None for a module that
    is not one of the package's."""
    parts = name.split('.')
    if parts[0] != PACKAGE.name:
        return None
    path = PACKAGE.joinpath(*parts[1:])
    for candidate in (path.with_suffix('.py'), path / '__init__.py'):
        if candidate.is_file():
            return candidate
    return None


def _imports(name, path):
    """Dotted names that module `name` (source `path`) imports at its top level (what its
    functions import when called is not compiled into a kernel), and of each name it
    imports from a module, as if a submodule (the caller keeps those that are modules)."""
    package = name if path.name == '__init__.py' else name.rpartition('.')[0]
    for node in ast.parse(path.read_bytes()).body:
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = importlib.util.resolve_name('.' * node.level + (node.module or ''), package)
            yield base
            yield from (f'{base}.{alias.name}' for alias in node.names)


@functools.lru_cache(maxsize=None)
def kernel_sources():
    """The package's source files its cached kernels are compiled from: the kernel modules
    and, transitively, every module of the package they import (read, not imported), but
    this one, which every kernel module imports and which compiles nothing into them (an
    edit of the bookkeeping keeps the cache)."""
    found, pending = {}, list(KERNEL_MODULES)
    while pending:
        name = pending.pop()
        path = _module_file(name)
        if path is not None and name not in found and name != __name__:
            found[name] = path
            pending.extend(_imports(name, path))
    return tuple(sorted(set(found.values())))


@functools.lru_cache(maxsize=None)
def sources_fingerprint():
    """SHA-256 (hex) of the package's `kernel_sources`, names and contents."""
    digest = hashlib.sha256()
    for path in kernel_sources():
        digest.update(path.relative_to(PACKAGE).as_posix().encode() + b'\0')
        digest.update(path.read_bytes() + b'\0')
    return digest.hexdigest()


def module_kernels(module_name, namespace):
    """{name: dispatcher} of the separately compiled, cached numba kernels defined in the
    module namespace `namespace` (numba never compiles inline='always' helpers on their own:
    they are left out)."""
    from numba.core.caching import NullCache
    from numba.core.dispatcher import Dispatcher
    return {name: value for name, value in namespace.items()
            if isinstance(value, Dispatcher) and value.__module__ == module_name
            and not isinstance(value._cache, NullCache)
            and value.targetoptions.get('inline', 'never') == 'never'}


def source_stats(paths):
    """{path relative to the package: [modification time ns, size]} of source files `paths`
    (absolute); None where one of them is gone."""
    stats = {}
    for path in paths:
        try:
            stat = path.stat()
        except OSError:
            return None
        stats[path.relative_to(PACKAGE).as_posix()] = [stat.st_mtime_ns, stat.st_size]
    return stats


def sources_unchanged(recorded):
    """Whether the source files of `recorded` ({relative path: [mtime ns, size]}, what
    `source_stats` gave when a marker was written) are still those: same modification time and
    size each. A new source joins `kernel_sources` only through an edit of one of them."""
    try:
        return source_stats([PACKAGE / name for name in recorded]) == recorded
    except (TypeError, ValueError):
        return False


#: Callables `when_kernels_import` keeps for the first kernel module's import.
_KERNEL_MODULE_HOOKS = []


def when_kernels_import(hook):
    """Call `hook()` once numba is imported for the package's kernels: now, where it is
    already, else when the first kernel module is imported (its `forget_stale`, before any
    of its kernels can compile or load). A run whose kernels are all prebuilt imports none
    (`prebuilt`). Returns a callable that withdraws the hook where it was not called yet."""
    if 'numba' in sys.modules:
        hook()
    else:
        _KERNEL_MODULE_HOOKS.append(hook)

    def withdraw():
        if hook in _KERNEL_MODULE_HOOKS:
            _KERNEL_MODULE_HOOKS.remove(hook)
    return withdraw


def forget_stale(namespace, fingerprint=None):
    """Drop the cached kernels of the module whose globals are `namespace` when they were
    compiled from other sources than `fingerprint` (default: `sources_fingerprint()`, the
    package's now), as a marker file beside them in numba's cache records; then record
    `fingerprint` there. Called by each kernel module at the end of its import. Returns
    whether it dropped them.

    The marker's first line is the fingerprint; its second, the modification time and size
    of each of `kernel_sources` when it was written (JSON). While those all still hold, the
    sources are the marker's and the fingerprint is not computed (it reads and parses some
    thirty files, about 0.1 s of every start); an explicit `fingerprint` is always compared."""
    while _KERNEL_MODULE_HOOKS:  # (the first kernel module: numba is now imported)
        _KERNEL_MODULE_HOOKS.pop(0)()
    kernels = module_kernels(namespace['__name__'], namespace).values()
    if not kernels:  # (e.g. NUMBA_DISABLE_JIT: no dispatchers)
        return False
    marker = Path(next(iter(kernels))._cache._cache_path) / f'{namespace["__name__"]}.sources'
    try:
        recorded, _, stats = marker.read_text().partition('\n')
    except OSError:
        recorded = stats = None  # no marker yet: kernels cached before, if any, are dropped
    if fingerprint is None and stats:
        try:
            if sources_unchanged(json.loads(stats)):
                return False
        except ValueError:
            pass
    now = fingerprint or sources_fingerprint()
    dropped = recorded != now
    if dropped:
        for kernel in kernels:
            kernel._cache.flush()
    try:
        marker.write_text(now if fingerprint else
                          f'{now}\n{json.dumps(source_stats(kernel_sources()))}')
    except OSError:
        pass  # a cache folder numba cannot write to either: nothing is cached there
    return dropped


def is_cached(kernel):
    """Whether numba's on-disk index holds a compiled signature of the numba dispatcher
    `kernel` for its current source (an index left by older source or another numba version
    counts as none)."""
    return bool(kernel._cache._cache_file._load_index())


#: File beside a module's cached kernels that keeps how long the last start that compiled
#: them took (`record_cold_start`).
COLD_START_FILE = 'rft_sim_ros.cold_start.json'


def _cold_start_file(kernel):
    """The cold-start record in the cache folder of numba dispatcher `kernel`."""
    return Path(kernel._cache._cache_path) / COLD_START_FILE


def record_cold_start(kernel, key, wall_s, cpu_s):
    """Keep, in the cache folder of numba dispatcher `kernel`, that a start compiling the
    kernels of `key` (a short text, e.g. 'implicit') took `wall_s` seconds (and `cpu_s` of
    CPU, this process and its children), for `last_cold_start` to quote the next time those
    kernels must compile in that folder (after an upgrade, an edit, a cleared cache). A
    folder numba cannot write to keeps nothing."""
    path = _cold_start_file(kernel)
    try:
        records = json.loads(path.read_text())
    except (OSError, ValueError):
        records = {}
    records[key] = {'wall_s': round(wall_s, 2), 'cpu_s': round(cpu_s, 2)}
    try:
        path.write_text(json.dumps(records))
    except OSError:
        pass


def last_cold_start(kernel, key):
    """{'wall_s', 'cpu_s'} of the last start that compiled the kernels of `key` with its cache
    in the folder of numba dispatcher `kernel` (`record_cold_start`), or None: none recorded."""
    try:
        record = json.loads(_cold_start_file(kernel).read_text())[key]
        return {'wall_s': float(record['wall_s']), 'cpu_s': float(record['cpu_s'])}
    except (OSError, ValueError, KeyError, TypeError):
        return None


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
    _compile_main(sys.argv[1:])
