"""`rft-sim` as a user meets it: one-line errors (exit 2) before anything runs, output
folders, --version, Ctrl-C / SIGTERM on a running `run`, MuJoCo's log, the written summary."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from rosbags.highlevel import AnyReader

from rft_sim_ros import __version__
from rft_sim_ros.cli import main
from rft_sim_ros.sim.simulation import Simulation
from rft_sim_ros.scenes.config import load_scene

#: A short, cheap run.
SHORT = ['run', 'plate_drop', '--duration', '0.05', '--quiet', '--set', 'drop_height=0.01']


def one_error_line(capsys, *phrases):
    """The captured stderr is exactly one `rft-sim: error:` line holding every phrase (after
    the notice that a cold kernel cache prints first, if the cache is cold)."""
    lines = [line for line in capsys.readouterr().err.strip().splitlines()
             if not line.startswith('rft-sim: compiling kernels')]
    assert len(lines) == 1, lines
    assert lines[0].startswith('rft-sim: error: '), lines
    for phrase in phrases:
        assert phrase in lines[0], lines
    return lines[0]


def exit_code(argv):
    """main(argv)'s exit status, whether it returns it or argparse exits."""
    try:
        return main(argv)
    except SystemExit as stop:
        return stop.code


# --- output folders: checked before running ------------------------------------------------

@pytest.mark.parametrize('bag', [[], ['--no-bag']])
def test_out_at_a_file_or_under_one_is_refused_before_running(tmp_path, capsys, bag):
    existing = tmp_path / 'results.txt'
    existing.write_text('keep me')
    for out in (existing, existing / 'run'):
        assert exit_code([*SHORT, '--out', str(out), *bag]) == 2
        one_error_line(capsys, str(out), 'is a file')
    assert existing.read_text() == 'keep me'


@pytest.mark.parametrize('bag', [[], ['--no-bag']])
def test_out_where_nothing_can_be_written_is_refused(capsys, bag):
    assert exit_code([*SHORT, '--out', '/proc/rft-sim-run', *bag]) == 2
    one_error_line(capsys, '/proc/rft-sim-run', 'cannot write there')


@pytest.mark.skipif(os.geteuid() == 0, reason='root may write into a read-only folder')
def test_out_in_a_read_only_folder_is_refused(tmp_path, capsys):
    locked = tmp_path / 'locked'
    locked.mkdir()
    locked.chmod(0o555)
    try:
        assert exit_code([*SHORT, '--out', str(locked / 'run'), '--no-bag']) == 2
        one_error_line(capsys, 'cannot write there')
    finally:
        locked.chmod(0o755)


def test_a_scene_that_fails_to_build_leaves_no_folder_behind(tmp_path, capsys):
    model = tmp_path / 'broken.xml'
    model.write_text('<mujoco>\n  <worldbody>\n    <body name="a">\n  </worldbody>\n</mujoco>\n')
    scene = tmp_path / 'broken.yaml'
    scene.write_text(yaml.safe_dump({**load_scene('plate_drop').raw, 'model': str(model)}))
    out = tmp_path / 'runs' / 'broken'
    assert exit_code(['run', str(scene), '--out', str(out), '--quiet']) == 2
    one_error_line(capsys, str(model), 'line ')   # MuJoCo's line number, the file named
    assert not (tmp_path / 'runs').exists()


def test_validate_and_bench_write_into_a_fresh_folder_unless_told(monkeypatch, tmp_path):
    import rft_sim_ros.bench as bench
    import rft_sim_ros.validation as validation
    monkeypatch.chdir(tmp_path)
    seen = []

    class Results:
        trends, wall_s = [], 0.0

    monkeypatch.setattr(validation, 'run_validation', lambda out, quick, log, workers:
                        seen.append((Path(out), workers)) or Results())
    monkeypatch.setattr(bench, 'run_bench', lambda out, quick, log, workers: seen.append(
        (Path(out), workers)) or {
        'step_cost': {'sand_step_s': 1.0, 'rigid_step_s': 1.0, 'ratio_full_to_rigid': 1.0},
        'trial': {'real_time_factor': 1.0}})
    assert main(['validate', '--quick']) == 0
    assert main(['bench', '--quick', '--workers', '1']) == 0
    assert main(['validate', '--quick', '--out', 'validation', '--workers', '2']) == 0
    assert [p.parent.name for p, _ in seen[:2]] == ['runs', 'runs']
    assert seen[0][0].name.startswith('validate-') and seen[1][0].name.startswith('bench-')
    assert seen[2][0] == Path('validation')
    assert [workers for _, workers in seen] == [None, 1, 2]  # None: all cores


