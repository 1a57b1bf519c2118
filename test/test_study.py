"""Studies (`rft-sim sweep`): study files expanded into runs, the local process pool (results
identical to serial runs, a failing run recorded, a killed worker retried, resume) and the
Ray backend against a real single-machine Ray cluster on loopback."""
import io
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import yaml

from rft_sim_ros.cli import main
from rft_sim_ros.native_threads import ONE_THREAD
from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.resources import config_dir
from rft_sim_ros.study import StudyError, load_study, run_study, study_from_mapping
from rft_sim_ros.study.cost import dearest_first, run_cost
from rft_sim_ros.study.execute import RunTask, execute
from rft_sim_ros.study.pool import PARENT_CHECK_S, map_unordered
from rft_sim_ros.study.progress import StudyProgress
from rft_sim_ros.study.table import read_csv, row

#: A short plate drop: the plate hits the sand after ~0.14 s and is at rest by 0.4 s.
DROP = {'scene': 'plate_drop', 'duration': 0.4, 'set': {'rft.plates_per_body': 100},
        'metrics': ['max_sinkage_m', 'final_sinkage_m']}


def _study(**changes):
    return study_from_mapping({**DROP, **changes})


def test_grid_expands_every_combination_with_repeats():
    study = _study(vary={'zeta': [1.0, 3.75], 'mass': [0.5, 1.0, 2.0]}, repeats=2)
    assert study.keys == ('zeta', 'mass')
    assert len(study.runs) == 12
    points = [(r.varied['zeta'], r.varied['mass'], r.repeat) for r in study.runs]
    assert len(set(points)) == 12
    assert {p[:2] for p in points} == {(z, m) for z in (1.0, 3.75) for m in (0.5, 1.0, 2.0)}
    assert [r.run_id for r in study.runs] == [f'{i:02d}' for i in range(12)]
    assert all(r.overrides['rft.plates_per_body'] == 100 for r in study.runs)


def test_list_and_samples():
    listed = _study(vary=[{'zeta': 1.0}, {'mass': 2.0, 'timestep': 0.0005}])
    assert [r.varied for r in listed.runs] == [{'zeta': 1.0}, {'mass': 2.0, 'timestep': 0.0005}]
    assert listed.keys == ('zeta', 'mass', 'timestep')
    spec = {'sample': {'count': 20, 'seed': 7, 'log': ['zeta'],
                       'ranges': {'zeta': [0.5, 5.0], 'rft.plates_per_body': [50, 60]}}}
    sampled = _study(vary=spec)
    again = _study(vary=spec)
    assert [r.varied for r in sampled.runs] == [r.varied for r in again.runs]  # seeded
    zetas = [r.varied['zeta'] for r in sampled.runs]
    plates = [r.varied['rft.plates_per_body'] for r in sampled.runs]
    assert all(0.5 <= z <= 5.0 for z in zetas) and len(set(zetas)) == 20
    assert all(isinstance(p, int) and 50 <= p <= 60 for p in plates)
    other = _study(vary={'sample': {**spec['sample'], 'seed': 8}})
    assert [r.varied for r in other.runs] != [r.varied for r in sampled.runs]


@pytest.mark.parametrize('changes, message', [
    ({'vary': {'no_such_key': [1, 2]}}, 'unknown setting'),
    ({'vary': {'zeta': [1.0, -1.0]}}, 'zeta'),
    ({'vary': {'zeta': 1.0}}, 'non-empty list'),
    ({'vary': {'sample': {'count': 3, 'ranges': {'zeta': [1, 2]}}}}, 'seed'),
    ({'vary': {'zeta': [1.0]}, 'metrics': []}, 'metrics'),
    ({'vary': {'zeta': [1.0]}, 'repeat': 2}, 'unknown keys'),
    ({'vary': {'zeta': [1.0]}, 'scene': 'no_such_scene'}, 'unknown scene'),
    # terrain read before any run starts: a bed too large for the machine, a map file
    ({'vary': {'sand.deformable.cell': [0.01, 1e-4]},
      'set': {'sand.deformable.enabled': True, 'sand.deformable.size': [100.0, 100.0]}},
     r'a bed \(0.0001 m cells\) of 1000001 x 1000001 nodes'),
    ({'vary': {'sand.zeta_map.file': ['missing.npy']}, 'set': {'sand.zeta_map.size': [1, 1]}},
     'not found'),
])
def test_bad_studies_are_refused_with_the_reason(changes, message):
    with pytest.raises(StudyError, match=message):
        _study(**changes)


