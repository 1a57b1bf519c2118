"""Headless scene runs: step a Simulation for a duration, feed recorders at the publish rate,
and write summary.json, a time series and plots.

`run_scene` is what `rft-sim run` calls; recorders (e.g. the rosbag2 writer) receive the same
SimState snapshots the ROS node publishes, at the scene's publish rate (Hz of sim time).
"""
import contextlib
import json
import math
import os
import platform
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from .. import __version__, prebuilt
from ..sand.timestep import timestep_bound, timestep_problem
from .metrics import GenericMetrics
from ..scenes.scenarios import load_scenario
from .publishing import PublishSchedule
from .series import SeriesRows, joint_legs, model_name
from .simulation import ScenarioFailed, Simulation, SimulationDiverged
from .summary import finite, json_default, significant


class ProgressBar:
    """A one-line progress bar on a terminal; silent when the stream is not a TTY."""

    def __init__(self, total, stream=sys.stderr, label=''):
        self.total, self.stream, self.label = total, stream, label
        self.enabled = hasattr(stream, 'isatty') and stream.isatty()
        self._last = -1

    def update(self, done):
        if not self.enabled:
            return
        percent = int(100 * done / self.total) if self.total else 100
        if percent != self._last:
            self._last = percent
            filled = percent * 30 // 100
            self.stream.write(f'\r{self.label} [{"#" * filled}{"." * (30 - filled)}] {percent:3d}%')
            self.stream.flush()

    def close(self):
        if self.enabled:
            self.stream.write('\n')
            self.stream.flush()


def load_average():
    """The machine's load average over 1, 5 and 15 minutes (runnable processes), or None
    where the system does not say: a shared machine's wall times depend on it."""
    try:
        return [round(value, 2) for value in os.getloadavg()]
    except (OSError, AttributeError):  # (AttributeError: a system without it, e.g. Windows)
        return None


def machine_info():
    """Where a run was measured: CPU, cores, load average now (`load_average`), Python,
    MuJoCo and numpy versions, and whether this process runs the prebuilt kernels
    (`prebuilt.state`; a run's summary says its own: `Simulation.kernels`)."""
    cpu = platform.processor() or platform.machine()
    try:
        with open('/proc/cpuinfo') as info:
            for line in info:
                if line.startswith('model name'):
                    cpu = line.split(':', 1)[1].strip()
                    break
    except OSError:
        pass
    return {'cpu': cpu, 'cores': os.cpu_count(), 'load_average': load_average(),
            'python': platform.python_version(),
            'mujoco': mujoco.__version__, 'numpy': np.__version__,
            'rft_sim_ros': __version__, 'platform': platform.platform(),
            'kernels': prebuilt.state()}


@dataclass(frozen=True)
class SettingChange:
    """A scheduled change of a run-time setting (`key` an attribute of Simulation, e.g.
    'zeta' in N/cm^3): callable on a Simulation, and recorded in the summary."""
    key: str
    value: float

    def __call__(self, sim):
        setattr(sim, self.key, self.value)


def run_duration(scene, duration=None):
    """The sim time (s) a run of `scene` lasts: `duration`, else the scene's, else its
    scenario's own (`duration: auto`); checked to be a positive finite number."""
    if duration is None:
        duration = (scene.duration if scene.duration is not None
                    else load_scenario(scene).duration())
    duration = float(duration)
    if not (math.isfinite(duration) and duration > 0):
        raise ValueError(f'duration must be a positive number of seconds, got {duration}')
    return duration


@contextlib.contextmanager
def mujoco_log(path):
    """MuJoCo's own messages (e.g. 'Nan, Inf or huge value in QACC') go to the file `path`
    instead of MUJOCO_LOG.TXT in the working directory and the console; None: dropped (the
    run's summary says why it stopped). The previous settings are restored afterwards."""
    previous = mujoco.MjLogConfig.get()
    config = mujoco.MjLogConfig.get()
    config.logto_console = False
    config.logto_file = path is not None
    if path is not None:
        config.logfile = str(path)
    config.set()
    try:
        yield
    finally:
        previous.set()


