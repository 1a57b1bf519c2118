"""Benchmark of the study machinery (`rft-sim sweep`): a 40-run hexapod study on one local
worker, on all local cores, and on a single-machine Ray cluster; speed-up over one worker
and the overhead per run; optionally (--reuse) `rft-sim validate --quick` and the quick
speed-against-error sweep of `rft-sim bench` on one worker and on all cores.

    python -m rft_sim_ros.bench.study_scaling [--out DIR] [--runs 40] [--duration S] [--reuse]

Overhead per run, on one worker: the time the worker waits between the end of one run and
the start of the next (the median over the study, from the worker's own clock): result
transfer, the parent's recording (the run's summary file, the table rewrites) and handing
out the next run. The once-per-study costs are reported beside it: the worker's start (a
fresh interpreter importing the package), its warm-up and the final table and plots.
Ratios come from runs measured back to back in one invocation; on a shared machine the load
during each phase is reported (1-minute load average before and after). It runs as `rft-sim`
does, with one-thread BLAS and OpenMP pools (`native_threads`: it restarts itself with them
set), so the local workers are forked.
"""
import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

from ..native_threads import unset
from ..scenes.config import load_scene
from ..sim.runner import machine_info, run_duration
from ..study import run_study, study_from_mapping
from ..study.pool import default_workers, map_unordered


