"""Speed against error for every scene: sweep plates per sand body and timestep, compare each
scene's main metric with a converged reference (finest plates, smallest timestep), and find
the runs no other run beats on both wall time and error (the Pareto front). The runs go
out to all cores on the study machinery's process pool (rft_sim_ros/study/pool.py), the
dearest first (study/cost.py)."""
from dataclasses import dataclass

from ..sim.runner import run_scene
from ..scenes.config import load_scene
from ..study.cost import dearest_first, run_cost
from ..study.pool import map_unordered


@dataclass(frozen=True)
class Sweep:
    """metric: the scene's main output; plates: plates per sand body; timesteps: s;
    reference: (plates, timestep) of the converged run."""
    metric: str
    plates: tuple
    timesteps: tuple
    reference: tuple


SWEEPS = {
    'plate_press': Sweep('force_per_sinkage_N_per_m', (50, 100, 400, 1600),
                         (0.002, 0.001, 0.0005), (3200, 0.00025)),
    'plate_drop': Sweep('max_sinkage_m', (50, 100, 400, 1600), (0.002, 0.001, 0.0005),
                        (3200, 0.00025)),
    'rotating_intruder': Sweep('peak_torque_increase_Nm', (250, 500, 1000, 2000),
                               (0.002, 0.001, 0.0005), (8000, 0.00025)),
    'rail_flat': Sweep('carriage_displacement_m', (250, 500, 1000, 2000),
                       (0.001, 0.0005, 0.00025), (8000, 0.000125)),
    'rail_open_c': Sweep('carriage_displacement_m', (250, 500, 1000, 2000),
                         (0.001, 0.0005, 0.00025), (8000, 0.000125)),
    'rail_closed_c': Sweep('carriage_displacement_m', (250, 500, 1000, 2000),
                           (0.001, 0.0005, 0.00025), (8000, 0.000125)),
    'articulated_leg': Sweep('carriage_displacement_per_step_m', (250, 500, 1000, 2000),
                             (0.001, 0.0005, 0.00025), (8000, 0.000125)),
    'hexapod': Sweep('forward_distance_m', (125, 250, 500, 1000), (0.0016, 0.0008, 0.0004),
                     (2000, 0.0002)),
}

QUICK_SWEEPS = {
    'plate_drop': Sweep('max_sinkage_m', (50, 400), (0.002, 0.001), (1600, 0.0005)),
    'rail_flat': Sweep('carriage_displacement_m', (250, 1000), (0.001, 0.0005),
                       (2000, 0.00025)),
}


def pareto_front(points, tolerance=1e-6):
    """Indices of the points (wall, error) that no other point beats: as fast or faster and
    as accurate or more (errors within `tolerance` relative count as equal), better in one."""
    def not_worse(a, b):  # error a no worse than error b
        return a <= b * (1 + tolerance) + 1e-15

    front = []
    for i, (wall, error) in enumerate(points):
        beaten = any(w <= wall and not_worse(e, error) and (w < wall or not not_worse(error, e))
                     for j, (w, e) in enumerate(points) if j != i)
        if not beaten:
            front.append(i)
    return front


def _points(name, sweep):
    """(plates, timestep) pairs to run for scene `name`: the reference first, then the grid
    (with the scene's default) by timestep and plates."""
    default = load_scene(name)
    grid = {(p, t) for p in sweep.plates for t in sweep.timesteps}
    if default.plates_per_body is not None:
        grid.add((default.plates_per_body, default.timestep))
    return [sweep.reference] + sorted(grid, key=lambda g: (g[1], g[0]))


def _scene(job):
    """The SceneConfig of (scene, plates per body, timestep s)."""
    name, plates, timestep = job
    return load_scene(name, {'rft.plates_per_body': plates, 'timestep': timestep})


def _run(job):
    """Run (scene, plates per body, timestep s) headless: its summary."""
    return run_scene(_scene(job), progress=False, plots=False)


def speed_against_error(sweeps, log=lambda line: None, workers=None):
    """Runs of each scene over its Sweep ({name: Sweep}), on `workers` processes (default:
    all cores; each run's wall time is its own, measured in its worker). Returns, per scene,
    the rows (plates, timestep, wall s per sim s, metric, relative error vs the reference,
    default, on_front, stable) and the reference."""
    jobs = [(name, *point) for name, sweep in sweeps.items() for point in _points(name, sweep)]
    jobs = [jobs[i] for i in dearest_first([run_cost(_scene(job)) for job in jobs])]
    summaries = {}
    for outcome in map_unordered(_run, jobs, workers):
        name, plates, timestep = job = jobs[outcome.index]
        if outcome.error is not None:
            raise RuntimeError(f'{name} {plates} plates/body, dt {timestep:g} s: {outcome.error}')
        summary = summaries[job] = outcome.value
        log(f'{name}: {plates} plates/body, dt {timestep * 1e3:g} ms -> '
            f'{summary["wall_time_s"] / summary["sim_time_s"]:.3f} s wall per sim s')
    return [_rows(name, sweep, [summaries[(name, *point)] for point in _points(name, sweep)])
            for name, sweep in sweeps.items()]


def _rows(name, sweep, summaries):
    """The speed-against-error table of scene `name` from its runs' summaries (in _points
    order: the reference first)."""
    default = load_scene(name)
    reference, runs = summaries[0], summaries[1:]
    ref_value = reference['metrics'][sweep.metric]
    rows = []
    for (plates, timestep), summary in zip(_points(name, sweep)[1:], runs):
        value = summary['metrics'].get(sweep.metric)
        error = (abs(value - ref_value) / abs(ref_value)
                 if summary['stable'] and value is not None and ref_value else float('inf'))
        rows.append({'plates_per_body': plates, 'timestep_s': timestep,
                     'plates_total': summary['plates_total'],
                     'wall_s_per_sim_s': summary['wall_time_s'] / summary['sim_time_s'],
                     'metric': value, 'relative_error': error, 'stable': summary['stable'],
                     'default': (plates, timestep) == (default.plates_per_body, default.timestep)})
    front = pareto_front([(r['wall_s_per_sim_s'], r['relative_error']) for r in rows])
    for i, row in enumerate(rows):
        row['on_front'] = i in front
    return {'scene': name, 'metric': sweep.metric, 'reference': {
        'plates_per_body': sweep.reference[0], 'timestep_s': sweep.reference[1],
        'metric': ref_value,
        'wall_s_per_sim_s': reference['wall_time_s'] / reference['sim_time_s']}, 'rows': rows}
