"""`rft-sim`: run sand scenes headless, list them, benchmark and validate (no ROS needed).

  rft-sim scenes [SCENE [--set key=value ...]]
  rft-sim run SCENE|ROBOT_FILE [--sand-bodies P[,P...]|auto] [--base floating|fixed]
                    [--keyframe NAME] [--spawn rest|drop:HEIGHT]
                    [--package-path NAME=DIR ...] [--xacro-arg K=V ...] [--duration S]
                    [--zeta Z] [--timestep DT] [--plates-per-body N] [--set key=value ...]
                    [--set-at T:zeta=Z ...] [--out DIR] [--overwrite] [--no-bag]
                    [--plates] [--video] [--commands FILE] [--json] [--quiet]
  rft-sim render RUN_DIR|BAG_DIR [--scene SCENE|ROBOT_FILE] [--set key=value ...]
                 [--out FILE] [--force]
  rft-sim view SCENE|ROBOT_FILE [--set key=value ...] [--real-time-factor R]
  rft-sim validate [--quick] [--stability] [--out DIR]
  rft-sim bench [--quick] [--out DIR]
  rft-sim warmup
  rft-sim sweep STUDY.yaml [--out DIR] [--workers N | --ray auto|ADDRESS] [--resume]
                           [--run-timeout S]

A ROBOT_FILE (MJCF .xml, URDF .urdf, xacro .xacro/.urdf.xacro) runs in the scene
`scenes.config.robot_scene` makes for it (external commands, paper sand, 1 ms steps).
`run` writes DIR/summary.json, the time series and plots, and a rosbag2 (MCAP) under
DIR/bag/ with the topics the ROS node publishes, into a new or empty DIR (one that holds an
earlier run's outputs is refused, or with --overwrite replaced once the run has started),
and prints a few lines saying how it ended (the JSON with --json; only errors with
--quiet). `validate` and `bench` write into a fresh
runs/<command>-<time> unless `--out` names a folder (e.g. the committed validation/).

Errors in what the user asked for (unknown scene, bad value, an output folder that cannot
be written) print one line and exit 2, before anything runs. Ctrl-C (SIGINT) or SIGTERM stops
a run at the next published state: the bag is closed, summary.json says `"interrupted":
true`, and the exit status is 128 + the signal number (130, 143), as a shell reports it; one
that comes while the run is set up, before its output folder is made, ends it with nothing
written. In every command a first Ctrl-C during a numba compile waits for it (`interrupts`).
"""
import argparse
import contextlib
import datetime
import json
import os
import shutil
import signal
import sys
import threading
import time
from collections import Counter
from pathlib import Path

from . import __version__
from .render import VIDEO_FILE
from .interrupts import held_while_compiling, interrupts_never_lost, release_quietly
from .sim.ways_down import DOWN
from .sim.summary import significant
from .scenes.config import (SceneError, anchor_paths, bundled_scenes, load_scene,
                            parse_assignment, robot_overrides)
from .scenes.schema import KEYS, given_paths
from .units import validated_zeta


class UsageError(ValueError):
    """What the user asked for cannot be done (e.g. an output folder that cannot be written);
    the message says why."""


class Parser(argparse.ArgumentParser):
    """argparse with one-line errors: `rft-sim: error: ...`, exit 2 (no usage block)."""

    def error(self, message):
        self.exit(2, f'rft-sim: error: {message} (see rft-sim {self._subcommand()}--help)\n')

    def _subcommand(self):
        words = self.prog.split()[1:]
        return ''.join(f'{word} ' for word in words)


#: Values `--set-at` may change during a run: name -> check(value) (returns it, or raises
#: ValueError); the change is a runner.SettingChange of the Simulation attribute `name`.
RUNTIME_SETTINGS = {'zeta': validated_zeta}


def _scene_overrides(args):
    overrides = dict(parse_assignment(text) for text in args.set or [])
    for option, key in (('zeta', 'zeta'), ('timestep', 'timestep'),
                        ('plates_per_body', 'rft.plates_per_body'), ('base', 'robot.base'),
                        ('keyframe', 'robot.keyframe'), ('spawn', 'robot.spawn')):
        value = getattr(args, option)
        if value is not None:
            overrides[key] = value
    if getattr(args, 'video', False):
        overrides['video.enabled'] = True
    overrides.update(robot_overrides(args.sand_bodies, args.package_path, args.xacro_arg))
    return anchor_paths(overrides, Path.cwd())  # files named on the command line: from here


