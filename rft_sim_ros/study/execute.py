"""One study run, as a worker executes it: warm the kernels once per worker process, load the
scene with the run's overrides, run it headless, and hand back a plain-data record.

Whatever happens inside a run (an exception, divergence, exceeding the time limit) comes back
as a record with `stable` False and the `reason`; only a worker process that dies loses its
record (the backend then retries the run once). Records hold only JSON-ready data, so they
cross process and machine boundaries unchanged.
"""
import os
import signal
import socket
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass

from ..scenes.config import load_scene
from ..sim.runner import run_scene
from ..sim.simulation import Simulation, kernel_key

#: (scene, kernel_key) pairs whose kernels this process has warmed.
_warmed = set()


@dataclass(frozen=True)
class RunTask:
    """What a worker needs for one run: scene (bundled name or absolute YAML path), the
    overrides (as --set), sim duration (s, None: the scene's) and time limit (s, None: none)."""
    run_id: str
    scene: str
    overrides: dict
    duration: float = None
    timeout: float = None


#: After a run's time limit, SIGALRM repeats at this interval until the run stops, s.
REPEAT_S = 0.25


class RunTimeout(BaseException):
    """The run exceeded its time limit. An interruption from outside the run, as
    KeyboardInterrupt is (hence BaseException): the `except Exception` that ends a run whose
    scenario raised (sim/simulation.py) lets it through."""


def warm(scene, overrides):
    """Compile or load the numba kernels (and import everything a run needs) once per process
    per scene and set of kernels its runs step with (`kernel_key`: a study varying the
    surface or deformable sand meets several), outside any run's timing: build the scene
    and take two steps. Returns the time it took (s; 0 when this process had warmed up for
    them already)."""
    started = time.perf_counter()
    try:
        key = (scene, kernel_key(load_scene(scene, overrides)))
    except Exception:  # noqa: BLE001 - the run itself reports what is wrong
        key = (scene, None)
    if key in _warmed:
        return 0.0
    _warmed.add(key)
    for values in (overrides, {}):  # the run's values; if they fail, the scene's own
        try:
            Simulation(load_scene(scene, values)).step(2)
            break
        except Exception:  # noqa: BLE001 - the run itself reports what is wrong
            continue
    return time.perf_counter() - started


def execute(task):
    """Run `task` (a RunTask); return its record: run_id, stable, reason, wall_time_s (s: the
    whole run in the worker, scene loading included, warm-up excluded), warm_s (s spent
    warming this worker first, 0 where its kernels were warm: `warm`), started_at /
    finished_at (the worker's clock, s since the epoch), worker (host:pid) and summary
    (run_scene's summary dict, None when the run raised or timed out)."""
    warm_s = warm(task.scene, task.overrides)
    started_at = time.time()
    started = time.perf_counter()
    summary, reason = None, None
    try:
        with time_limit(task.timeout):
            summary = run_scene(load_scene(task.scene, task.overrides), None,
                                duration=task.duration, progress=False, plots=False)
        reason = summary['reason']
    except RunTimeout:
        reason = f'timeout: exceeded --run-timeout {task.timeout:g} s'
    except Exception as error:  # noqa: BLE001 - recorded, the study goes on
        reason = f'error: {type(error).__name__}: {error}'
    if summary is not None:
        summary.pop('machine', None)  # the same for every run: once per study, not per row
    return {'run_id': task.run_id, 'stable': reason is None, 'reason': reason,
            'wall_time_s': time.perf_counter() - started, 'warm_s': warm_s,
            'started_at': started_at, 'finished_at': time.time(),
            'worker': f'{socket.gethostname()}:{os.getpid()}', 'summary': summary}


@contextmanager
def time_limit(seconds):
    """Raise RunTimeout in the block once `seconds` (wall) have passed (None: no limit), and
    again every REPEAT_S after, in case native code swallowed the first (an exception raised
    inside a C callback is lost). Uses SIGALRM, so it acts only in a process's main thread
    (where both backends run tasks); elsewhere the block runs unlimited and the backend's
    own limit applies."""
    if seconds is None or threading.current_thread() is not threading.main_thread():
        yield
        return

    def expire(signum, frame):
        raise RunTimeout()

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, max(1e-3, float(seconds)), REPEAT_S)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def failure_record(run_id, reason):
    """The record of a run that came back without one (its worker died)."""
    return {'run_id': run_id, 'stable': False, 'reason': reason, 'wall_time_s': None,
            'warm_s': 0.0, 'started_at': None, 'finished_at': None, 'worker': None,
            'summary': None}
