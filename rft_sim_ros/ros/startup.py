"""Start-up of the `rft_sim` node (ROS-free): the scene is read and the simulation built off
the executor.

Reading the scene needs the simulation's modules (MuJoCo, the sand engine, and numba where
the kernels are not prebuilt: up to seconds of imports on a busy two-core machine), and
building a `Simulation` compiles its sand
kernels when numba's cache lacks them (a first start after an install or an upgrade: a
minute or more). The node serves ROS meanwhile: it is on the graph (its module imports
none of the simulation's), and its parameters, its services and /diagnostics answer at
once; the simulation
starts publishing once it is built. `SimStartup` runs `read` (imports and the scene), then
`build` in a worker thread and says how far it got; the node polls it from its executor:

* `scene`: None until read, then the scene `read` returned (the node then reads its
  scene-dependent parameters), `compiling` and `notice` what it compiles.
* `result()`: None while building; the built object once (then None again); raises
  `StartFailed` (the reason) if reading or building raised one of the start-up errors (a
  scene that does not load or build); any other error propagates as it is (a defect, with
  its traceback).
* `progress(now)`: 'reading the scene, 1 s so far', then 'compiling kernels, 12 s so far'
  (or 'building the simulation, 12 s so far' when the kernels are cached), for
  /diagnostics and the answers below.
* `pause_answer(paused)` / `refusal(service)`: what the services answer meanwhile: pause
  is taken (the simulation then starts paused, or running), reset, step and reset_terrain
  are refused with the reason, as there is nothing to reset or step yet.
* `diagnostic_fields(scene, zeta, paused, now)`: the /diagnostics status meanwhile (level
  OK, message 'starting: compiling kernels, 12 s so far').

Parameter changes made meanwhile (zeta, real_time_factor, paused) are checked as always
(`parameters.parameter_problem`) and kept by the node; the simulation starts with them, so
they apply from its first step.

Where the kernels must compile, they compile in a child Python process first
(`compile_in_child`), then the worker thread builds the simulation from the filled cache:
a compile in the node's own process would hold the GIL for whole garbage collections of
numba's many objects, which on a busy two-core machine took up to 6.5 s each (14 pauses over
0.5 s in a 13-minute cold build), and the executor thread could not answer meanwhile (with
the child, on the same machine: the longest pause 0.9 s, the OS's scheduling). A
child that fails costs time, never correctness: the worker thread then compiles what is
missing itself. Times: wall seconds (monotonic).
"""
import os
import pickle
import subprocess
import sys
import threading
import time

from rft_sim_ros.ros.messages import DiagnosticFields, ServiceResult

#: /diagnostics status name and level while starting (as `messages.diagnostic_fields`).
STATUS_NAME = 'rft_sim: simulation'
OK = 0


class StartFailed(Exception):
    """The simulation could not be built; the message says why (what to fix)."""


