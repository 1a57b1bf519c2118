"""`rft-sim bench`: speed of the sand simulation, against plain MuJoCo and against error.

run_bench(out, quick) measures, in one process: the hexapod step against a rigid-floor
MuJoCo step of the same robot and full hexapod trials' real-time factor (`step_cost`),
start-up cold and warm (`startup`), cost against plates in and above the sand (`scaling`);
then speed against error for every scene (`pareto`), its runs spread over all cores; it
writes JSON, markdown and PNG. `study_scaling` (a command of its own) measures the study
machinery: speed-up over one worker, locally and on Ray, and the overhead per run.
"""
import tempfile
from pathlib import Path

from .. import prebuilt
from ..sim.runner import load_average, machine_info
from . import pareto, report, scaling, startup, step_cost


def _median(values):
    return sorted(values)[len(values) // 2]


def run_bench(out, quick=False, log=print, workers=None):
    """Run the benchmark (`quick`: fewer, shorter measurements) and write it under `out`;
    the speed-against-error sweep runs on `workers` processes (default: all cores)."""
    results = {'machine': machine_info(), 'quick': quick}
    log('step cost: hexapod on sand vs rigid floor')
    results['step_cost'] = step_cost.hexapod_step_cost(
        chunks=3 if quick else 9, chunk_steps=300 if quick else 1000,
        settle_steps=500 if quick else 2500)
    log('full hexapod trials, without and with the bag (alternating)')
    overrides = {'cycles': 1} if quick else None
    plain, bagged = [], []
    with tempfile.TemporaryDirectory() as bags:
        for i in range(1 if quick else 3):
            plain.append(step_cost.hexapod_trial(overrides))
            bagged.append(step_cost.hexapod_trial(overrides, bag=Path(bags) / str(i)))
    trials = sorted(plain, key=lambda run: run[1]['real_time_factor'])
    trial, walk = trials[len(trials) // 2]  # the run with the median walk
    results['trial'] = {k: trial[k] for k in ('sim_time_s', 'wall_time_s', 'real_time_factor',
                                              'startup_time_s', 'plates_total',
                                              'plates_active_mean')}
    results['trial']['walk'] = walk
    results['trial']['walk_real_time_factors'] = [run[1]['real_time_factor'] for run in trials]
    results['trial_with_bag'] = {
        'real_time_factor': _median([run[0]['real_time_factor'] for run in bagged]),
        'real_time_factors': [run[0]['real_time_factor'] for run in bagged],
        'recording_fraction': _median([run[0]['recording_time_s'] / run[0]['wall_time_s']
                                       for run in bagged]),
        'real_time_factor_without': _median([run[0]['real_time_factor'] for run in plain])}
    log('start-up, cold and warm')
    results['startup'] = startup.startup_times(warm_runs=1 if quick else 3)
    log('cost against plates')
    results['scaling'] = scaling.slab_scaling(
        (1000, 4000) if quick else (1000, 2000, 5000, 10000, 20000, 50000),
        steps=50 if quick else 200)
    results['idle_plates'] = scaling.idle_plates_cost(
        chunks=2 if quick else 7, chunk_steps=200 if quick else 500,
        settle_steps=300 if quick else 2500)
    sweeps = pareto.QUICK_SWEEPS if quick else pareto.SWEEPS
    results['speed_against_error'] = pareto.speed_against_error(sweeps, log, workers)
    results['load_average_at_end'] = load_average()
    # (and the kernels this process gave other types; its workers' are their runs')
    results['machine']['kernels'] = prebuilt.state() + prebuilt.fallback_line()
    report.write(Path(out), results)
    return results