def parse_timed_assignment(text):
    """'T:key=value' -> (T in s, SettingChange) for run_scene's schedule; raises SceneError."""
    from .sim.runner import SettingChange
    at, sep, assignment = text.partition(':')
    try:
        at = float(at)
    except ValueError:
        at = float('nan')
    if not sep or not (at >= 0 and at != float('inf')):
        raise SceneError(f'--set-at expects T:key=value with T >= 0 s, got {text!r}')
    key, value = parse_assignment(assignment)
    if key not in RUNTIME_SETTINGS:
        raise SceneError(f'--set-at can change {", ".join(RUNTIME_SETTINGS)} during a run, '
                         f'not {key!r}')
    try:
        value = RUNTIME_SETTINGS[key](value)
    except ValueError as error:
        raise SceneError(f'--set-at {text}: {error}') from None
    return at, SettingChange(key, value)


def say_if_cold(scene=None, quiet=False):
    """Before building a simulation of `scene` (SceneConfig; None: a default scene, for the
    commands that run many): say at once when its kernels must first be compiled
    (sim.simulation.compile_notice), instead of leaving a cold start silent (`quiet`: say
    nothing)."""
    from .sim.simulation import compile_notice
    line = None if quiet else compile_notice(scene or load_scene('hexapod'))
    if line:
        print(f'rft-sim: {line} (`rft-sim warmup` compiles them ahead)', file=sys.stderr,
              flush=True)


def warn(message):
    """One `rft-sim: warning: ...` line on stderr (the run goes on)."""
    print(f'rft-sim: warning: {message}', file=sys.stderr)


def output_folder(path):
    """Create the output folder `path` (and its parents) and check that files can be written
    in it; returns it as a Path. Raises UsageError saying why not (a file in the way, no
    permission, a system folder such as /proc)."""
    path = Path(path)
    for folder in (path, *path.parents):
        if folder.exists() and not folder.is_dir():
            raise UsageError(f'--out {path}: {folder} is a file, not a folder')
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe = path / f'.rft-sim-write-test-{os.getpid()}'
        probe.write_bytes(b'')
        probe.unlink()
    except OSError as error:
        raise UsageError(f'--out {path}: cannot write there ({error.strerror or error})') from None
    return path


def fresh_folder(name):
    """runs/<name>-<local time> (-2, -3, ... where that exists already): where a command
    writes unless --out says otherwise."""
    path = Path('runs') / f'{name}-{datetime.datetime.now():%Y%m%d-%H%M%S}'
    count = 1
    while (path.parent / f'{path.name}{"" if count == 1 else f"-{count}"}').exists():
        count += 1
    return path.parent / f'{path.name}{"" if count == 1 else f"-{count}"}'


#: What marks a folder as an earlier run's (`rft-sim run` writes them first or always).
RUN_MARKERS = ('summary.json', 'bag', 'timeseries.csv', 'mujoco.log', VIDEO_FILE, 'report.html')


def earlier_run(out, overwrite):
    """Check the output folder `out` of a run: it must be new or empty, or, with
    `overwrite`, hold an earlier run's outputs (RUN_MARKERS). Returns whether it holds
    outputs to replace; raises UsageError saying why the run cannot write there."""
    if not out.is_dir():
        return False
    entries = sorted(entry.name for entry in out.iterdir())
    if not entries:
        return False
    listed = ', '.join(entries[:4]) + (', ...' if len(entries) > 4 else '')
    if not any(name in entries for name in RUN_MARKERS):
        raise UsageError(f'--out {out} holds other files ({listed}): a run writes into a new '
                         'or empty folder; choose another --out')
    if not overwrite:
        raise UsageError(f"--out {out} holds an earlier run's outputs ({listed}): choose "
                         'another --out, or --overwrite to replace them')
    return True


@contextlib.contextmanager
def replacing(out):
    """Context of a run that replaces the earlier run in `out`: that folder is set aside
    (renamed) for the run; deleted once the run has ended, put back where the run is
    refused while it is set up (an exception), so that bad input loses nothing."""
    aside = out.with_name(f'.{out.name}.replaced-{os.getpid()}')
    out.rename(aside)
    try:
        yield
    except BaseException:
        shutil.rmtree(out, ignore_errors=True)
        aside.rename(out)
        raise
    shutil.rmtree(aside, ignore_errors=True)