class SimStartup:
    """Runs `read()` (returns the scene), then `build(scene)` (returns the simulation) in a
    daemon thread from construction on.

    notice(scene): None where the kernels are cached, else what compiles
    (`sim.simulation.compile_notice`); then `compiling` is true, which `progress` says.
    warm(scene): called before `build` when compiling (`compile_in_child`); returns None, or
    why it did not fill the cache (then `warm_problem`, and `build` compiles the rest).
    errors: exception classes that mean a bad scene or parameter (re-raised as StartFailed
    by `result`). clock: wall time, s (monotonic). The thread is a daemon: a node shut down
    while it builds does not wait for it.
    """

    def __init__(self, read, build, *, notice=None, warm=None, errors=(), clock=time.monotonic):
        self._read = read
        self._build = build
        self._notice = notice
        self._warm = warm
        self._errors = tuple(errors)
        self._clock = clock
        self.scene = None
        self.notice = None
        self.compiling = False
        self.started = clock()
        self.warm_problem = None
        self._built = None
        self._error = None
        self._taken = False
        self._thread = threading.Thread(target=self._run, name='rft_sim start-up', daemon=True)
        self._thread.start()

    def _run(self):
        try:
            scene = self._read()
            self.notice = self._notice(scene) if self._notice is not None else None
            self.compiling = self.notice is not None
            self.scene = scene  # (last: the node reads notice and compiling once it is set)
            if self.compiling and self._warm is not None:
                self.warm_problem = self._warm(scene)
            self._built = self._build(scene)
        except BaseException as error:  # handed to the executor thread by `result`
            self._error = error

    @property
    def building(self):
        """Whether the build is still running."""
        return self._thread.is_alive()

    def wait(self, timeout=None):
        """Wait up to `timeout` s (None: until done) for the build; returns not `building`."""
        self._thread.join(timeout)
        return not self.building

    def result(self):
        """The built object, the first time it is asked for once ready; None before and
        after. Raises StartFailed for a start-up error, the error itself for any other."""
        if self.building or self._taken:
            return None
        self._taken = True
        if self._error is not None:
            if isinstance(self._error, self._errors):
                raise StartFailed(str(self._error)) from self._error
            raise self._error
        return self._built

    def elapsed(self, now=None):
        """Wall seconds since the start-up began (until `now`, default the clock's now)."""
        return (self._clock() if now is None else now) - self.started

    def progress(self, now=None):
        """What the start-up is doing: 'reading the scene, N s so far', then 'compiling
        kernels, N s so far' (or 'building the simulation, N s so far'), N in whole seconds."""
        if self.scene is None:
            doing = 'reading the scene'
        else:
            doing = 'compiling kernels' if self.compiling else 'building the simulation'
        return f'{doing}, {self.elapsed(now):.0f} s so far'

    def pause_answer(self, paused, now=None):
        """The pause service's answer meanwhile: taken; the node sets its `paused`
        parameter to `paused` and the simulation starts so."""
        return ServiceResult(True, f'the simulation will start {"paused" if paused else "running"}'
                                   f' once built ({self.progress(now)})')

    def refusal(self, service, now=None):
        """The answer of service `service` (reset, step, reset_terrain) meanwhile: refused,
        with why and when to retry."""
        return ServiceResult(False, f'{service}: the simulation is not built yet '
                                    f'({self.progress(now)}); try again once /diagnostics says '
                                    "'running' or 'paused'")

    def diagnostic_fields(self, scene, zeta, paused, now=None):
        """`messages.DiagnosticFields` of the start-up: level OK, message 'starting: ...'
        (`progress`), hardware_id `scene` (its name, or the parameter naming it); values
        (texts, as /diagnostics writes them when running): starting_s (wall s so far),
        compiling_kernels, and the zeta_n_per_cm3 (left out while None: the scene's, not
        read yet) and paused the simulation will start with."""
        values = (('starting_s', repr(round(self.elapsed(now), 1))),
                  ('compiling_kernels', 'true' if self.compiling else 'false'),
                  *((('zeta_n_per_cm3', repr(float(zeta))),) if zeta is not None else ()),
                  ('paused', 'true' if paused else 'false'))
        return DiagnosticFields(level=OK, name=STATUS_NAME,
                                message=f'starting: {self.progress(now)}',
                                hardware_id=scene, values=values)


def compile_in_child(scene, timeout=None):
    """Compile the kernels of `scene` (SceneConfig) into numba's cache in a child Python
    process (`python -m rft_sim_ros.ros.startup`, the scene pickled on its stdin; it
    builds the simulation once, steps it twice (the scenario's kernels: a built-in gait's)
    and exits; it inherits NUMBA_CACHE_DIR). Returns None, or
    why it failed (its last line of error output, e.g. the scene's SceneError, which the
    build in this process then raises itself). timeout: s, None = no limit."""
    try:
        done = subprocess.run([sys.executable, '-m', 'rft_sim_ros.ros.startup'],
                              input=pickle.dumps(scene), stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE, timeout=timeout)
    except (OSError, subprocess.TimeoutExpired) as error:
        return f'no compiling process: {error}'
    if done.returncode == 0:
        return None
    lines = done.stderr.decode(errors='replace').strip().splitlines()
    return lines[-1] if lines else f'the compiling process exited {done.returncode}'


def _leave_with_parent(period_s=0.5):
    """End this process (status 1) soon after its parent has: a node stopped by a signal
    to it alone (ros2 launch) leaves no compile running."""
    parent = os.getppid()

    def watch():
        while os.getppid() == parent:
            time.sleep(period_s)
        os._exit(1)
    threading.Thread(target=watch, daemon=True).start()


def _compile_main():
    """The child of `compile_in_child`."""
    _leave_with_parent()
    scene = pickle.load(sys.stdin.buffer)
    from rft_sim_ros.sim.simulation import Simulation
    Simulation(scene).step(2)  # (steps: the scenario's kernels too, e.g. a built-in gait's)


if __name__ == '__main__':
    _compile_main()
