"""What a Ctrl-C does while numba compiles, and what it leaves behind when it ends a command
(`rft-sim`, the ROS executables).

A KeyboardInterrupt is raised wherever Python code runs when the signal arrives. During a
numba compile that may be a ctypes callback of llvmlite's, or a destructor, where it cannot
propagate: Python prints it ("Exception ignored on calling ctypes callback function") and
it is lost, and the compile it cut short then fails with an error of its own ("no compiled
object yet"). Or it is a constructor of llvmlite's, whose object, half built, later fails
in its destructor with a traceback of its own. So the CLI holds a first Ctrl-C while numba
compiles (`held_while_compiling`); a KeyboardInterrupt lost all the same is delivered again
(`interrupts_never_lost`); and what an interrupt half built is freed quietly
(`release_quietly`).
"""
import _thread
import contextlib
import gc
import signal
import sys
import threading
import traceback

from . import kernel_cache

#: s after a KeyboardInterrupt was lost before it is delivered again.
REDELIVERY_S = 0.01


@contextlib.contextmanager
def interrupts_never_lost():
    """Context (or decorator): a KeyboardInterrupt that could not be raised where it landed
    (a callback, a destructor) is not printed but delivered again REDELIVERY_S later, to the
    main thread's SIGINT handler of that moment (a KeyboardInterrupt, or `rft-sim run`'s
    stop request), until it lands where it can act; other unraisable errors are reported as
    before. The hook is restored on exit."""
    hook = sys.unraisablehook

    def report(unraisable):
        if not issubclass(unraisable.exc_type, KeyboardInterrupt):
            hook(unraisable)
            return
        again = threading.Timer(REDELIVERY_S, _thread.interrupt_main, (signal.SIGINT,))
        again.daemon = True
        again.start()
    sys.unraisablehook = report
    try:
        yield
    finally:
        sys.unraisablehook = hook


class _HoldInterrupts:
    """numba event listener for "numba:compiler_lock" (held while a kernel is compiled or
    loaded from the cache). While the lock is held (in the main thread), a first Ctrl-C is
    noted, with a line on stderr at once, and delivered to the SIGINT handler it would have
    met (a KeyboardInterrupt, or `rft-sim run`'s stop request) as soon as the lock is
    released; a second one quits at once (KeyboardInterrupt)."""

    def __init__(self):
        self.depth = 0
        self.previous = None
        self.pressed = False

    def notify(self, ev):
        if threading.current_thread() is not threading.main_thread():
            return
        if ev.is_start:
            self._lock_taken()
        else:
            self._lock_released()

    def _lock_taken(self):
        self.depth += 1
        handler = signal.getsignal(signal.SIGINT)
        if self.depth == 1 and callable(handler):  # (not ignored, default, or set in C)
            self.previous = handler
            signal.signal(signal.SIGINT, self._note)

    def _note(self, signum, frame):
        if self.pressed:  # quit at once (the first is not delivered again)
            self.pressed = False
            raise KeyboardInterrupt
        self.pressed = True
        print('\nrft-sim: Ctrl-C: acted on once numba has compiled the kernel in hand (up to '
              'some 10 s on a first run; again to quit at once)', file=sys.stderr, flush=True)

    def _lock_released(self):
        self.depth -= 1
        if self.depth == 0 and self.previous is not None:
            signal.signal(signal.SIGINT, self.previous)
            self.previous = None
            if self.pressed:
                self.pressed = False
                signal.raise_signal(signal.SIGINT)  # handled at the next bytecode


@contextlib.contextmanager
def held_while_compiling():
    """Context: a first Ctrl-C (SIGINT) waits for the numba compile or cache load in hand to
    end before it acts (`_HoldInterrupts`). For a process whose Python code owns SIGINT's
    handler: rclpy installs its own in C, which Python's `signal.signal` would replace.
    The listener is installed once the package imports numba for its kernels
    (`kernel_cache.when_kernels_import`): a run on prebuilt kernels imports none, and numba
    loads scipy (0.3 s)."""
    listening = contextlib.ExitStack()

    def listen():
        from numba.core import event
        event.Listener.register(_HoldInterrupts)  # (numba takes Listener instances)
        listening.enter_context(event.install_listener('numba:compiler_lock',
                                                       _HoldInterrupts()))
    withdraw = kernel_cache.when_kernels_import(listen)
    with listening:
        try:
            yield
        finally:
            withdraw()


def release_quietly(interrupt):
    """Free what the exception `interrupt` (a KeyboardInterrupt, or a shutdown a signal
    caused) holds, its traceback's frames, at once, with the errors of the destructors this
    runs ignored (an object whose constructor the interrupt cut short). Other errors are not
    affected: the hook is restored before returning."""
    hook = sys.unraisablehook
    sys.unraisablehook = lambda unraisable: None
    try:
        traceback.clear_frames(interrupt.__traceback__)
        interrupt.__traceback__ = None
        gc.collect()  # (frames in reference cycles)
    finally:
        sys.unraisablehook = hook