def run_scene(scene, out_dir=None, duration=None, recorders=(), progress=True, plots=True,
              schedule=(), stop=None, log=None, surface=None, started=None):
    """Run `scene` (SceneConfig) headless for `duration` s (default: the scene's), on its
    sand surface or on `surface` (a `sand.surface.Surface` made in Python: `Simulation`).

    out_dir: where summary.json, timeseries.csv, plots and report.html (sim/page.py) go
    (None: write nothing).
    recorders: objects with record(SimState) and close(), fed the initial state (before the
    first step, as the ROS node publishes it), then at the publish rate (mean rate exact, on
    whole steps: `PublishSchedule`) and at the end; an optional start(sim) is called with
    the Simulation before the initial state, and an optional wants_plates attribute asks for
    the active plates in the states.
    schedule: (time_s, action) pairs; action(sim) runs once, when sim time first reaches
    time_s (rounded up to a whole step): after the state of that instant is recorded, before
    the next step (e.g. a zeta change, which then acts from that step on). SettingChange
    actions are listed in the summary's `schedule` (time_s, key: value, applied).
    stop: an object whose is_set() asks the run to end early (e.g. a threading.Event set on
    Ctrl-C): checked at every published state; the summary then says `interrupted` (and the
    object's `reason`, if it has one).
    MuJoCo's messages go to out_dir/mujoco.log (see `mujoco_log`).
    An exception in the scenario's code while the run steps, or in its metrics, ends the run
    as a divergence does (`ScenarioFailed`): stable false, the reason 'scenario failed at t =
    T s: the scenario raised at FILE:LINE: Type: message', what was recorded kept, and the
    traceback in out_dir/SCENARIO_TRACEBACK (the summary's `scenario_traceback` names it).
    log: called with each start-up notice of the Simulation (e.g. the sand bodies `auto`
    chose), before the first step.
    A timestep longer than the sand coupling resolves at the run's largest zeta
    (sand/timestep.py) is said through log('warning: ...') before the first step, and the
    run is reported not stable with that reason.
    started: `time.perf_counter()` when the run began for its user (`rft-sim run` passes its
    command's start, before its imports; default: this call), from which the summary's
    `first_step_s` counts: the seconds until the loop starts stepping (the simulation built,
    its recorders started, its initial state made).
    Returns the summary dict (see design section 4 for its fields; recording_time_s is the
    part of wall_time_s spent in the recorders, finishing them (closing a bag) included;
    generic_metrics: sim/metrics.py, those of every scene, next to the scenario's own
    `metrics`).
    """
    started = time.perf_counter() if started is None else started
    out = None if out_dir is None else Path(out_dir)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
    with mujoco_log(None if out is None else out / 'mujoco.log'):
        summary, series, sim, details = _run(scene, duration, recorders, progress, schedule,
                                             stop, log, surface, started)
    if details is not None:
        summary['scenario_traceback'] = SCENARIO_TRACEBACK if out is not None else details
    if out is not None:
        if details is not None:
            (out / SCENARIO_TRACEBACK).write_text(details)
        (out / 'summary.json').write_text(
            json.dumps(significant(summary), indent=2, default=json_default))
        _write_series(out / 'timeseries.csv', series, scene)
        if plots and series:
            from .plots import plot_run
            plot_run(out / 'timeseries.png', series, summary)
        if sim.engine.deformable:  # the final surface: heights (m, world z) and a map
            np.save(out / 'terrain.npy', sim.engine.surface.grid)
            if plots:
                from .plots import plot_surface
                plot_surface(out / 'terrain.png', sim.engine.surface)
        from .page import write_run_page  # last: it lists the files written
        write_run_page(out, significant(summary))
    return summary


#: The file of a run's folder that holds the traceback of an exception in its scenario.
SCENARIO_TRACEBACK = 'scenario_traceback.log'