def test_the_contract_study_file_loads(tmp_path):
    path = tmp_path / 'study.yaml'
    path.write_text('scene: hexapod\nvary: {zeta: [1.0, 3.75], payload: [0.0, 1.0]}\n'
                    'repeats: 1\nmetrics: [forward_distance_m, mean_sinkage_m]\n')
    study = load_study(path)
    assert len(study.runs) == 4 and study.keys == ('zeta', 'payload')
    path.write_text('scene: hexapod\nvary: {timestep: [5e-4, 1e-3]}\nmetrics: [steps]\n')
    assert [run.overrides['timestep'] for run in load_study(path).runs] == [5e-4, 1e-3]


def test_list_values_are_written_to_the_table_as_json(tmp_path):
    """A varied list (a surface size, zeta-map regions) reads back from results.csv and
    results.npz as JSON, not as Python's repr."""
    from rft_sim_ros.study.table import column_array, write_csv
    regions = [{'x': [0.0, 0.2], 'y': [-1, 1], 'factor': 0.5}]
    write_csv(tmp_path / 'r.csv', ['size', 'regions'], [{'size': [2, 2], 'regions': regions}])
    [read] = read_csv(tmp_path / 'r.csv')
    assert json.loads(read['size']) == [2, 2] and json.loads(read['regions']) == regions
    assert json.loads(column_array([regions, None])[0]) == regions


def test_a_run_that_raises_or_times_out_is_recorded():
    broken = execute(RunTask('0', 'plate_drop', {'mass': 'heavy'}, 0.1))
    assert not broken['stable'] and broken['reason'].startswith('error: ')
    assert broken['summary'] is None
    slow = execute(RunTask('1', 'plate_drop', {}, 30.0, timeout=0.2))
    assert not slow['stable'] and slow['reason'].startswith('timeout')
    assert slow['wall_time_s'] < 5.0


def test_runs_are_costed_by_steps_times_plates():
    study = _study(vary={'timestep': [0.002, 0.0005], 'rft.plates_per_body': [50, 200]},
                   duration=0.2)
    cost = {(r.varied['timestep'], r.varied['rft.plates_per_body']): r.cost for r in study.runs}
    assert cost[(0.0005, 200)] == pytest.approx(16 * cost[(0.002, 50)])  # 4x steps, 4x plates
    assert cost[(0.002, 50)] == pytest.approx(0.2 / 0.002 * 50)
    hexapod = run_cost(load_scene('hexapod'))  # 12 sand bodies x 500 plates, 7500 steps
    assert hexapod == pytest.approx(12 * 500 * 6.0 / 0.0008)
    assert dearest_first([1.0, 3.0, 2.0, 3.0]) == [1, 3, 2, 0]


def test_the_dearest_runs_go_out_first(tmp_path):
    study = _study(vary={'timestep': [0.002, 0.001, 0.0005]}, duration=0.2)
    result = run_study(study, tmp_path / 'out', workers=1, progress=False)
    started = sorted(result.records.values(), key=lambda record: record['started_at'])
    by_id = {run.run_id: run for run in study.runs}
    assert [by_id[r['run_id']].varied['timestep'] for r in started] == [0.0005, 0.001, 0.002]
    assert [row['timestep'] for row in result.rows] == [0.002, 0.001, 0.0005]  # listed order