def hexapod_study(runs, duration=None):
    """`runs` hexapod runs over zeta x payload: the bundled scene as it is (drop, settle, five
    gait cycles: 6 s of sim time), or `duration` s of sim time each (0.3 s settle, then
    walking)."""
    payloads = (0.0, 0.5, 1.0, 1.5, 2.0)
    zetas = [round(1.0 + 0.5 * i, 2) for i in range(max(1, runs // len(payloads)))]
    short = {} if duration is None else {'duration': duration, 'set': {'settle_time': 0.3}}
    return study_from_mapping({
        'scene': 'hexapod', **short,
        'vary': {'zeta': zetas, 'payload': list(payloads)},
        'metrics': ['forward_distance_m', 'mean_sinkage_m']})


def _noop(item):
    return item


def worker_start_s():
    """Wall time (s) to start one pool worker (forked, or spawned and importing the package:
    `pool.start_method`) and get an answer."""
    started = time.perf_counter()
    list(map_unordered(_noop, [0], workers=1))
    return time.perf_counter() - started


def gaps_between_runs(records):
    """Per worker, the times (s) between one run's end and the next run's start."""
    by_worker = {}
    for record in records.values():
        if record['started_at'] is not None:
            by_worker.setdefault(record['worker'], []).append(
                (record['started_at'], record['finished_at']))
    gaps = []
    for spans in by_worker.values():
        spans.sort()
        gaps += [start - end for (_, end), (start, _) in zip(spans, spans[1:])]
    return gaps


def _load():
    return os.getloadavg()[0]


def _timed_study(study, out, start_s=0.0, **backend):
    """Run `study` on `backend` into `out`: wall time, the runs' own times, warm-up, final
    outputs, overhead per run (median gap between runs on a worker), load before/after."""
    load = _load()
    result = run_study(study, out, progress=False, **backend)
    walls = [r['wall_time_s'] for r in result.rows]
    return {'backend': result.backend, 'wall_s': result.wall_s, 'runs': len(result.rows),
            'failed': result.failed, 'run_wall_sum_s': sum(walls),
            'run_wall_median_s': statistics.median(walls), 'worker_start_s': start_s,
            'warm_s': result.warm_s, 'outputs_s': result.outputs_s,
            'overhead_per_run_s': statistics.median(gaps_between_runs(result.records)),
            'load_before': load, 'load_after': _load(), 'rows': result.rows}


def measure_study(runs=40, workers=None, duration=None):
    """One worker, `workers` local workers and a local Ray cluster of `workers` CPUs, back to
    back on the same study (`hexapod_study`); speed-ups over one worker and bit-for-bit
    agreement."""
    workers = workers or default_workers()
    study = hexapod_study(runs, duration)
    with tempfile.TemporaryDirectory() as scratch:
        one = _timed_study(study, Path(scratch) / 'one', start_s=worker_start_s(), workers=1)
        many = _timed_study(study, Path(scratch) / 'many', workers=workers)
        import ray
        started = time.perf_counter()
        ray.init(address='local', include_dashboard=False, num_cpus=workers,
                 log_to_driver=False, _node_ip_address='127.0.0.1')
        cluster_start_s = time.perf_counter() - started
        try:  # the study's wall time excludes the cluster start (a cluster outlives studies)
            on_ray = _timed_study(study, Path(scratch) / 'ray', ray='local')
            on_ray['cluster_start_s'] = cluster_start_s
        finally:
            ray.shutdown()

    def same(a, b):
        return [{k: v for k, v in r.items() if k != 'wall_time_s'} for r in a['rows']] == [
            {k: v for k, v in r.items() if k != 'wall_time_s'} for r in b['rows']]

    result = {'runs': len(study.runs), 'run_sim_time_s': duration or run_duration(
                  load_scene('hexapod')), 'workers': workers, 'one_worker': one,
              'local': many, 'ray': on_ray,
              'speedup_local': one['wall_s'] / many['wall_s'],
              'speedup_ray': one['wall_s'] / on_ray['wall_s'],
              'overhead_fraction_of_run': one['overhead_per_run_s'] / one['run_wall_median_s'],
              'identical_local': same(one, many), 'identical_ray': same(one, on_ray)}
    for phase in (one, many, on_ray):
        del phase['rows']
    return result


def measure_reuse(workers=None):
    """Wall time of `rft-sim validate --quick` and of the quick speed-against-error sweep on
    one worker and on `workers` (default: all cores)."""
    from ..bench import pareto
    from ..validation import run_validation
    workers = workers or default_workers()
    out = {}
    with tempfile.TemporaryDirectory() as scratch:
        for label, count in (('one_worker', 1), ('all_cores', workers)):
            load = _load()
            started = time.perf_counter()
            run_validation(Path(scratch) / label, quick=True, log=lambda line: None,
                           workers=count)
            out[f'validate_quick_{label}'] = {'wall_s': time.perf_counter() - started,
                                              'workers': count, 'load_before': load}
            load = _load()
            started = time.perf_counter()
            pareto.speed_against_error(pareto.QUICK_SWEEPS, workers=count)
            out[f'pareto_quick_{label}'] = {'wall_s': time.perf_counter() - started,
                                            'workers': count, 'load_before': load}
    out['validate_speedup'] = (out['validate_quick_one_worker']['wall_s']
                               / out['validate_quick_all_cores']['wall_s'])
    out['pareto_speedup'] = (out['pareto_quick_one_worker']['wall_s']
                             / out['pareto_quick_all_cores']['wall_s'])
    return out


def main(argv=None):
    if unset():  # measured as `rft-sim sweep` runs: one-thread native pools, forked workers
        os.execve(sys.executable, [sys.executable, '-m', __spec__.name,
                                   *(sys.argv[1:] if argv is None else argv)],
                  {**os.environ, **unset()})
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--out', default='bench/results', help='folder for study_scaling.json')
    parser.add_argument('--runs', type=int, default=40, help='runs in the hexapod study')
    parser.add_argument('--duration', type=float,
                        help='sim time of each run, s (default: the scene as bundled, 6 s)')
    parser.add_argument('--reuse', action='store_true',
                        help='also time validate --quick and the quick speed-against-error '
                             'sweep on one worker and on all cores')
    args = parser.parse_args(argv)
    results = {'machine': machine_info()}
    if args.reuse:  # first: once Ray has run in this process, its threads remain, and a
        results['reuse'] = measure_reuse()  # multi-threaded process spawns its workers
    results['study'] = measure_study(args.runs, duration=args.duration)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / 'study_scaling.json').write_text(json.dumps(results, indent=2))
    s = results['study']
    print(f'{s["runs"]}-run hexapod study ({s["run_sim_time_s"]:g} s runs): one worker {s["one_worker"]["wall_s"]:.1f} s, '
          f'{s["workers"]} workers {s["local"]["wall_s"]:.1f} s (x{s["speedup_local"]:.2f}), '
          f'Ray {s["ray"]["wall_s"]:.1f} s (x{s["speedup_ray"]:.2f}); overhead per run '
          f'{1e3 * s["one_worker"]["overhead_per_run_s"]:.0f} ms = '
          f'{100 * s["overhead_fraction_of_run"]:.1f} % of a run (worker start '
          f'{s["one_worker"]["worker_start_s"]:.1f} s once); identical results: '
          f'local {s["identical_local"]}, Ray {s["identical_ray"]}')
    if args.reuse:
        r = results['reuse']
        print(f'validate --quick x{r["validate_speedup"]:.2f}, quick speed-against-error '
              f'x{r["pareto_speedup"]:.2f} on all cores')
    print(f'wrote {out / "study_scaling.json"}', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
