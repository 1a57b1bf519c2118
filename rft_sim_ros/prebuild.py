"""Build the prebuilt kernels that `prebuilt` loads: one extension module of the engine's
table kernels, compiled for this machine's CPU by numba's ahead-of-time compiler
(`numba.pycc`, which needs a C compiler for its small runtime).

Each kernel compiles through its own numba dispatcher, with the options it was declared with
(fastmath, error model), or loads from numba's cache where that holds it already; the
extension exports a caller of it with the argument types given, so the code a run calls is
the code the dispatcher would have run. `rft-sim warmup` builds after it has run the scenes,
in a second process (`python -m rft_sim_ros.prebuild`, `main`): there every kernel loads from
numba's cache as machine code, which the extension takes as it is (19 s on an AMD EPYC VM);
kernels compiled in the same process are held as LLVM IR, which the build would optimise and
generate again (60 s).
"""
import json
import os
import tempfile
import time
import warnings
from pathlib import Path

from .prebuilt import FOLDER, RECORD, extension_file, load, record, state, symbol


def _caller(dispatcher, arity):
    """A Python function of `arity` arguments that calls numba dispatcher `dispatcher` with
    them (what the extension exports, compiled for one signature: numba compiles an exported
    function of named arguments only, not *args)."""
    names = ', '.join(f'a{i}' for i in range(arity))
    namespace = {'kernel': dispatcher}
    exec(f'def call({names}):\n    return kernel({names})\n', namespace)
    return namespace['call']


def build(kernels, folder=FOLDER):
    """Compile `kernels` ((numba dispatcher, numba's text of its argument types) pairs) into
    the extension in `folder` and record what it was built from (`prebuilt.RECORD`),
    replacing the extension and record there (a process that loaded the old one keeps it).
    Returns the wall seconds it took. Raises what the compiler raised (e.g. no C compiler):
    the old extension, if any, is then kept."""
    from numba.core import sigutils
    with warnings.catch_warnings():  # (numba marks pycc as deprecated, without a successor)
        warnings.simplefilter('ignore')
        from numba.pycc import CC
    start = time.perf_counter()
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=folder) as work:
        compiler = CC(extension_file(folder).name.split('.')[0])
        compiler.output_dir, compiler.target_cpu, compiler.verbose = work, 'host', False
        for dispatcher, signature in kernels:
            arguments, _ = sigutils.normalize_signature(signature)
            dispatcher.compile(arguments)
            returns = dispatcher.overloads[tuple(arguments)].signature.return_type
            compiler.export(symbol(dispatcher), returns(*arguments))(_caller(dispatcher, len(arguments)))
        compiler.compile()
        built = Path(work) / extension_file(folder).name
        (folder / RECORD).unlink(missing_ok=True)
        os.replace(built, extension_file(folder))
        seconds = time.perf_counter() - start
        kept = Path(work) / RECORD
        kept.write_text(json.dumps(record(folder, seconds), indent=1))
        os.replace(kept, folder / RECORD)
    load.cache_clear()
    return seconds



def main():
    """`python -m rft_sim_ros.prebuild`: build the engine's table kernels
    (`sand.engine.TABLE_KERNELS`) into `prebuilt.FOLDER` and print `prebuilt.state` and how
    long it took; a failure raises (the traceback's last line says why)."""
    from rft_sim_ros.sand.engine import TABLE_KERNELS
    seconds = build(TABLE_KERNELS)
    print(f'{state()} (built in {seconds:.1f} s)')


if __name__ == '__main__':
    main()
