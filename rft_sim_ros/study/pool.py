"""A small process pool that survives its workers: each worker is a spawned process with its
own pipe; a worker that dies (a crash, os._exit, SIGKILL, the OOM killer) is replaced and its
item retried once; an item that runs past a hard time limit has its worker killed and replaced.

concurrent.futures.ProcessPoolExecutor marks the whole pool broken when one worker dies,
which would end a study; this pool does not. Items go out one at a time to idle workers and
outcomes stream back as they finish (`map_unordered`). Workers are reused across items, so
per-process set-up (imports, warmed kernels) is paid once per worker.
"""
import contextlib
import multiprocessing
import os
import time
from collections import deque
from dataclasses import dataclass
from multiprocessing.connection import wait

#: Attempts per item when its worker dies: the first, and one retry.
ATTEMPTS = 2
#: Native thread pools each worker keeps to one thread (unless the user's environment sets
#: them): a run is single-threaded, and N workers that each start a BLAS/OpenMP pool as large
#: as the machine oversubscribe it, their idle threads spinning (measured on 2 cores: a 40-run
#: hexapod study on 2 workers took x0.91 the time of one worker, x0.63 with this). Ray sets
#: OMP_NUM_THREADS to a task's CPUs itself, which OpenBLAS follows.
WORKER_THREADS = {'OMP_NUM_THREADS': '1', 'OPENBLAS_NUM_THREADS': '1', 'MKL_NUM_THREADS': '1'}
#: Time a worker may take to start (spawn, imports) before the hard limit starts counting, s.
START_GRACE_S = 120.0


@dataclass(frozen=True)
class Outcome:
    """An item's result: index into the items, the value fn returned, or `error` (text) when
    fn raised, its worker died twice, or it ran past the hard limit (value is then None)."""
    index: int
    value: object = None
    error: str = None


def default_workers():
    """The cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def _serve(conn, fn):
    """Worker loop: receive (index, item); send (index, None, None) when fn starts on it, then
    (index, ok, value or error text)."""
    while True:
        message = conn.recv()
        if message is None:
            return
        index, item = message
        conn.send((index, None, None))
        try:
            conn.send((index, True, fn(item)))
        except Exception as error:  # noqa: BLE001 - reported to the parent as an Outcome
            conn.send((index, False, f'{type(error).__name__}: {error}'))


@contextlib.contextmanager
def _worker_environment():
    """os.environ with WORKER_THREADS filled in where unset, while a worker is spawned (a
    spawned process inherits the environment at start; this process's own pools are set)."""
    added = {name: value for name, value in WORKER_THREADS.items() if name not in os.environ}
    os.environ.update(added)
    try:
        yield
    finally:
        for name in added:
            del os.environ[name]


class _Worker:
    def __init__(self, context, fn):
        self.conn, child = context.Pipe()
        self.process = context.Process(target=_serve, args=(child, fn), daemon=True)
        with _worker_environment():
            self.process.start()
        child.close()
        self.index = None  # item being run
        self.started = None

    def give(self, index, item):
        # the hard limit counts from the worker's "started" answer; until then, a grace
        self.index, self.started = index, time.monotonic() + START_GRACE_S
        self.conn.send((index, item))

    def stop(self, kill=False):
        if kill:
            self.process.kill()
        else:
            try:
                self.conn.send(None)
            except OSError:
                pass
        self.process.join(timeout=None if kill else 5)
        if self.process.is_alive():
            self.process.kill()
            self.process.join()
        self.conn.close()


def map_unordered(fn, items, workers=None, hard_timeout=None):
    """Yield an Outcome per item of `items` as each finishes, running fn(item) in `workers`
    processes (default: all cores; fn and the items must pickle, fn by reference: a module-
    level function). hard_timeout: s an item may run before its worker is killed (None: no
    limit). Closing the generator stops the workers."""
    items = list(items)
    context = multiprocessing.get_context('spawn')  # fresh interpreters: no forked state
    queue = deque(range(len(items)))
    attempts = {}
    pool = [_Worker(context, fn) for _ in range(max(1, min(workers or default_workers(),
                                                            len(items))))]
    try:
        while queue or any(w.index is not None for w in pool):
            for i, worker in enumerate(pool):
                if worker.index is None and queue:
                    if not worker.process.is_alive():  # died after its last answer
                        worker.stop(kill=True)
                        worker = pool[i] = _Worker(context, fn)
                    index = queue.popleft()
                    attempts[index] = attempts.get(index, 0) + 1
                    worker.give(index, items[index])
            busy = [w for w in pool if w.index is not None]
            now = time.monotonic()
            wait_s = 1.0 if hard_timeout is None else max(0.0, min(
                w.started + hard_timeout - now for w in busy))
            ready = set(wait([w.conn for w in busy] + [w.process.sentinel for w in busy],
                             timeout=wait_s))
            for i, worker in enumerate(pool):
                if worker.index is None:
                    continue
                if worker.conn in ready or worker.process.sentinel in ready:
                    try:
                        index, ok, value = worker.conn.recv()
                    except (EOFError, OSError):  # died without an answer
                        index = worker.index
                        code = worker.process.exitcode
                        worker.stop(kill=True)
                        pool[i] = _Worker(context, fn)
                        if attempts[index] < ATTEMPTS:
                            queue.appendleft(index)
                        else:
                            yield Outcome(index, error=f'worker died twice (exit code {code})')
                        continue
                    if ok is None:  # fn started on the item: the hard limit counts from now
                        worker.started = time.monotonic()
                        continue
                    worker.index = None
                    yield Outcome(index, value) if ok else Outcome(index, error=value)
                elif hard_timeout is not None and time.monotonic() - worker.started > hard_timeout:
                    index = worker.index
                    worker.stop(kill=True)
                    pool[i] = _Worker(context, fn)
                    yield Outcome(index, error=f'timeout: killed after {hard_timeout:g} s')
    finally:
        for worker in pool:
            worker.stop(kill=worker.index is not None)
