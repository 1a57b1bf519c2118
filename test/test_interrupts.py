"""Ctrl-C during a numba compile and where Python cannot raise it (`interrupts`): a first
Ctrl-C waits for the compile in hand; a KeyboardInterrupt that lands in a callback or a
destructor (llvmlite's) is delivered again instead of printed and lost; what an interrupt
half built is freed without a traceback."""
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from numba import njit
from numba.core import event

from rft_sim_ros.cli import main, stop_on_signals
from rft_sim_ros.interrupts import REDELIVERY_S, held_while_compiling, interrupts_never_lost

SHORT = ['run', 'plate_drop', '--duration', '0.05', '--quiet', '--no-bag']


class _RaisesWhenFreed:
    """Its destructor raises `error`: Python reports that to sys.unraisablehook (as it does a
    KeyboardInterrupt raised inside a ctypes callback) and goes on."""

    def __init__(self, error):
        self.error = error

    def __del__(self):
        raise self.error


def _a_ctrl_c_lost():
    """A KeyboardInterrupt raised where it cannot propagate."""
    _RaisesWhenFreed(KeyboardInterrupt())


def _wait(seconds, until=lambda: False):
    """Python code running for `seconds`, or until `until()` (a delivered SIGINT acts in
    it; a handler does not run while this thread blocks in a wait of its own)."""
    end = time.monotonic() + seconds
    while time.monotonic() < end and not until():
        time.sleep(0.001)


@pytest.fixture
def reported(monkeypatch):
    """The unraisable errors Python reports (to the hook in place before the test's)."""
    errors = []
    monkeypatch.setattr(sys, 'unraisablehook', errors.append)
    return errors


class _CtrlCWhileCompiling(event.Listener):
    """Presses Ctrl-C (SIGINT to this process) `times` times as numba starts compiling."""

    def __init__(self, times=1):
        self.times = times

    def on_start(self, ev):
        for _ in range(self.times):
            signal.raise_signal(signal.SIGINT)
            _wait(0.001)  # (each press handled before the next)

    def on_end(self, ev):
        pass


def _fresh_kernel():
    """A numba function never compiled before (no cache): calling it compiles it."""
    @njit
    def summed(values):
        total = 0.0
        for value in values:
            total += value
        return total
    return summed


def test_a_ctrl_c_while_numba_compiles_acts_once_the_compile_is_done(ctrl_c_raises, capsys):
    kernel = _fresh_kernel()
    with held_while_compiling():
        with event.install_listener('numba:compile', _CtrlCWhileCompiling()):
            with pytest.raises(KeyboardInterrupt):
                kernel(np.ones(3))
        assert len(kernel.overloads) == 1  # compiled whole, not cut short inside LLVM
        assert kernel(np.ones(3)) == 3.0
    assert 'acted on once numba has compiled' in capsys.readouterr().err
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_without_the_hold_the_ctrl_c_lands_inside_the_compile(ctrl_c_raises):
    """(What the hold prevents: the interrupt cuts numba's compile short.)"""
    kernel = _fresh_kernel()
    with event.install_listener('numba:compile', _CtrlCWhileCompiling()):
        with pytest.raises(KeyboardInterrupt):
            kernel(np.ones(3))
    assert len(kernel.overloads) == 0


def test_a_second_ctrl_c_while_a_run_compiles_quits_at_once(ctrl_c_raises):
    kernel = _fresh_kernel()
    with held_while_compiling(), stop_on_signals() as stop:
        with event.install_listener('numba:compile', _CtrlCWhileCompiling(times=2)):
            with pytest.raises(KeyboardInterrupt):
                kernel(np.ones(3))
        _wait(0.01)
        assert len(kernel.overloads) == 0
        assert not stop.is_set()  # (quitting, not asked to stop as well)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_ctrl_c_while_a_run_compiles_becomes_its_stop_request(ctrl_c_raises):
    kernel = _fresh_kernel()
    with held_while_compiling(), stop_on_signals() as stop:
        with event.install_listener('numba:compile', _CtrlCWhileCompiling()):
            assert kernel(np.ones(3)) == 3.0  # no exception: the run's handler took it
            assert stop.is_set() and stop.signal == signal.SIGINT
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_the_hold_is_installed_once_the_package_imports_numba_for_its_kernels():
    """(A run on prebuilt kernels imports no numba: the hold waits for its first kernel
    module, and is removed with the context.)"""
    held = "any(isinstance(x, _HoldInterrupts) for x in event._registered['numba:compiler_lock'])"
    code = ('import sys\n'
            'from rft_sim_ros.interrupts import _HoldInterrupts, held_while_compiling\n'
            'with held_while_compiling():\n'
            "    print('numba' in sys.modules)\n"
            '    import rft_sim_ros.scenes.gait_kernels\n'
            '    from numba.core import event\n'
            f'    print({held})\n'
            f'print({held})\n')
    done = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True)
    assert done.stdout.split() == ['False', 'True', 'False'], done.stderr


def test_a_lost_ctrl_c_is_delivered_again(reported, ctrl_c_raises):
    with interrupts_never_lost():
        _a_ctrl_c_lost()
        with pytest.raises(KeyboardInterrupt):
            _wait(500 * REDELIVERY_S)  # (ends at the KeyboardInterrupt, 10 ms in)
    assert reported == [] and sys.unraisablehook == reported.append


def test_a_lost_ctrl_c_during_a_run_becomes_its_stop_request(reported, ctrl_c_raises):
    with interrupts_never_lost(), stop_on_signals() as stop:
        _a_ctrl_c_lost()
        _wait(500 * REDELIVERY_S, until=stop.is_set)
        assert stop.is_set() and stop.signal == signal.SIGINT
    assert reported == []


def test_an_ignored_sigint_stays_ignored(reported):
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with interrupts_never_lost():
            _a_ctrl_c_lost()
            _wait(20 * REDELIVERY_S)  # (no KeyboardInterrupt)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert reported == []


def test_other_unraisable_errors_are_reported_as_before(reported, ctrl_c_raises):
    with interrupts_never_lost():
        _RaisesWhenFreed(ValueError('a real error'))
    assert [type(error.exc_value) for error in reported] == [ValueError]


class _HalfBuilt:
    """An object whose constructor a Ctrl-C cut short, and whose destructor then fails (as
    llvmlite's ObjectRef does when `_as_parameter_` was never set)."""

    def __init__(self):
        raise KeyboardInterrupt  # between the constructor's two lines
        self.handle = 1

    def __del__(self):
        del self.handle


def test_an_object_a_ctrl_c_half_built_is_freed_without_a_traceback(reported, capsys,
                                                                    monkeypatch):
    from rft_sim_ros import cli
    monkeypatch.setattr(cli, 'load_scene', lambda *args: _HalfBuilt())
    assert main(SHORT) == 130
    assert reported == [] and sys.unraisablehook == reported.append
    assert capsys.readouterr().err.strip() == 'rft-sim: interrupted'