def _run(scene, duration, recorders, progress, schedule, stop, log, surface, started):
    """The run itself: (summary, time series rows, the Simulation, the traceback of an
    exception in the scenario's code or None); started: `run_scene`'s."""
    bar = None
    loop_started = None
    interrupted = False
    details = None
    recording = 0.0  # s in the recorders: recording each state, and finishing
    try:  # recorders are closed however the run ends (a bag is only complete once closed)
        duration = run_duration(scene, duration)
        actions = _scheduled_steps(schedule, scene.timestep)
        changes = [{'time_s': step * scene.timestep, action.key: action.value,
                    'applied': False} for step, action in actions
                   if isinstance(action, SettingChange)]
        building = time.perf_counter()
        sim = Simulation(scene, surface)
        startup = time.perf_counter() - building
        for notice in sim.notices if log else ():
            log(notice)
        generic = GenericMetrics(sim)
        rows = SeriesRows(sim)
        zeta_max = max([scene.zeta, *(change['zeta'] for change in changes if 'zeta' in change)])
        coarse = timestep_problem(sim.engine, sim.timestep, zeta_max)
        if coarse and log is not None:
            log(f'warning: {coarse}')
        steps = int(round(duration / sim.timestep))
        publishing = PublishSchedule(scene.publish_rate, sim.timestep)
        cycle, next_publish = 1, publishing.end_step(1)
        with_plates = any(getattr(r, 'wants_plates', False) for r in recorders)
        for recorder in recorders:
            if hasattr(recorder, 'start'):
                recorder.start(sim)
        bar = ProgressBar(steps, label=scene.name) if progress else ProgressBar(0, stream=None)
        series = []
        active_sum = 0
        reason = None
        done = 0
        initial = sim.state(with_plates=with_plates)  # (sim time 0, as the node's first)
        generic.observe(sim, initial)
        loop_started = time.perf_counter()
        recording += _record(recorders, initial)
        _run_due(actions, done, sim, changes)
        while done < steps:
            if stop is not None and stop.is_set():
                interrupted = True
                break
            chunk = min(next_publish - done, steps - done)
            if actions:
                chunk = min(chunk, actions[0][0] - done)
            sim.step(chunk)
            done += chunk
            if done == next_publish or done == steps:
                if done == next_publish:
                    cycle += 1
                    next_publish = publishing.end_step(cycle)
                active_sum += sim.engine.plates_active
                state = sim.state(with_plates=with_plates)
                generic.observe(sim, state)
                series.append(rows.row(state, generic.latest_depths))
                recording += _record(recorders, state)
                bar.update(done)
                for line in sim.run_warnings():
                    sim.notices.append(line)
                    if log is not None:
                        log(f'warning: {line}')
            _run_due(actions, done, sim, changes)
    except ScenarioFailed as error:
        reason, details = f'scenario failed {error}', error.details
    except SimulationDiverged as error:
        reason = f'diverged {error}'
    finally:
        if bar is not None:
            bar.close()
        closing = time.perf_counter()
        for recorder in recorders:  # (finishing a bag is part of the run and its recording)
            recorder.close()
        recording += time.perf_counter() - closing
        if loop_started is not None:
            wall = time.perf_counter() - loop_started
    sim_time = sim.steps * sim.timestep
    metrics = {}
    if done:
        try:
            metrics = dict(sim.scenario.metrics(sim))
        except Exception as error:  # the scenario's: as if it had raised while stepping
            failure = sim.scenario_failure(error)
            if failure is None:
                raise
            if details is None:
                reason, details = f'scenario failed {failure} (in its metrics)', failure.details
        metrics.update(sim.terrain_metrics())
    if coarse:  # (a divergence at such a timestep: its likely cause, said beside it)
        reason = coarse if reason is None else f'{reason}; {coarse}'
    stable = reason is None  # neither diverged nor too coarse a timestep
    if interrupted:
        reason = '; '.join(filter(None, (
            f'interrupted at t = {sim_time:.4f} s of {duration:g} s '
            f'({getattr(stop, "reason", None) or "stopped on request"})', reason)))
    solves, unsettled, handed_back = sim.implicit_counts()
    generic_metrics = generic.result(stable=stable)
    shared = sorted(set(metrics) & set(generic_metrics))
    if shared:  # one name, one quantity: a scenario's metric must not take a generic name
        line = (f'warning: metric{"s" * (len(shared) > 1)} {", ".join(shared)}: the scenario '
                'reports a metric under the name of a generic one (sim/metrics.py), which may '
                "be another quantity: rename the scenario's")
        sim.notices.append(line)
        if log is not None:
            log(line)
    summary = {
        'scene': scene.name,
        'description': scene.description,
        'zeta': scene.zeta,
        'zeta_final': sim.zeta,
        'schedule': changes,
        'timestep_s': sim.timestep,
        'timestep_bound_s': timestep_bound(sim.engine, zeta_max)[0],
        'sim_time_s': sim_time,
        'wall_time_s': wall,
        'recording_time_s': recording,
        'startup_time_s': startup,
        'first_step_s': loop_started - started,
        'real_time_factor': sim_time / wall if wall > 0 else float('inf'),
        'steps': sim.steps,
        'spawn_settle_steps': sim.settle_steps,
        'plates_total': sim.engine.plates_total,
        'sand_bodies': list(sim.sand_bodies),
        'other_bodies': list(sim.other_bodies),
        'legs': {leg: list(bodies) for leg, bodies in sim.legs.items()},
        # the joints commands address (array commands in this order), and those left
        # passive as the model has them (robot/joints.py)
        'commanded_joints': list(sim.servo_joint_names),
        'passive_joints': list(sim.passive_joint_names),
        'robot_model': {'name': model_name(sim.model), 'file': str(scene.model_path)},
        'joint_legs': joint_legs(sim.model, [sim.model.joint(n).id for n in sim.joint_names],
                                 sim.legs, sim.model.body(sim.base_body).id),
        'notices': list(sim.notices),
        'plates_per_body': {name: int(sim.engine.plate_start[i + 1] - sim.engine.plate_start[i])
                            for i, name in enumerate(sim.engine.body_names)},
        'plates_active_mean': active_sum / max(1, len(series)),
        'low_velocity': sim.engine.low_velocity.method,
        # implicit treatment over the run's steps (spawn rest's settling left out): solves
        # per step, steps in which a plate had to be frozen (anti-cycling) or the sets did
        # not settle, and steps whose constraint rows were handed back to MuJoCo's solve
        # (see sand/implicit_solve.py)
        'implicit_solves_per_step': solves / max(1, sim.steps),
        'implicit_unsettled_steps': unsettled,
        'implicit_rows_handed_back_steps': handed_back,
        'normalisation': scene.normalisation,
        'stable': stable,
        'outcome': sim.outcome(),
        'interrupted': interrupted,
        'reason': reason,
        'metrics': finite(metrics),
        'generic_metrics': finite(generic_metrics),
        'scene_config': scene.raw,
        'scene_values': scene.values,
        'surface': sim.engine.surface.describe() if surface is None else {
            **sim.engine.surface.describe(), 'given_in_python': True},
        'machine': {**machine_info(), 'kernels': sim.kernels},
    }
    if sim.engine.deformable:  # where the nodes of the final surface (terrain.npy) lie
        summary['terrain_grid'] = sim.engine.surface.placement()
    return summary, series, sim, details