def cmd_scenes(args):
    if args.scene is None:
        for name, path in bundled_scenes().items():
            scene = load_scene(path)
            print(f'{name:20s} {scene.description.splitlines()[0] if scene.description else ""}')
        return 0
    scene = load_scene(args.scene, dict(parse_assignment(text) for text in args.set or []))
    print(f'scene {scene.name}: effective values (--set KEY=VALUE overrides any of them; '
          'docs/scene-reference.md)')
    given = set(given_paths(scene.raw))
    for key in KEYS:
        if key.section or key.path == 'params':
            continue
        if key.path not in scene.values:  # a key of an optional section left out (null)
            print(f'  {key.path}  (unset: {key.path.rpartition(".")[0]} is off)')
            continue
        default = '' if key.path in given else '  (default)'
        print(f'  {key.path} = {json.dumps(scene.values[key.path], default=str)}{default}')
    print('scene values (params; --set NAME=VALUE):')
    for key, value in scene.params.items():
        print(f'  {key} = {json.dumps(value, default=str)}')
    return 0


def cmd_run(args):
    say = (lambda line: None) if args.quiet else (  # noqa: E731
        lambda line: print(f'rft-sim: {line}', file=sys.stderr))
    with stop_on_signals() as stop:  # from the start: a Ctrl-C in the set-up is no exception
        from .scenes.scenarios import load_scenario
        from .sim.runner import run_duration, run_scene
        scene = load_scene(args.scene, _scene_overrides(args))
        load_scenario(scene)  # (one that cannot be imported: one error, nothing written)
        if args.duration is not None and not args.duration > 0:
            raise SceneError(f'--duration must be > 0 s, got {args.duration}')
        schedule = [parse_timed_assignment(text) for text in args.set_at or []]
        twice = sorted(when for when, count in Counter(
            (at, change.key) for at, change in schedule).items() if count > 1)
        if twice:
            raise SceneError(f'--set-at changes {twice[0][1]} twice at {twice[0][0]:g} s: give '
                             'one value')
        duration = run_duration(scene, args.duration)
        for (at, change), text in zip(schedule, args.set_at or []):
            if at > duration and not args.quiet:
                warn(f'--set-at {text} comes after the run ends ({duration:g} s): not applied')
        if args.commands:
            from .ros.replay import load_commands
            schedule += load_commands(args.commands).schedule()
        out = Path(args.out) if args.out else fresh_folder(scene.name)
        replace = earlier_run(out, args.overwrite)
        video = scene.values['video.enabled']
        if video:  # (no run, and nothing written, where no frame can be rendered)
            from .render.gl import check_offscreen
            check_offscreen()
        say_if_cold(scene, quiet=args.quiet)
        if stop.is_set():  # before anything is written: nothing is
            print('rft-sim: interrupted before the run started: nothing written',
                  file=sys.stderr)
            return 128 + stop.signal
        with replacing(out) if replace else contextlib.nullcontext():
            created = next((folder for folder in reversed((out, *out.parents))
                            if not folder.exists()), None)  # the first folder this run makes
            output_folder(out)
            try:
                recorders = []
                if not args.no_bag:
                    from .ros.recording import BagRecorder
                    recorders.append(BagRecorder(out / 'bag', scene, plates=args.plates))
                if video:
                    from .render.recorder import VideoRecorder
                    recorders.append(VideoRecorder(out / VIDEO_FILE, scene))
                summary = run_scene(scene, out, duration=args.duration,
                                    progress=not args.quiet, recorders=recorders,
                                    schedule=schedule, stop=stop, log=say,
                                    started=args.started)
                elapsed = time.perf_counter() - args.started
            except (SceneError, ValueError):  # refused before it ran (the model does not load)
                if created is not None:
                    shutil.rmtree(created, ignore_errors=True)
                else:  # (an empty folder given: left empty)
                    for entry in out.iterdir():
                        if entry.is_dir():
                            shutil.rmtree(entry)
                        else:
                            entry.unlink()
                raise
    if args.json:
        print(json.dumps(significant(run_report(summary)), indent=2))
    elif not args.quiet:
        print('\n'.join(human_summary(summary, out, elapsed)))
    if summary.get('scenario_traceback'):
        print(f'rft-sim: error: {summary["reason"]} (traceback: '
              f'{out / summary["scenario_traceback"]})', file=sys.stderr)
    elif args.quiet and not summary['stable']:  # (else the summary printed says why)
        print(f'rft-sim: error: {summary["reason"]}', file=sys.stderr)
    if stop.signal is not None:
        return 128 + stop.signal
    return 0 if summary['stable'] else 1