def test_a_metric_is_the_scenarios_else_every_scenes_else_the_summarys_own():
    """A study of one's own robot file (no scenario metrics) tabulates the generic metrics
    and the summary's numbers; a scenario's metric wins a shared name; a list of numbers is
    a metric by its components (name[i]), not whole; text is none."""
    study = _study(metrics=['max_sinkage_m', 'base_displacement_m', 'real_time_factor',
                            'base_displacement_xyz_m', 'scene', 'base_displacement_xyz_m[0]',
                            'base_displacement_xyz_m[2]'], vary={'zeta': [1.0]})
    record = {'summary': {'scene': 'plate_drop', 'stable': True, 'real_time_factor': 12.5,
                          'generic_metrics': {'base_displacement_m': 0.25, 'max_sinkage_m': 9.0,
                                              'base_displacement_xyz_m': [0.25, 0.0, 0.0]},
                          'metrics': {'max_sinkage_m': 0.02}},
              'wall_time_s': 1.0, 'stable': True, 'reason': None}
    cells = row(study, study.runs[0], record)
    assert cells['max_sinkage_m'] == 0.02 and cells['base_displacement_m'] == 0.25
    assert cells['real_time_factor'] == 12.5
    assert cells['base_displacement_xyz_m'] is None and cells['scene'] is None
    assert (cells['base_displacement_xyz_m[0]'], cells['base_displacement_xyz_m[2]']) == (0.25,
                                                                                          0.0)


@pytest.fixture(scope='module')
def local_study(tmp_path_factory):
    """A 2 x 2 plate-drop grid plus one broken run, on two local workers."""
    out = tmp_path_factory.mktemp('study') / 'out'
    study = _study(vary=[{'zeta': z, 'mass': m} for z in (1.0, 3.75) for m in (0.5, 2.0)]
                   + [{'zeta': 1.0, 'mass': 'heavy'}])
    return study, out, run_study(study, out, workers=2, progress=False)


def test_local_study_writes_table_summaries_and_plots(local_study):
    study, out, result = local_study
    rows = read_csv(out / 'results.csv')
    assert list(rows[0]) == ['run_id', 'repeat', 'zeta', 'mass', 'max_sinkage_m',
                             'final_sinkage_m', 'wall_time_s', 'stable', 'reason']
    assert [r['run_id'] for r in rows] == ['0', '1', '2', '3', '4']
    assert [r['stable'] for r in rows] == ['True'] * 4 + ['False']
    assert rows[4]['reason'].startswith('error: ') and rows[4]['max_sinkage_m'] == ''
    assert result.failed == 1 and result.ran == 5
    # physics through the table: heavier plates and looser sand sink deeper
    depth = {(float(r['zeta']), float(r['mass'])): float(r['max_sinkage_m']) for r in rows[:4]}
    assert depth[1.0, 2.0] > depth[1.0, 0.5] > depth[3.75, 0.5] > 0
    assert depth[1.0, 2.0] > depth[3.75, 2.0] > depth[3.75, 0.5]
    columns = np.load(out / 'results.npz')
    assert columns['max_sinkage_m'].dtype == float and math.isnan(columns['max_sinkage_m'][4])
    assert columns['stable'].dtype == bool and list(columns['stable']) == [True] * 4 + [False]
    saved = json.loads((out / 'runs' / '0' / 'summary.json').read_text())
    assert saved['study_run']['overrides'] == study.runs[0].overrides
    assert saved['summary']['metrics']['max_sinkage_m'] == float(rows[0]['max_sinkage_m'])
    assert sorted(p.name for p in (out / 'plots').iterdir()) == sorted(
        f'{m}_vs_{k}.png' for m in study.metrics for k in study.keys)
    page = (out / 'report.html').read_text()                # the study's page, each run's
    assert all(f'href="runs/{i}/report.html"' in page for i in range(5))
    assert all((out / 'runs' / str(i) / 'report.html').is_file() for i in range(5))