@pytest.mark.parametrize('argv, words', [
    (['validate', '--workers', '0'], ('--workers must be >= 1',)),
    (['bench', '--workers', '-1'], ('--workers must be >= 1',)),
    (['validate', '--stability', '--workers', '2'], ('--workers applies to the validation',)),
])
def test_bad_worker_counts_are_refused_before_anything_runs(argv, words, tmp_path, capsys,
                                                            monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert exit_code(argv) == 2
    one_error_line(capsys, *words)
    assert not (tmp_path / 'runs').exists()


# --- messages --------------------------------------------------------------------------------

def test_version(capsys):
    assert exit_code(['--version']) == 0
    assert capsys.readouterr().out.strip() == f'rft-sim {__version__}'


@pytest.mark.parametrize('argv, phrases', [
    (['run', 'plate_drop', '--zeta', 'abc'], ['--zeta', "'abc'"]),
    (['run'], ['scene']),
    (['run', 'plate_drop', '--set-at', '-1:zeta=1'], ['T >= 0', '-1:zeta=1']),
    (['run', 'plate_drop', '--set-at', '1:zeta=-2'], ['zeta']),
    (['run', 'nosuch'], ['unknown scene', 'hexapod', 'plate_drop']),
    (['run', 'missing.yaml'], ['missing.yaml', 'not found']),
    (['run', 'sub/missing'], ['sub/missing', 'not found']),
])
def test_bad_arguments_give_one_error_line_and_exit_2(capsys, argv, phrases):
    assert exit_code(argv) == 2
    one_error_line(capsys, *phrases)


def test_yaml_syntax_error_names_the_file_and_line(tmp_path, capsys):
    scene = tmp_path / 'scene.yaml'
    scene.write_text('name: bad\nscenario: plate_drop\n  model: [x\n')
    assert exit_code(['run', str(scene)]) == 2
    line = one_error_line(capsys, f'{scene}:3', 'not valid YAML')
    assert 'unicode string' not in line


def test_unknown_scenario_lists_the_known_ones(tmp_path, capsys):
    scene = tmp_path / 'scene.yaml'
    scene.write_text(yaml.safe_dump({**load_scene('plate_drop').raw,
                                     'scenario': 'walking_on_water'}))
    assert exit_code(['run', str(scene), '--no-bag', '--out', str(tmp_path / 'o')]) == 2
    one_error_line(capsys, "'walking_on_water'", 'unknown scenario', 'hexapod', 'plate_drop',
                   'external')


def test_set_at_past_the_end_warns_and_the_schedule_is_recorded(tmp_path, capsys):
    out = tmp_path / 'run'
    assert main(['run', 'plate_drop', '--duration', '0.2', '--zeta', '5', '--set-at',
                 '0.1:zeta=1', '--set-at', '99:zeta=2', '--out', str(out),
                 '--no-bag']) == 0
    err = capsys.readouterr().err
    assert 'rft-sim: warning: --set-at 99:zeta=2 comes after the run ends (0.2 s)' in err
    summary = json.loads((out / 'summary.json').read_text())
    assert summary['zeta'] == 5.0 and summary['zeta_final'] == 1.0
    assert summary['schedule'] == [{'time_s': 0.1, 'zeta': 1.0, 'applied': True},
                                   {'time_s': 99.0, 'zeta': 2.0, 'applied': False}]


def test_mujoco_messages_go_to_the_runs_log_not_the_working_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / 'run'
    code = main(['run', 'blade_drag', '--set', 'servo_kp=1e10', '--duration', '0.6',
                 '--out', str(out), '--quiet', '--no-bag'])
    assert code == 1                                      # diverged, and said so
    assert not (tmp_path / 'MUJOCO_LOG.TXT').exists()
    assert 'unstable' in (out / 'mujoco.log').read_text()


def test_written_summary_has_no_float_noise(tmp_path):
    out = tmp_path / 'run'
    assert main([*SHORT, '--out', str(out), '--no-bag']) == 0
    text = (out / 'summary.json').read_text()
    numbers = [float(word.strip(',')) for word in text.split()
               if word.strip(',').replace('.', '', 1).replace('e-', '', 1).isdigit()]
    assert numbers
    assert all(float(f'{value:.12g}') == value for value in numbers)
    assert json.loads(text)['sim_time_s'] == 0.05


# --- Ctrl-C and SIGTERM on a running `rft-sim run` -------------------------------------------

def _as_in_a_terminal():
    """The child's SIGINT as a terminal's foreground job has it (a background job, such as
    this test run may be, inherits SIGINT ignored, which `rft-sim run` respects)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _long_run_recording(out):
    """A warm `rft-sim run plate_drop` of 600 s into `out`, as a terminal's foreground job,
    once it is stepping and has written to its bag."""
    Simulation(load_scene('plate_drop'))  # kernels in numba's cache: the child starts warm
    child = subprocess.Popen(
        [sys.executable, '-m', 'rft_sim_ros.cli', 'run', 'plate_drop', '--duration', '600',
         '--out', str(out), '--quiet', '--json'], stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True, preexec_fn=_as_in_a_terminal)
    bag_file = out / 'bag' / 'bag.mcap'
    deadline = time.monotonic() + 120
    while not (bag_file.exists() and bag_file.stat().st_size > 0):  # stepping, recording
        assert child.poll() is None and time.monotonic() < deadline, child.communicate()
        time.sleep(0.05)
    return child


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM])
def test_signal_stops_a_run_with_its_bag_closed_and_summary_marked(tmp_path, signum):
    out = tmp_path / 'run'
    child = _long_run_recording(out)
    child.send_signal(signum)
    stdout, stderr = child.communicate(timeout=60)
    assert child.returncode == 128 + signum, stderr
    assert 'Traceback' not in stderr
    summary = json.loads((out / 'summary.json').read_text())
    assert summary['interrupted'] is True and summary['stable'] is True
    assert signal.Signals(signum).name in summary['reason']
    assert 0 < summary['sim_time_s'] < 600
    assert json.loads(stdout)['interrupted'] is True
    with AnyReader([out / 'bag']) as bag:                 # a complete, readable bag
        clocks = [m for m in bag.messages() if m[0].topic == '/clock']
    published = round(summary['sim_time_s'] * 100)        # 100 Hz publish rate
    assert abs(len(clocks) - published) <= 1


def test_ctrl_c_while_the_cli_loads_exits_130_without_a_traceback(tmp_path):
    """A Ctrl-C while `rft-sim` is still importing numpy, MuJoCo and numba ends like any
    other: one line, exit 130, nothing written (the console script's entry guards it). The
    signal goes when the child reports numpy imported (Python's -X importtime lines, one per
    finished import), well before the CLI's imports end, on any machine."""
    env = dict(os.environ, PYTHONPROFILEIMPORTTIME='1')
    child = subprocess.Popen(
        [sys.executable, '-m', 'rft_sim_ros', 'run', 'plate_drop', '--out',
         str(tmp_path / 'run'), '--quiet'], env=env, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True, preexec_fn=_as_in_a_terminal)
    lines = []
    for line in child.stderr:
        lines.append(line)
        if line.split('|')[-1].strip() == 'numpy':
            child.send_signal(signal.SIGINT)
            break
    stdout, stderr = child.communicate(timeout=120)
    assert not any(line.split('|')[-1].strip() == 'rft_sim_ros.cli' for line in lines)
    assert child.returncode == 130, stderr
    assert 'Traceback' not in stderr and 'rft-sim: interrupted' in stderr
    assert not (tmp_path / 'run').exists()


def _pressing_ctrl_c(function):
    """`function`, with a Ctrl-C pressed while it runs."""
    def pressed(*args, **kwargs):
        signal.raise_signal(signal.SIGINT)  # (its handler runs here, in this thread)
        return function(*args, **kwargs)
    return pressed


def test_ctrl_c_while_a_run_is_set_up_writes_nothing(tmp_path, capsys, monkeypatch,
                                                     ctrl_c_raises):
    from rft_sim_ros import cli
    monkeypatch.setattr(cli, 'say_if_cold', _pressing_ctrl_c(cli.say_if_cold))
    out = tmp_path / 'run'
    assert main([*SHORT, '--out', str(out)]) == 130
    err = capsys.readouterr().err
    assert 'interrupted before the run started: nothing written' in err
    assert 'Traceback' not in err and not out.exists()


def test_ctrl_c_once_the_output_folder_exists_ends_in_a_complete_interrupted_run(
        tmp_path, capsys, monkeypatch, ctrl_c_raises):
    from rft_sim_ros.ros import recording
    monkeypatch.setattr(recording, 'BagRecorder', _pressing_ctrl_c(recording.BagRecorder))
    out = tmp_path / 'run'
    assert main([*SHORT, '--out', str(out)]) == 130
    summary = json.loads((out / 'summary.json').read_text())
    assert summary['interrupted'] is True and summary['sim_time_s'] == 0
    assert 'SIGINT received' in summary['reason']
    with AnyReader([out / 'bag']) as bag:  # closed, readable: the initial state alone
        assert {time_ns for _, time_ns, _ in bag.messages()} == {0}
    assert 'Traceback' not in capsys.readouterr().err


# --- first run: a cold kernel cache is announced at once ---------------------------------------

def test_a_cold_kernel_cache_is_announced_before_compiling(tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / 'empty-cache'))
    child = subprocess.Popen(
        [sys.executable, '-m', 'rft_sim_ros.cli', 'run', 'plate_drop', '--out',
         str(tmp_path / 'run')], env=env, stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE, text=True)
    try:
        started = time.monotonic()
        first = child.stderr.readline()
        waited = time.monotonic() - started
    finally:
        child.kill()
        child.communicate()
    assert first.startswith('rft-sim: compiling kernels, first run only'), first
    assert waited < 20  # at start-up (a few s of imports), not after the 30-60 s compile


def test_warmup_leaves_every_kernel_cached(capsys):
    from rft_sim_ros import warmup
    assert main(['warmup']) == 0
    total = len(warmup.cached_kernels())
    assert total >= 20  # the engine's, the law's and the gaits' kernels were all found
    assert f'{total} of {total} kernels cached' in capsys.readouterr().out
    assert warmup.uncached() == []
    from rft_sim_ros.ros import jazzy_types, topics
    assert set(jazzy_types._read(jazzy_types.cache_file())) >= topics.RECORDABLE_TYPES


def test_an_ignored_sigint_stays_ignored(tmp_path):
    """A run started as a background job (SIGINT ignored, as `cmd &` in a script) is not
    stopped by the Ctrl-C meant for the foreground."""
    out = tmp_path / 'run'
    child = subprocess.Popen(
        [sys.executable, '-m', 'rft_sim_ros.cli', 'run', 'plate_drop', '--duration', '1.5',
         '--out', str(out), '--quiet', '--no-bag'], stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    time.sleep(1.0)
    child.send_signal(signal.SIGINT)
    stdout, stderr = child.communicate(timeout=120)
    assert child.returncode == 0, stderr
    summary = json.loads((out / 'summary.json').read_text())
    assert summary['interrupted'] is False and summary['sim_time_s'] == 1.5


def test_ctrl_c_twice_quits_at_once_without_a_traceback(tmp_path):
    """The first Ctrl-C asks the run to stop; a second one right after (while it closes the
    bag, writes the summary and plots) quits at once: exit 130, no traceback."""
    out = tmp_path / 'run'
    child = _long_run_recording(out)
    child.send_signal(signal.SIGINT)
    time.sleep(0.01)
    if child.poll() is None:
        child.send_signal(signal.SIGINT)
    stdout, stderr = child.communicate(timeout=120)
    assert child.returncode == 130, stderr
    assert 'Traceback' not in stderr


def test_starting_the_cli_leaves_the_mesh_libraries_unloaded():
    # trimesh (with scipy) takes ~0.5 s to import: only making plates, not reading them from
    # the plate cache, and converting mesh files need it, so every start would pay for it
    probe = 'import sys, rft_sim_ros.cli; print(sorted({"trimesh", "scipy"} & set(sys.modules)))'
    done = subprocess.run([sys.executable, '-c', probe], capture_output=True, text=True,
                          check=True, timeout=60)
    assert done.stdout.strip() == '[]'


def test_rft_sim_keeps_native_thread_pools_to_one_thread_unless_the_user_says(monkeypatch,
                                                                              capsys):
    # before numpy loads: runs are single-threaded, and a single-threaded parent forks its
    # study workers (study/pool.py)
    from rft_sim_ros.__main__ import main as entry
    monkeypatch.delenv('OMP_NUM_THREADS', raising=False)
    monkeypatch.delenv('OPENBLAS_NUM_THREADS', raising=False)
    monkeypatch.setenv('MKL_NUM_THREADS', '3')
    with pytest.raises(SystemExit):
        entry(['--version'])
    assert [os.environ.get(name) for name in
            ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS')] == ['1', '1', '3']


def test_a_runs_time_in_all_counts_from_the_entry_point_before_the_clis_imports(monkeypatch):
    """`rft-sim`'s entry point takes the time before it imports the CLI (numpy, MuJoCo and
    the scene code) and hands it to `cli.main`, from which a run's "in all" counts."""
    import rft_sim_ros.cli as cli
    from rft_sim_ros.__main__ import main as entry
    handed = []
    monkeypatch.setattr(cli, 'main', lambda argv, started: handed.append(started) or 0)
    called = time.perf_counter()
    assert entry(['--version']) == 0
    assert len(handed) == 1 and called <= handed[0] <= time.perf_counter()