#: The summary keys `rft-sim run --json` prints (with the metrics and the outcome).
REPORT_KEYS = ('scene', 'zeta', 'timestep_s', 'sim_time_s', 'wall_time_s', 'real_time_factor',
               'plates_total', 'plates_active_mean', 'stable', 'interrupted', 'reason')


def run_report(summary):
    """What `rft-sim run --json` prints of a run's `summary`: REPORT_KEYS, its `outcome`
    where it has one, its metrics and generic metrics."""
    report = {key: summary[key] for key in REPORT_KEYS}
    if 'outcome' in summary:
        report['outcome'] = summary['outcome']
    return {**report, 'metrics': summary['metrics'],
            'generic_metrics': summary['generic_metrics']}


#: Scenario metrics the human summary shows at most.
SHOWN_METRICS = 4


def human_summary(summary, out, elapsed):
    """The few lines `rft-sim run` prints at the end: how the run ended (stable, and
    whether the robot fell, was upside down, collapsed or sank; its real-time factor, and
    `elapsed`, s, the command's wall time since it started (`main`'s `started`: through
    `rft-sim`, its imports too), the model's set-up and the outputs written, the figure's
    included), what happened to the robot (the summary's outcome words, where it has them),
    its key metrics (the scenario's first SHOWN_METRICS, else the base's displacement and
    final speed), and where its files are."""
    if summary['interrupted']:
        ended = 'interrupted'
    elif summary['stable']:
        outcome = summary.get('outcome') or {}
        down = [said for key, _, said in DOWN if outcome.get(key)]
        ended = 'stable' + (f' (the robot {" and ".join(down)})' if down else '')
    else:
        ended = 'NOT STABLE'
    lines = [f'{summary["scene"]}: {ended}, {summary["sim_time_s"]:.4g} s of sim time in '
             f'{summary["wall_time_s"]:.3g} s (real-time factor '
             f'{summary["real_time_factor"]:.3g}; first step at {summary["first_step_s"]:.3g} s, '
             f'{elapsed:.3g} s in all, set-up and files included)']
    if summary['reason']:
        lines.append(f'  reason: {summary["reason"]}')
    words = (summary.get('outcome') or {}).get('words')
    if words:
        lines.append(f'  outcome: {words}')
    shown = {key: value for key, value in summary['metrics'].items()
             if isinstance(value, (int, float)) and not isinstance(value, bool)}
    if not shown:
        shown = {key: summary['generic_metrics'][key]
                 for key in ('base_displacement_m', 'final_speed_mps')
                 if key in summary['generic_metrics']}
    if shown:
        lines.append('  ' + ', '.join(f'{key} {_number(value)}' for key, value
                                      in list(shown.items())[:SHOWN_METRICS]))
    files = [name for name in ('summary.json', 'timeseries.csv', 'bag', VIDEO_FILE, 'report.html')
             if (out / name).exists()]
    lines.append(f'  wrote {out}/: {", ".join(files)} (all metrics: summary.json)')
    return lines


def _number(value):
    return 'null' if value is None else f'{value:.4g}'


class StopRequest(threading.Event):
    """Set by SIGINT/SIGTERM while a run is going; `signal` is the number that set it and
    `reason` says so (run_scene puts it in the summary)."""
    signal = None

    @property
    def reason(self):
        return f'{signal.Signals(self.signal).name} received' if self.signal else None


class stop_on_signals:
    """Context: SIGINT and SIGTERM set the yielded StopRequest instead of killing the process,
    so the run ends at its next published state with its bag closed and its summary written;
    a second signal acts as usual (KeyboardInterrupt / termination); a signal that was
    ignored stays ignored. Handlers are restored on exit."""
    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __enter__(self):
        self.stop = StopRequest()
        # a signal the caller ignores (a background job's SIGINT, nohup) stays ignored
        self.previous = {number: signal.getsignal(number) for number in self.SIGNALS
                         if signal.getsignal(number) is not signal.SIG_IGN}
        for number in self.previous:
            signal.signal(number, self._handle)
        return self.stop

    def _handle(self, number, frame):
        self.stop.signal = number
        self.stop.set()
        print(f'\nrft-sim: {signal.Signals(number).name}: stopping at the next published '
              'state (again to quit at once)', file=sys.stderr)
        for other, handler in self.previous.items():  # the next one stops at once
            signal.signal(other, handler)

    def __exit__(self, *exc):
        for number, handler in self.previous.items():
            signal.signal(number, handler)


