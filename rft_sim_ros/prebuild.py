"""Build the prebuilt kernels that `prebuilt` loads: one extension module of the kernels a run
calls from Python (`kernel_names.PREBUILT`), compiled for this machine's CPU by numba's
ahead-of-time compiler (`numba.pycc`, which needs a C compiler for its small runtime).

Each kernel compiles through its own numba dispatcher, with the options it was declared with
(fastmath, error model), or loads from numba's cache where that holds it already; the
extension exports a caller of it with the argument types given, which the record keeps for
the checks of every call (`prebuilt.checked`), and its machine code is generated for the CPU
name and instruction-set features numba's JIT compiles for (numba's ahead-of-time compiler
would otherwise take every feature of the CPU's model, which a virtual machine may hide).
`rft-sim warmup` builds after it has run the scenes, in a second process (`python -m
rft_sim_ros.prebuild`, `main`): measured on an AMD EPYC VM, the build took 19 to 28 s where
the kernels loaded from numba's cache, and 60 s where the same process had just compiled
them.
"""
import contextlib
import json
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

from .kernel_cache import kernel_sources, source_stats, sources_fingerprint, sources_unchanged
from .prebuilt import (FOLDER, RECORD, checked, dispatcher, extension_file, generated, load,
                       module_name, settings_refusal, state, symbol, toolchain, toolchain_key)


def _caller(kernel, arity):
    """A Python function of `arity` arguments that calls numba dispatcher `kernel` with
    them (what the extension exports, compiled for one signature: numba compiles an exported
    function of named arguments only, not *args)."""
    names = ', '.join(f'a{i}' for i in range(arity))
    return generated(names, f'return kernel({names})', {'kernel': kernel})


@contextlib.contextmanager
def _host_features():
    """numba's ahead-of-time code generation with the instruction-set features its JIT
    uses (this machine's, or NUMBA_CPU_FEATURES; `CPUCodegen._get_host_cpu_features`)
    instead of none (which lets LLVM take every feature of the CPU's model)."""
    from numba.core.codegen import AOTCPUCodegen
    original = AOTCPUCodegen._customize_tm_features
    AOTCPUCodegen._customize_tm_features = lambda self: self._get_host_cpu_features()
    try:
        yield
    finally:
        AOTCPUCodegen._customize_tm_features = original


def build(kernels, folder=FOLDER):
    """Compile `kernels` ((kernel name, numba's text of its argument types) pairs) into
    an extension in `folder`'s subfolder of this `toolchain()` and record what it was built
    from there (`prebuilt.RECORD`), replacing the extension and record of older sources (a
    process that loaded one keeps it). Returns the wall seconds it took. Raises what the
    compiler raised (e.g. no C compiler), or RuntimeError where a source changed while it
    compiled: the previous extension, if any, is then kept."""
    from numba.core import config, sigutils
    with warnings.catch_warnings():  # (numba marks pycc as deprecated, without a successor)
        warnings.simplefilter('ignore')
        from numba.pycc import CC
    refused = settings_refusal()
    if refused:  # (what a run would refuse the extension for: it would be built with it)
        raise RuntimeError(f'not built: {refused}')
    for kernel_name, signature in kernels:  # (each a signature the calls can be checked by)
        checked(None, kernel_name, signature)
    start = time.perf_counter()
    tools = toolchain()
    target = Path(folder) / toolchain_key(tools)
    target.mkdir(parents=True, exist_ok=True)
    fingerprint, stats = sources_fingerprint(), source_stats(kernel_sources())
    name = module_name(fingerprint)
    with tempfile.TemporaryDirectory(dir=target) as work, _host_features():
        compiler = CC(name)
        compiler.output_dir, compiler.verbose = work, False
        compiler.target_cpu = config.CPU_NAME or 'host'  # (the JIT's: NUMBA_CPU_NAME or this)
        for kernel_name, signature in kernels:
            kernel = dispatcher(kernel_name)
            arguments, _ = sigutils.normalize_signature(signature)
            kernel.compile(arguments)
            returns = kernel.overloads[tuple(arguments)].signature.return_type
            compiler.export(symbol(kernel_name), returns(*arguments))(
                _caller(kernel, len(arguments)))
        compiler.compile()
        if not sources_unchanged(stats):
            raise RuntimeError("the kernels' sources changed while they compiled: build again")
        os.replace(extension_file(work, name), extension_file(target, name))
        seconds = time.perf_counter() - start
        kept = Path(work) / RECORD
        kept.write_text(json.dumps({'fingerprint': fingerprint, 'stats': stats, **tools,
                                    'kernels': dict(kernels), 'built_s': round(seconds, 1)},
                                   indent=1))
        os.replace(kept, target / RECORD)
    for older in target.glob(f'{module_name("")}*'):
        if older != extension_file(target, name):
            older.unlink(missing_ok=True)
    load.cache_clear()
    return seconds


def main():
    """`python -m rft_sim_ros.prebuild`: build the kernels a run calls from Python
    (`kernel_names.PREBUILT`) into `prebuilt.FOLDER` and print `prebuilt.state` and how
    long it took; returns 0. Where the build fails, prints why as one line on stderr (the
    error's type and message, whose lines numba's compiler errors spread over several) and
    returns 1."""
    from rft_sim_ros.kernel_names import PREBUILT
    try:
        seconds = build(PREBUILT)
    except Exception as error:  # (the building process's report: warmup says it and goes on)
        print(f'{type(error).__name__}: {" ".join(str(error).split())}', file=sys.stderr)
        return 1
    print(f'{state()} (built in {seconds:.1f} s)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