def _record(recorders, state):
    """Give `state` to every recorder; returns the wall time it took, s."""
    started = time.perf_counter()
    for recorder in recorders:
        recorder.record(state)
    return time.perf_counter() - started


def _scheduled_steps(schedule, timestep):
    """[(step, action)] sorted by step: the first whole step at or after each time (s)."""
    actions = []
    for at, action in schedule:
        at = float(at)
        if not (math.isfinite(at) and at >= 0):
            raise ValueError(f'scheduled time must be a finite number >= 0 s, got {at}')
        actions.append((max(0, math.ceil(at / timestep - 1e-9)), action))
    return sorted(actions, key=lambda item: item[0])


def _run_due(actions, done, sim, changes):
    """Run (and drop) the scheduled actions due at step `done`; mark the SettingChanges
    among them applied in `changes` (the summary's schedule, in the same order)."""
    while actions and actions[0][0] <= done:
        action = actions.pop(0)[1]
        action(sim)
        if isinstance(action, SettingChange):
            next(change for change in changes if not change['applied'])['applied'] = True


def _write_series(path, series, scene):
    if not series:
        return
    columns = list(series[0])
    lines = [','.join(columns)]
    lines += [','.join(f'{row[c]:.9g}' for c in columns) for row in series]
    path.write_text('\n'.join(lines) + '\n')