def _scene_of_run(run_dir, overrides):
    """The scene a run ran, from its summary.json's scene_config, `overrides` applied."""
    import tempfile
    import yaml
    summary = run_dir / 'summary.json'
    try:
        raw = json.loads(summary.read_text())['scene_config']
    except (OSError, ValueError, KeyError, TypeError):
        raise UsageError(f'{run_dir}: no readable summary.json with the scene it ran: name the '
                         'scene with --scene') from None
    with tempfile.TemporaryDirectory() as folder:  # (a bundled model is found by name)
        path = Path(folder) / f'{raw.get("name") or "scene"}.yaml'
        path.write_text(yaml.safe_dump(raw))
        return load_scene(path, overrides)


def cmd_render(args):
    from .render.frames import VideoSettings
    from .render.gl import check_offscreen
    source = Path(args.run)
    overrides = anchor_paths(dict(parse_assignment(text) for text in args.set or []), Path.cwd())
    if (source / 'metadata.yaml').is_file():  # a bag folder (ros2 bag record)
        bag, default_out = source, source.with_suffix('.mp4')
        if args.scene is None:
            raise UsageError(f'{source} is a bag: name the scene or robot it ran with --scene')
    elif (source / 'bag' / 'metadata.yaml').is_file():
        bag, default_out = source / 'bag', source / VIDEO_FILE
    else:
        raise UsageError(f'{source}: neither a run folder with a bag (bag/metadata.yaml) nor a '
                         'bag folder (metadata.yaml)')
    scene = (load_scene(args.scene, overrides) if args.scene is not None
             else _scene_of_run(source, overrides))
    out = Path(args.out) if args.out else default_out
    if out.exists() and not args.force:
        raise UsageError(f'{out} exists: choose another --out, or --force to replace it')
    check_offscreen()
    say_if_cold(scene)
    from .ros.bag_video import render_bag
    from .sim.simulation import Simulation
    frames = render_bag(bag, Simulation(scene), out, VideoSettings.from_scene(scene),
                        log=lambda line: print(f'rft-sim: {line}', file=sys.stderr))
    print(f'wrote {out} ({frames} frames)', file=sys.stderr)
    return 0


def cmd_view(args):
    from .render.viewer import check_display, view
    overrides = dict(parse_assignment(text) for text in args.set or [])
    scene = load_scene(args.scene, anchor_paths(overrides, Path.cwd()))
    check_display()
    if not (args.real_time_factor > 0):
        raise UsageError(f'--real-time-factor must be > 0, got {args.real_time_factor}')
    say_if_cold(scene)
    from .sim.simulation import Simulation
    sim = Simulation(scene)
    for notice in sim.notices:
        print(f'rft-sim: {notice}', file=sys.stderr)
    reached = view(sim, args.real_time_factor, until=args.duration)
    print(f'viewer closed at t = {reached:.2f} s', file=sys.stderr)
    return 0


def _check_workers(workers):
    if workers is not None and workers < 1:
        raise SceneError(f'--workers must be >= 1, got {workers}')


def cmd_validate(args):
    log = lambda line: print(f'validate: {line}', file=sys.stderr)  # noqa: E731
    _check_workers(args.workers)
    if args.workers is not None and (args.terrain or args.stability):
        raise SceneError('--workers applies to the validation report, which runs its cases '
                         'in parallel; --stability and --terrain run one case at a time')
    args.out = output_folder(args.out or fresh_folder(
        'terrain' if args.terrain else 'stability' if args.stability else 'validate'))
    say_if_cold()
    if args.terrain:
        from .validation.terrain import run_terrain
        run_terrain(args.out, quick=args.quick, log=log)
        print(f'wrote {Path(args.out) / "terrain.md"}', file=sys.stderr)
        return 0
    if args.stability:
        from .validation.stability import run_stability
        suite = run_stability(args.out, quick=args.quick, log=log)
        failed = [row for row in suite.rows if not row.held]
        print(f'{len(suite.rows) - len(failed)} of {len(suite.rows)} stability checks held')
        for row in failed:
            print(f'NOT HELD  {row.case}: {row.metric} = {row.value} ({row.bound})')
        print(f'wrote {Path(args.out) / "stability.md"}', file=sys.stderr)
        return 0
    from .validation import run_validation
    results = run_validation(args.out, quick=args.quick, log=log, workers=args.workers)
    for trend in results.trends:
        print(f'{"held    " if trend.held else "NOT HELD"}  {trend.name}')
    print(f'wrote {Path(args.out) / "report.md"} ({results.wall_s:.0f} s)', file=sys.stderr)
    return 0