def test_local_study_matches_serial_runs_bit_for_bit(local_study):
    study, out, result = local_study
    for run, row in zip(study.runs[:4], result.rows):
        serial = execute(RunTask(run.run_id, study.scene, run.overrides, study.duration))
        assert serial['summary']['metrics'] == json.loads(
            (out / 'runs' / run.run_id / 'summary.json').read_text())['summary']['metrics']
        assert row['max_sinkage_m'] == serial['summary']['metrics']['max_sinkage_m']


def test_resume_runs_only_what_is_missing(local_study, tmp_path):
    study, out, result = local_study
    copy = tmp_path / 'out'
    shutil.copytree(out, copy)
    with pytest.raises(StudyError, match='--resume'):
        run_study(study, copy, workers=1, progress=False)
    (copy / 'runs' / '2' / 'summary.json').unlink()
    (copy / 'runs' / '3' / 'summary.json').write_text('{"truncated')  # a crash mid-write
    resumed = run_study(study, copy, workers=1, progress=False, resume=True)
    assert (resumed.ran, resumed.resumed) == (2, 3)
    assert resumed.rows == [{**r, 'wall_time_s': n['wall_time_s']}
                            for r, n in zip(result.rows, resumed.rows)]
    assert (read_csv(copy / 'results.csv')[2]['max_sinkage_m']
            == repr(result.rows[2]['max_sinkage_m']))
    retried = run_study(study, copy, workers=1, progress=False, resume=True, retry_failed=True)
    assert (retried.ran, retried.resumed) == (1, 4)


def test_resume_redoes_a_run_whose_files_changed(tmp_path):
    """A study's run records the SHA-256 of each file it reads, as its scene resolves them
    (here a grid named relative to the scene file, in another folder than the study's):
    after the grid is rewritten (0.3 m higher), --resume redoes the runs that read it, not
    the others."""
    scenes = tmp_path / 'scenes'
    scenes.mkdir()
    np.save(scenes / 'g.npy', np.zeros((5, 5)))
    text = (config_dir() / 'plate_drop.yaml').read_text()
    grid = '  surface: {type: grid, file: g.npy, size: [1.0, 1.0]}'
    (scenes / 'drop.yaml').write_text(text.replace('  surface_height: 0.0  # m', grid))
    study = study_from_mapping({
        'scene': str(scenes / 'drop.yaml'), 'duration': 0.05,
        'vary': [{'zeta': 2.0}, {'sand.surface': {'type': 'slope'}}],
        'metrics': ['max_sinkage_m']}, base=tmp_path)
    out = tmp_path / 'out'
    run_study(study, out, workers=1, progress=False)
    saved = json.loads((out / 'runs' / '0' / 'summary.json').read_text())['study_run']
    assert {str(scenes / 'g.npy'), str(scenes / 'drop.yaml')} <= set(saved['files'])
    again = run_study(study, out, workers=1, progress=False, resume=True)
    assert (again.ran, again.resumed) == (0, 2)
    np.save(scenes / 'g.npy', np.full((5, 5), 0.3))
    changed = run_study(study, out, workers=1, progress=False, resume=True)
    assert (changed.ran, changed.resumed) == (1, 1)


def die_once(item):
    """Kill this worker process the first time `item` (a marker path) is seen; later return
    the item's name."""
    path, always = item
    if always or not os.path.exists(path):
        open(path, 'w').close()
        os.kill(os.getpid(), signal.SIGKILL)
    return os.path.basename(path)


def test_a_killed_worker_is_replaced_and_its_item_retried_once(tmp_path):
    items = [(str(tmp_path / f'item{i}'), i == 3) for i in range(4)]
    outcomes = {o.index: o for o in map_unordered(die_once, items, workers=2)}
    assert [outcomes[i].value for i in range(3)] == ['item0', 'item1', 'item2']
    assert outcomes[3].value is None and 'worker died twice' in outcomes[3].error


def sleep_for(seconds):
    """Sleep `seconds` in a worker; return them."""
    time.sleep(seconds)
    return seconds


