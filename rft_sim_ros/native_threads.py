"""The native thread pools (BLAS, OpenMP) of this package's processes: one thread each.

Every run is single-threaded (its matrices are small), and many runs go in parallel as
processes (studies, validation: `study/pool.py`), so a pool as large as the machine in each
process only oversubscribes the cores: its idle threads spin (measured on 2 cores: a 40-run
hexapod study on 2 workers took x0.91 the time of one worker, x0.63 with one thread each).
A single-threaded process can also fork its workers, which then start at once. The settings
must be in the environment before numpy loads its BLAS; a value the user set is kept. Ray
sets OMP_NUM_THREADS to a task's CPUs itself, which OpenBLAS follows. Standard library only.
"""
import os

#: Environment settings for one thread per native pool.
ONE_THREAD = {'OMP_NUM_THREADS': '1', 'OPENBLAS_NUM_THREADS': '1', 'MKL_NUM_THREADS': '1'}


def unset(environ=os.environ):
    """The ONE_THREAD settings `environ` does not have yet."""
    return {name: value for name, value in ONE_THREAD.items() if name not in environ}