def cmd_bench(args):
    from .bench import run_bench
    _check_workers(args.workers)
    args.out = output_folder(args.out or fresh_folder('bench'))
    say_if_cold()
    results = run_bench(args.out, quick=args.quick, workers=args.workers,
                        log=lambda line: print(f'bench: {line}', file=sys.stderr))
    cost = results['step_cost']
    print(f'hexapod step: {cost["sand_step_s"] * 1e6:.1f} us on sand, '
          f'{cost["rigid_step_s"] * 1e6:.1f} us rigid (x{cost["ratio_full_to_rigid"]:.2f}); '
          f'trial real-time factor {results["trial"]["real_time_factor"]:.1f}')
    print(f'wrote {Path(args.out) / "bench.md"}', file=sys.stderr)
    return 0


def cmd_sweep(args):
    from .study import load_study, run_study
    study = load_study(args.study)
    _check_workers(args.workers)
    if args.run_timeout is not None and not args.run_timeout > 0:
        raise SceneError(f'--run-timeout must be > 0 s, got {args.run_timeout}')
    out = args.out or str(Path('runs') / f'study-{Path(args.study).stem}')
    result = run_study(study, out, workers=args.workers, ray=args.ray, resume=args.resume,
                       retry_failed=args.retry_failed, run_timeout=args.run_timeout,
                       progress=not args.quiet,
                       log=lambda line: print(f'sweep: {line}', file=sys.stderr))
    print(f'{len(result.rows)} runs ({result.ran} run now, {result.resumed} before), '
          f'{result.failed} not stable; {result.wall_s:.1f} s')
    print(f'wrote {Path(out) / "results.csv"}', file=sys.stderr)
    return 0


def cmd_warmup(args):
    from .warmup import cached_kernels, warm_up
    print('warmup: every kernel into numba\'s cache, then the prebuilt kernels for this CPU '
          '(minutes where the cache is empty)', file=sys.stderr, flush=True)
    missing, prebuilt = warm_up(log=lambda line: print(line, file=sys.stderr))
    print(f'{len(cached_kernels()) - len(missing)} of {len(cached_kernels())} kernels cached'
          + (f'; not cached: {", ".join(missing)}' if missing else ''))
    print(f'warmup: {time.perf_counter() - args.started:.1f} s in all')
    print(prebuilt)  # (last: the line that says why, where they could not be built)
    return 1 if missing else 0


