"""A small process pool that survives its workers: each worker is a process with its own
pipe; a worker that dies (a crash, os._exit, SIGKILL, the OOM killer) is replaced and its item
retried once; an item that runs past a hard time limit has its worker killed and replaced.

Workers are forked from this process when it runs a single thread (`start_method`): they
start at once with everything it has imported (the package, MuJoCo, numba: about 0.8 s a
worker otherwise, which a short study or validation pays before its first result). Forking
a process with other threads can deadlock the child (a lock held by a thread that is not
copied), so a multi-threaded process (e.g. one whose BLAS keeps a thread pool) spawns fresh
interpreters instead. `rft-sim` keeps the native thread pools to one thread (`__main__.py`),
so its commands fork.

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

from ..native_threads import unset

#: Attempts per item when its worker dies: the first, and one retry.
ATTEMPTS = 2
#: Time a worker may take to start (spawn, imports) before the hard limit starts counting, s.
START_GRACE_S = 120.0
#: An idle worker looks whether its parent is still there this often, s.
PARENT_CHECK_S = 1.0


@dataclass(frozen=True)
class Outcome:
    """An item's result: index into the items, the value fn returned, or `error` (text) when
    fn raised, its worker died twice, or it ran past the hard limit (value is then None)."""
    index: int
    value: object = None
    error: str = None


def start_method():
    """'fork' when this process runs a single thread (Linux: its task count), else
    'spawn' (see module docstring)."""
    try:
        threads = len(os.listdir('/proc/self/task'))
    except OSError:  # not Linux: no cheap way to know
        return 'spawn'
    return 'fork' if threads == 1 else 'spawn'


def default_workers():
    """The cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def _serve(conn, fn, parent):
    """Worker loop: receive (index, item); send (index, None, None) when fn starts on it, then
    (index, ok, value or error text). Ends when told (None) or once its parent process (pid
    `parent`) is gone, looked at every PARENT_CHECK_S while idle: a forked worker holds
    copies of the pipes' parent ends, so it would never read an end of file from them."""
    while True:
        while not conn.poll(PARENT_CHECK_S):
            if os.getppid() != parent:
                return
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
    """os.environ with `native_threads.ONE_THREAD` filled in where unset, while a worker is
    started (a
    spawned process reads it as it starts; a forked one has this single-threaded process's
    pools already)."""
    added = unset()
    os.environ.update(added)
    try:
        yield
    finally:
        for name in added:
            del os.environ[name]


class _Worker:
    def __init__(self, context, fn):
        self.conn, child = context.Pipe()
        self.process = context.Process(target=_serve, args=(child, fn, os.getpid()),
                                       daemon=True)
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
    context = multiprocessing.get_context(start_method())
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