def test_a_hung_worker_is_killed_at_the_hard_limit_and_replaced():
    outcomes = {o.index: o for o in map_unordered(sleep_for, [60.0, 0.0], workers=1,
                                                  hard_timeout=1.0)}
    assert outcomes[0].error.startswith('timeout: killed after 1 s')
    assert outcomes[1].value == 0.0  # ran on the replacement worker


WORKER_PARENT = """
import os, sys, time
from rft_sim_ros.study.pool import map_unordered, start_method

def pid(_):
    return os.getpid()

if __name__ == '__main__':
    assert start_method() == 'fork'  # (a single thread: `rft-sim sweep` as users run it)
    outcomes = map_unordered(pid, [0, 1], workers=2)
    print(next(outcomes).value, next(outcomes).value, flush=True)  # the workers, now idle
    time.sleep(60)
"""


def _running(pid):
    """Whether process `pid` runs (neither gone nor a zombie no one reaped)."""
    try:
        with open(f'/proc/{pid}/stat') as stat:
            return stat.read().rsplit(')', 1)[1].split()[0] != 'Z'
    except FileNotFoundError:
        return False


@pytest.mark.skipif(not os.path.isdir('/proc'), reason='reads processes from /proc')
def test_workers_end_when_their_parent_is_killed(tmp_path):
    """A study killed with SIGKILL (no cleanup runs) leaves no worker behind: each forked
    worker holds copies of the pipes' parent ends, so it would wait for its next item
    forever; it looks for its parent while idle instead."""
    (tmp_path / 'parent.py').write_text(WORKER_PARENT)
    parent = subprocess.Popen([sys.executable, str(tmp_path / 'parent.py')],
                              stdout=subprocess.PIPE, text=True,
                              env=dict(os.environ, **ONE_THREAD))
    workers = [int(pid) for pid in parent.stdout.readline().split()]
    assert len(set(workers)) == 2 and all(_running(pid) for pid in workers)
    parent.kill()
    parent.wait()
    deadline = time.monotonic() + 10 * PARENT_CHECK_S
    while any(_running(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(_running(pid) for pid in workers)


def thread_settings(names):
    """The worker's values of the environment variables `names` (None where unset)."""
    return [os.environ.get(name) for name in names]


def test_workers_keep_native_thread_pools_to_one_thread_unless_the_user_says(monkeypatch):
    """N workers each with a BLAS/OpenMP pool as large as the machine oversubscribe it (a
    2-worker study ran no faster than one); a value the user set is passed on as it is."""
    monkeypatch.setenv('MKL_NUM_THREADS', '3')
    monkeypatch.delenv('OMP_NUM_THREADS', raising=False)
    monkeypatch.delenv('OPENBLAS_NUM_THREADS', raising=False)
    names = ['OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS']
    [outcome] = map_unordered(thread_settings, [names], workers=1)
    assert outcome.value == ['1', '1', '3']
    assert 'OMP_NUM_THREADS' not in os.environ  # this process's environment is left alone


_FORK_PROBE = '''
import json, sys, threading, wave   # wave: a module no spawned worker would load
sys.path.insert(0, sys.argv[1])
from probe import loaded
from rft_sim_ros.study.pool import map_unordered, start_method
if sys.argv[2] == 'threaded':  # another thread: forking could deadlock a child
    threading.Thread(target=threading.Event().wait, daemon=True).start()
[outcome] = map_unordered(loaded, ['wave'], workers=1)
print(json.dumps([start_method(), outcome.value]))
'''


@pytest.mark.parametrize('threads, method', [('single', 'fork'), ('threaded', 'spawn')])
def test_a_single_threaded_process_forks_its_workers(threads, method, tmp_path):
    """Forked workers start with what their parent imported (no 0.8 s of imports each);
    a process with other threads spawns fresh interpreters instead."""
    (tmp_path / 'probe.py').write_text('import sys\n\n\ndef loaded(name):\n'
                                       '    return name in sys.modules\n')
    env = dict(os.environ, **ONE_THREAD)
    done = subprocess.run([sys.executable, '-c', _FORK_PROBE, str(tmp_path), threads],
                          env=env, capture_output=True, text=True, check=True, timeout=120)
    assert json.loads(done.stdout.strip().splitlines()[-1]) == [method, method == 'fork']


def test_progress_line_counts_and_estimates():
    progress = StudyProgress(10, stream=io.StringIO())
    assert not progress.enabled  # not a terminal: quiet
    progress.started -= 30.0  # 30 s in
    line = progress.line(3, 1)
    assert '3/10 done, 1 failed, 7 remaining, 1:10 left' in line


def test_cli_sweep(tmp_path, capsys):
    path = tmp_path / 'study.yaml'
    path.write_text(yaml.safe_dump({**DROP, 'duration': 0.2, 'vary': {'zeta': [2.0]}}))
    assert main(['sweep', str(path), '--out', str(tmp_path / 'out'), '--workers', '1',
                 '--quiet']) == 0
    assert read_csv(tmp_path / 'out' / 'results.csv')[0]['stable'] == 'True'
    assert main(['sweep', str(tmp_path / 'missing.yaml')]) == 2
    assert 'rft-sim: error: cannot read study file' in capsys.readouterr().err
    assert main(['sweep', str(path), '--workers', '0']) == 2


@pytest.mark.slow  # (starting a local Ray cluster: about a minute of CPU)
def test_ray_backend_on_a_local_cluster(local_study, tmp_path):
    """A real single-machine Ray cluster on loopback, dashboard off: the study's rows equal
    the local backend's bit for bit, and a task whose worker is killed is retried once."""
    import ray  # the test extra installs Ray: this test runs in CI, never skips
    from rft_sim_ros.study import ray_backend
    study, out, result = local_study
    here = os.path.dirname(os.path.abspath(__file__))  # Ray workers import die_once from here
    ray.init(address='local', include_dashboard=False, num_cpus=2, log_to_driver=False,
             _node_ip_address='127.0.0.1', runtime_env={'env_vars': {'PYTHONPATH': here}})
    try:
        on_ray = run_study(study, tmp_path / 'ray', ray='local', progress=False)
        items = [(str(tmp_path / f'item{i}'), i == 1) for i in range(2)]
        outcomes = {o.index: o for o in ray_backend.map_unordered(die_once, items, 'local')}
    finally:
        ray.shutdown()
    assert on_ray.backend == 'ray (local)'
    assert [{k: v for k, v in r.items() if k != 'wall_time_s'} for r in on_ray.rows] == [
        {k: v for k, v in r.items() if k != 'wall_time_s'} for r in result.rows]
    assert outcomes[0].value == 'item0' and outcomes[0].error is None
    assert outcomes[1].value is None and 'WorkerCrashedError' in outcomes[1].error


def test_study_benchmark_pieces():
    from rft_sim_ros.bench.study_scaling import gaps_between_runs, hexapod_study
    study = hexapod_study(40)
    assert len(study.runs) == 40 and study.keys == ('zeta', 'payload')
    assert study.duration is None and study.fixed == {}  # the scene as bundled
    short = hexapod_study(10, duration=1.0)
    assert short.duration == 1.0 and short.fixed == {'settle_time': 0.3}
    records = {'a': {'worker': 'w1', 'started_at': 10.0, 'finished_at': 11.0},
               'b': {'worker': 'w1', 'started_at': 11.25, 'finished_at': 12.0},
               'c': {'worker': 'w2', 'started_at': 10.5, 'finished_at': 11.5},
               'd': {'worker': 'w2', 'started_at': 11.5, 'finished_at': 13.0},
               'e': {'worker': None, 'started_at': None, 'finished_at': None}}
    assert gaps_between_runs(records) == [0.25, 0.0]


def test_a_worker_warms_each_set_of_kernels_its_runs_meet(monkeypatch):
    """A study varying the surface meets the slope's kernels after the plane's: the worker
    warms them too, outside the run's timing (a run that compiled them could pass
    --run-timeout); the same kernels again cost nothing."""
    from rft_sim_ros.study import execute
    monkeypatch.setattr(execute, '_warmed', set())
    assert execute.warm('plate_drop', {}) > 0.0
    assert execute.warm('plate_drop', {'drop_height': 0.2}) == 0.0
    assert execute.warm('plate_drop', {'sand.surface.type': 'slope'}) > 0.0
    assert execute.warm('plate_drop', {'sand.surface.type': 'slope', 'zeta': 2.0}) == 0.0
    # only what selects kernels counts: deformable sand has one gather whatever its base,
    # and the explicit methods share theirs
    assert execute.warm('plate_drop', {'sand.deformable.enabled': True}) > 0.0
    assert execute.warm('plate_drop', {'sand.deformable.enabled': True,
                                       'sand.surface.type': 'slope'}) == 0.0
    assert execute.warm('plate_drop', {'rft.low_velocity.method': 'ema'}) > 0.0
    assert execute.warm('plate_drop', {'rft.low_velocity.method': 'none'}) == 0.0


HFIELD_ROBOT = """<mujoco><asset><hfield name="bumps" nrow="3" ncol="3" size="1 1 0.05 0.01"/>
  </asset><worldbody><geom name="terrain" type="hfield" hfield="bumps"/>
  <body name="base" pos="0 0 0.2"><freejoint/><geom type="box" size="0.1 0.1 0.03"/></body>
  </worldbody></mujoco>"""


def test_a_study_refuses_an_hfield_geom_its_model_lacks_before_any_run(tmp_path):
    """The model's own hfield is read from its MJCF before the first run: a geom name it
    lacks stops the study with the reason (it used to fail that run alone, later)."""
    (tmp_path / 'robot.xml').write_text(HFIELD_ROBOT)
    study = {'scene': str(tmp_path / 'robot.xml'), 'set': {'sand.surface.type': 'hfield'},
             'vary': {'sand.surface.geom': ['terrain', 'nope']}, 'metrics': ['stable']}
    with pytest.raises(StudyError, match=r"sand.surface.geom: no geom or <hfield> 'nope' in the "
                                         'model; its hfield geoms: terrain'):
        study_from_mapping(study, base=tmp_path)
    assert len(study_from_mapping({**study, 'vary': {'sand.surface.geom': ['terrain']}},
                                  base=tmp_path).runs) == 1


def test_a_study_says_each_distinct_notice_of_its_runs_once(tmp_path):
    """What runs say at start-up (here: cells wider than the plate) is logged once with the
    first run that said it, not once per run and not never."""
    study = _study(set={'sand.deformable.enabled': True, 'sand.deformable.size': [0.5, 0.5],
                        'sand.deformable.cell': 0.12},
                   vary={'zeta': [2.0, 3.0, 4.0]}, duration=0.05)
    lines = []
    run_study(study, tmp_path / 'out', workers=1, progress=False, log=lines.append)
    said = [line for line in lines if 'is wider than sand body plate' in line]
    assert len(said) == 1 and said[0].startswith('run ')
    summaries = [json.loads((tmp_path / 'out' / 'runs' / r.run_id / 'summary.json').read_text())
                 for r in study.runs]
    assert all(said[0].split(': ', 1)[1] in s['summary']['notices'] for s in summaries)


def test_workers_that_would_hold_more_beds_than_memory_allows_are_fewer(monkeypatch):
    """Each bed fits the machine alone; two workers holding the two largest at once would
    pass half its memory, so the study runs on one and says why."""
    from rft_sim_ros.sand.deformable import BED_BYTES_PER_NODE
    from rft_sim_ros.study import sweep
    study = _study(set={'sand.deformable.enabled': True}, vary={'sand.deformable.cell':
                                                                [0.01, 0.02]})
    largest = max(run.bed_bytes for run in study.runs)
    assert largest == pytest.approx(201 * 201 * BED_BYTES_PER_NODE)  # (2 m x 2 m at 1 cm)
    lines = []
    monkeypatch.setattr(sweep, 'machine_memory', lambda: 3.0 * largest)
    assert sweep.workers_within_memory(study.runs, 2, lines.append) == 2  # 1.25 beds <= 1.5
    monkeypatch.setattr(sweep, 'machine_memory', lambda: 2.2 * largest)
    assert sweep.workers_within_memory(study.runs, 2, lines.append) == 1
    assert lines == [f'deformable beds of up to {largest / 2**30:.3g} GiB: 1 of 2 workers at '
                     f"once keep them within half of this machine's {2.2 * largest / 2**30:.3g} "
                     'GiB']
    monkeypatch.setattr(sweep, 'machine_memory', lambda: None)  # (not told: as asked)
    assert sweep.workers_within_memory(study.runs, 2, lines.append) == 2


def test_a_studys_runs_read_an_mjcf_models_includes_and_assets(tmp_path):
    """files_read lists what MuJoCo reads for an MJCF model: its includes (relative to the
    main model), and the mesh, hfield and texture files resolved against the compiler's
    meshdir / texturedir, as MuJoCo resolves them (the model compiles from them); so a
    resumed study sees an hfield image rewritten since."""
    import mujoco
    import trimesh
    from PIL import Image
    from rft_sim_ros.study.spec import files_read
    (tmp_path / 'assets').mkdir()
    (tmp_path / 'pics').mkdir()
    trimesh.creation.box((0.1, 0.1, 0.1)).export(tmp_path / 'assets' / 'box.obj')
    Image.fromarray(np.arange(16, dtype=np.uint8).reshape(4, 4) * 16).save(
        tmp_path / 'assets' / 'bumps.png')
    Image.fromarray(np.zeros((8, 8, 3), dtype=np.uint8)).save(tmp_path / 'pics' / 'grey.png')
    (tmp_path / 'part.xml').write_text(
        '<mujoco><asset><mesh name="box" file="box.obj"/></asset></mujoco>')
    (tmp_path / 'robot.xml').write_text("""<mujoco>
      <compiler meshdir="assets" texturedir="pics"/>
      <include file="part.xml"/>
      <asset><hfield name="bumps" file="bumps.png" size="1 1 0.05 0.01"/>
        <texture name="t" type="2d" file="grey.png"/></asset>
      <worldbody><geom name="terrain" type="hfield" hfield="bumps"/>
        <body name="base" pos="0 0 0.2"><freejoint/><geom type="mesh" mesh="box"/></body>
      </worldbody></mujoco>""")
    mujoco.MjModel.from_xml_path(str(tmp_path / 'robot.xml'))   # MuJoCo reads these files
    loaded = load_scene(str(tmp_path / 'robot.xml'), {'sand.surface.type': 'hfield'})
    assert set(files_read(str(tmp_path / 'robot.xml'), loaded)) == {
        str(tmp_path / name) for name in ('robot.xml', 'part.xml', 'assets/box.obj',
                                          'assets/bumps.png', 'pics/grey.png')}


def test_a_list_metric_is_said_by_its_components(tmp_path):
    """Naming a vector metric whole tabulates nothing; the closing line says which names
    do (name[0] ..), and a component is tabulated."""
    said = []
    study = _study(vary={'zeta': [2.0]}, duration=0.05,
                   metrics=['base_displacement_xyz_m', 'base_displacement_xyz_m[2]'])
    result = run_study(study, tmp_path / 'out', workers=1, progress=False, log=said.append)
    assert result.rows[0]['base_displacement_xyz_m'] is None
    assert result.rows[0]['base_displacement_xyz_m[2]'] < 0.0          # the plate fell
    assert any("no stable run reported ['base_displacement_xyz_m']" in line
               and 'base_displacement_xyz_m is a list: name one of its numbers, '
                   'base_displacement_xyz_m[0] .. base_displacement_xyz_m[2]' in line
               for line in said)