def build_parser():
    parser = Parser(prog='rft-sim', description=__doc__.split('\n')[0])
    parser.add_argument('--version', action='version', version=f'rft-sim {__version__}')
    commands = parser.add_subparsers(dest='command', required=True)
    scenes = commands.add_parser(
        'scenes', help="list the bundled scenes, or print one scene's effective values")
    scenes.add_argument('scene', nargs='?', help='bundled scene name or path to a scene YAML')
    scenes.add_argument('--set', action='append', metavar='KEY=VALUE',
                        help='override a scene value first (repeatable)')
    scenes.set_defaults(func=cmd_scenes)
    run = commands.add_parser('run', help='run a scene headless and write its results')
    run.add_argument('scene', help='bundled scene name, path to a scene YAML, or a robot file '
                                   '(MJCF .xml, URDF .urdf, xacro .xacro/.urdf.xacro)')
    run.add_argument('--sand-bodies', metavar='PATTERN[,PATTERN...]|auto',
                     help='bodies that touch sand (rft.sand_bodies): names, glob patterns and '
                          "auto (auto,crate: auto's picks and the crate)")
    run.add_argument('--base', choices=('floating', 'fixed'),
                     help='root body: free or welded to the world (robot.base; default: '
                          'as the file says: a URDF welded where a fixed joint hangs it from '
                          'a world link, an MJCF as written)')
    run.add_argument('--keyframe', metavar='NAME',
                     help="initial pose: the model's keyframe NAME (robot.keyframe; "
                          'default: the first of home, stand, standing, default it has, else '
                          "its first keyframe; '': its qpos0)")
    run.add_argument('--spawn', metavar='rest|drop:HEIGHT|model',
                     help='where the robot starts (robot.spawn): settled on the sand, its '
                          'sand bodies HEIGHT m above it, or as the model puts it')
    run.add_argument('--package-path', action='append', metavar='NAME=DIR',
                     help='folder of ROS package NAME for $(find NAME) and package://NAME '
                          '(repeatable; else the ament index or ROS_PACKAGE_PATH)')
    run.add_argument('--xacro-arg', action='append', metavar='K=V',
                     help='xacro argument (repeatable)')
    run.add_argument('--duration', type=float, help='sim time to run, s')
    run.add_argument('--zeta', type=float, help='sand stiffness, N/cm^3')
    run.add_argument('--timestep', type=float, help='integration timestep, s')
    run.add_argument('--plates-per-body', type=int, help='RFT plates per sand body')
    run.add_argument('--set', action='append', metavar='KEY=VALUE',
                     help='override a scene value (repeatable), e.g. --set drop_height=0.5')
    run.add_argument('--set-at', action='append', metavar='T:KEY=VALUE',
                     help='change a value when sim time reaches T s (repeatable; recorded in '
                          'summary.json); '
                          f'KEY: {", ".join(RUNTIME_SETTINGS)}, e.g. --set-at 1.5:zeta=1.0')
    run.add_argument('--commands', metavar='FILE',
                     help='replay recorded joint commands in sim time: a rosbag2 folder '
                          '(JointTrajectory, Float64MultiArray, JointState commands), or a CSV '
                          '/ YAML of timed joint targets (docs/ros.md)')
    run.add_argument('--out', help='output folder (default: runs/<scene>-<time>)')
    run.add_argument('--no-bag', action='store_true', help='do not write DIR/bag (rosbag2)')
    run.add_argument('--plates', action='store_true',
                     help='record the active plates (/rft/plates markers) in the bag')
    run.add_argument('--overwrite', action='store_true',
                     help="replace an earlier run's outputs in --out (without it, a run "
                          'writes into a new or empty folder only)')
    run.add_argument('--json', action='store_true',
                     help='print the summary (key figures, outcome, metrics) as JSON on '
                          'stdout instead of the short human summary')
    run.add_argument('--quiet', action='store_true',
                     help='print only errors (no progress bar, notices or summary; --json '
                          'still prints its JSON)')
    run.add_argument('--video', action='store_true',
                     help=f'render the run into DIR/{VIDEO_FILE} (video.enabled; the video.* '
                          'keys set camera, size, rate: docs/video.md)')
    run.set_defaults(func=cmd_run)
    render = commands.add_parser('render', help="make a run's video from its bag, without "
                                 'simulating again')
    render.add_argument('run', help='run folder (DIR of rft-sim run, with bag/) or a bag folder '
                                    '(ros2 bag record of the node; needs --scene)')
    render.add_argument('--scene', help='the scene or robot file the bag ran (default: the '
                                        "run's summary.json)")
    render.add_argument('--set', action='append', metavar='KEY=VALUE',
                        help='override a scene value, e.g. --set video.camera=fixed')
    render.add_argument('--out', help=f'video file (default: RUN/{VIDEO_FILE}, or BAG.mp4)')
    render.add_argument('--force', action='store_true', help='replace an existing video')
    render.set_defaults(func=cmd_render)
    view = commands.add_parser('view', help="run a scene in MuJoCo's interactive viewer "
                                            '(needs a display)')
    view.add_argument('scene', help='bundled scene name, path to a scene YAML, or a robot file')
    view.add_argument('--set', action='append', metavar='KEY=VALUE',
                      help='override a scene value (repeatable)')
    view.add_argument('--real-time-factor', type=float, default=1.0,
                      help='sim seconds per wall second (default 1: real time)')
    view.add_argument('--duration', type=float, help='close after this much sim time, s')
    view.set_defaults(func=cmd_view)
    commands.add_parser(
        'warmup', help='compile the kernels now (otherwise the first run after an install does)'
    ).set_defaults(func=cmd_warmup)
    bench = commands.add_parser('bench', help='speed against plain MuJoCo and against error')
    bench.add_argument('--quick', action='store_true', help='few, short measurements')
    bench.add_argument('--out', help='output folder (default: a fresh runs/bench-<time>; '
                                     'the committed results: --out bench/results)')
    bench.add_argument('--workers', type=int,
                       help='processes for the speed-against-error sweep (default: all cores; '
                            'the step-cost and trial timings always run alone)')
    bench.set_defaults(func=cmd_bench)
    validate = commands.add_parser(
        'validate', help="reproduce the RFT-SiM paper's trends as a report with plots")
    validate.add_argument('--quick', action='store_true',
                          help='coarse plates and fewer cases: about half a minute on 2 cores '
                               '(the full run: one to two minutes)')
    validate.add_argument('--out',
                          help='output folder for report.md, results.json and plots '
                               '(default: a fresh runs/validate-<time>; the committed '
                               'report: --out validation)')
    validate.add_argument('--stability', action='store_true',
                          help='run the stability suite instead (drops, standing still, '
                               'start/stop, extreme sand, timesteps, divergence): '
                               'stability.md and plots')
    validate.add_argument('--terrain', action='store_true',
                          help='run the terrain study instead (slopes, deformable sand, a '
                               'patch of loose sand, step cost per surface): terrain.md')
    validate.add_argument('--workers', type=int,
                          help="processes the report's cases run on (default: all cores)")
    validate.set_defaults(func=cmd_validate)
    sweep = commands.add_parser('sweep', help='run a study: a scene over varied values, '
                                'on all cores or a Ray cluster (docs/studies.md)')
    sweep.add_argument('study', help='study YAML (scene, vary, repeats, metrics)')
    sweep.add_argument('--out', help='output folder (default: runs/study-<name>)')
    where = sweep.add_mutually_exclusive_group()
    where.add_argument('--workers', type=int, help='local worker processes (default: all cores)')
    where.add_argument('--ray', metavar='auto|ADDRESS',
                       help="run on a Ray cluster: 'auto', HOST:PORT, ray://HOST:PORT, or "
                            "'local' (pip install \"rft_sim_ros[ray]\")")
    sweep.add_argument('--resume', action='store_true',
                       help='finish a study in --out: runs already recorded are not repeated')
    sweep.add_argument('--retry-failed', action='store_true',
                       help='with --resume: run again the runs recorded as not stable')
    sweep.add_argument('--run-timeout', type=float, metavar='S',
                       help='wall-clock limit per run, s (recorded as a failed run)')
    sweep.add_argument('--quiet', action='store_true', help='no progress bar')
    sweep.set_defaults(func=cmd_sweep)
    return parser


