"""Where a run's loop spends its time, part by part: the sand engine's step, the control
ticks (the scenario's control, the servo targets, the outcome watch, the divergence
check), the scenario's observations and each published state (the state, the run's
metrics, the time-series row, the recorders: a bag, as `rft-sim run` writes). A run of the
scene (`run_scene` with its bag, no figure) in this process, each part timed by a wrapper
around the function that does it
(about a microsecond a call on a 2-core VM: parts called at every step read a little high),
from the run's first step to its end, wherever the function is called (the outcome watch
also looks once for the run's outcome, and at each /diagnostics the bag records);
microseconds per step of the run, the median of `runs` runs. What is left of the loop
(`rest`) is the loop's own bookkeeping.

    python -m rft_sim_ros.bench.loop_parts SCENE [RUNS]
"""
import contextlib
import functools
import statistics
import sys
import tempfile
import time
from pathlib import Path

from ..control.commands import CommandHandler
from ..ros.recording import BagRecorder
from ..sand.engine import SandEngine
from ..scenes.config import SceneError, load_scene
from ..sim import runner
from ..sim.metrics import GenericMetrics
from ..sim.outcome import OutcomeWatch
from ..sim.runner import machine_info, run_scene
from ..sim.series import SeriesRows
from ..sim.simulation import Simulation
from .report import machine_line

#: (part, owner, attribute): the functions timed; SCENARIO, the scenario's own methods
#: (its `control` in a tick, its `observe`), are wrapped on each run's scenario.
SCENARIO = {'control': '  scenario control', 'observe': 'scenario observations'}
PARTS = (
    ('sand engine step', SandEngine, 'step'),
    ('control ticks', Simulation, '_control_tick'),
    ('  servo targets', CommandHandler, 'sample'),
    ('  outcome watch', OutcomeWatch, 'observe'),
    ('  divergence check', Simulation, '_check'),
    ('published state', Simulation, 'state'),
    ('run metrics', GenericMetrics, 'observe'),
    ('time-series row', SeriesRows, 'row'),
    ('recorders', runner, '_record'),
)
#: The parts that, with the rest, add up to the loop (the indented ones are in a tick).
_TOP = ('sand engine step', 'control ticks', 'scenario observations', 'published state',
        'run metrics', 'time-series row', 'recorders')
#: The rows `main` prints, in order: each top part, a tick's parts under the ticks.
_SHOWN = ('loop', 'sand engine step', 'control ticks', SCENARIO['control'],
          *[part for part, _, _ in PARTS if part.startswith('  ')], *_TOP[2:], 'rest')


def _timed(function, totals, part):
    @functools.wraps(function)
    def timed(*args, **kwargs):
        started = time.perf_counter()
        try:
            return function(*args, **kwargs)
        finally:
            totals[part] += time.perf_counter() - started
    return timed


@contextlib.contextmanager
def _wrapped(totals, marks):
    """PARTS wrapped to add their wall time (s) to `totals`, and each new Simulation's
    scenario methods (SCENARIO); `marks` takes a copy of `totals` at the run's first step
    (the Simulation's start-up, its spawn's settling steps included, and the initial state
    come before it). Everything as it was afterwards."""
    with contextlib.ExitStack() as stack:
        for part, owner, name in PARTS:
            original = owner.__dict__[name] if isinstance(owner, type) else getattr(owner, name)
            stack.callback(setattr, owner, name, original)
            setattr(owner, name, _timed(original, totals, part))
        make, step = Simulation.__init__, Simulation.step

        def init(sim, *args, **kwargs):
            make(sim, *args, **kwargs)
            for name, part in SCENARIO.items():
                setattr(sim.scenario, name, _timed(getattr(sim.scenario, name), totals, part))

        def first_step(sim, *args, **kwargs):
            if not marks:
                marks.update(totals)
            return step(sim, *args, **kwargs)

        stack.callback(setattr, Simulation, '__init__', make)
        stack.callback(setattr, Simulation, 'step', step)
        Simulation.__init__, Simulation.step = init, first_step
        yield


def loop_parts(scene_name, runs=3, duration=None, overrides=None):
    """{part: microseconds per step of the run's loop, the median of `runs` runs} of
    `scene_name` run with its bag (`run_scene`), with 'loop' (the whole loop) and 'rest'
    (the loop less the parts that add up to it)."""
    per_run = []
    for _ in range(runs):
        scene = load_scene(scene_name, overrides or {})
        totals = dict.fromkeys([part for part, _, _ in PARTS] + list(SCENARIO.values()), 0.0)
        marks = {}
        with tempfile.TemporaryDirectory() as folder, _wrapped(totals, marks):
            summary = run_scene(scene, duration=duration,
                                recorders=[BagRecorder(Path(folder) / 'bag', scene)],
                                progress=False, plots=False)
        steps = max(summary['steps'], 1)
        row = {part: (totals[part] - marks.get(part, 0.0)) * 1e6 / steps for part in totals}
        row['loop'] = summary['wall_time_s'] * 1e6 / steps
        row['rest'] = row['loop'] - sum(row[part] for part in _TOP)
        per_run.append(row)
    return {part: statistics.median(run[part] for run in per_run) for part in per_run[0]}


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if not argv:
        print(__doc__.strip().splitlines()[-1].strip())
        return 2
    runs = int(argv[1]) if len(argv) > 1 else 3
    try:
        parts = loop_parts(argv[0], runs)
    except SceneError as error:
        print(f'loop_parts: error: {error}', file=sys.stderr)
        return 2
    print(machine_line(machine_info()))
    print(f'{argv[0]}: us per step, medians of {runs} runs')
    for part in _SHOWN:
        print(f'{part:22s} {parts[part]:8.1f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