def joined_values(parser, argv):
    """argv with each value that starts with '-' joined to its option (`--set-at -1:zeta=1`
    -> `--set-at=-1:zeta=1`), so that the value is checked, and refused with its own reason,
    instead of argparse taking it for an option."""
    actions = [*parser._actions, *(action for sub in parser._subparsers._group_actions[0]
                                   .choices.values() for action in sub._actions)]
    options = {option for action in actions for option in action.option_strings}
    takes_value = {option for action in actions for option in action.option_strings
                   if action.nargs is None}
    joined = []
    for word in argv:
        if (joined and joined[-1] in takes_value and word.startswith('-')
                and word not in options and len(word) > 1):
            joined[-1] = f'{joined[-1]}={word}'
        else:
            joined.append(word)
    return joined


def main(argv=None, started=None):
    """The `rft-sim` command on `argv` (default: the process's arguments); `started`:
    `time.perf_counter()` when the command began (the entry point's, before the imports of
    this module; default: now), from which a run's time "in all" counts. Returns the exit
    status."""
    started = time.perf_counter() if started is None else started
    parser = build_parser()
    args = parser.parse_args(joined_values(parser, sys.argv[1:] if argv is None else argv))
    args.started = started
    try:
        with interrupts_never_lost(), held_while_compiling():
            return args.func(args)
    except (SceneError, ValueError) as error:
        print(f'rft-sim: error: {error}', file=sys.stderr)
        return 2
    except KeyboardInterrupt as interrupt:  # Ctrl-C outside a run's loop (or a second one)
        release_quietly(interrupt)
        print('\nrft-sim: interrupted', file=sys.stderr)
        return 128 + signal.SIGINT
    except BrokenPipeError:  # output piped into a reader that left (`rft-sim scenes | head`)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # (nothing left to
        return 0  # flush at exit, which would raise again)


if __name__ == '__main__':
    sys.exit(main())
