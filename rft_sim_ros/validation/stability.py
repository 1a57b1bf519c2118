"""The stability suite: hard cases for the sand simulation, each with a measured value and a bound.

Cases (design section 3, "Stability"): drops of the plate and the hexapod from 10 cm, 50 cm
and 1 m; standing still (hexapod in its neutral pose, a loaded plate); a blade stopped
mid-stroke, held and restarted; extreme sand (zeta 0.1 ... 50); timesteps 0.25 ... 2 ms;
fast intrusion with and without the dynamic RFT term; a deliberately diverging run. The
low-velocity treatments are compared on the cases they decide: our implicit default, the
paper's exponential moving average (alpha_F 0.1 and 0.5) and raw explicit RFT.
`run_stability` writes stability.md (case, metric, bound, value, held) and PNG plots.
"""
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..scenes.config import load_scene
from ..sim.simulation import Simulation, SimulationDiverged
from ..units import zeta_to_si

#: Nothing may rise more than this above its lowest point after first touching the sand, m.
REBOUND_BOUND_M = 0.005
#: At rest: speed below this, m/s ...
REST_SPEED_BOUND_MPS = 1e-3
#: ... and drift below this over the last 5 s, m.
DRIFT_BOUND_M = 1e-3
#: Key outputs within this of the smallest-timestep run.
TIMESTEP_TOLERANCE = 0.05
#: Treatments compared: (label, scene overrides).
TREATMENTS = (('implicit (default)', {}),
              ('EMA alpha_F 0.1 (paper text)', {'rft.low_velocity.method': 'ema',
                                                'rft.low_velocity.ema_alpha': 0.1}),
              ('EMA alpha_F 0.5 (paper code)', {'rft.low_velocity.method': 'ema',
                                                'rft.low_velocity.ema_alpha': 0.5}),
              ('raw explicit RFT', {'rft.low_velocity.method': 'none'}))


@dataclass
class Trace:
    """Samples of a run: time (s), base position (m), base speed (m/s), lowest point z of
    each foot (m), and the divergence reason if the run blew up."""
    scene: str
    overrides: dict
    time: np.ndarray
    base: np.ndarray
    speed: np.ndarray
    low_point: np.ndarray
    diverged: str = None
    sim: object = field(default=None, repr=False)

    @property
    def stable(self):
        return self.diverged is None and bool(np.all(np.isfinite(self.base)))


def _feet(sim):
    """Indices (into the engine's sand bodies) of the bodies that stand in the sand: each
    leg's last body (its foot), or every sand body of a scene without legs."""
    names = list(sim.engine.body_names)
    feet = {bodies[-1] for bodies in sim.legs.values()} or set(sim.sand_bodies)
    return [names.index(body) for body in names if body in feet]


def _low_points(sim):
    """World z (m) of the lowest plate of each foot (see `_feet`): the points that stand in
    the sand. A robot's body may rise as its servos straighten its legs; its feet may not."""
    engine = sim.engine
    data = sim.data
    lows = []
    for i in _feet(sim):
        body = engine.body_ids[i]
        local = engine.local_pos[engine.plate_start[i]:engine.plate_start[i + 1]]
        lows.append((data.xpos[body][2] + local @ data.xmat[body].reshape(3, 3)[2]).min())
    return np.array(lows)


def trace(scene, overrides, duration, every=10):
    """Run scene `scene` with `overrides` for `duration` s, sampling every `every` steps."""
    sim = Simulation(load_scene(scene, overrides))
    body = sim.model.body(sim.base_body).id
    steps = int(round(duration / sim.timestep))
    times, bases, speeds, lows = [], [], [], []
    diverged = None
    try:
        for _ in range(steps // every):
            sim.step(every)
            times.append(sim.time)
            bases.append(sim.data.xpos[body].copy())
            speeds.append(np.linalg.norm(sim.data.cvel[body][3:]))
            lows.append(_low_points(sim))
    except SimulationDiverged as error:
        diverged = str(error)
    return Trace(scene, overrides, np.array(times), np.array(bases).reshape(-1, 3),
                 np.array(speeds), np.array(lows).reshape(len(times), -1), diverged, sim)


def rebound(trace, surface=0.0):
    """Largest rise (m) of any foot above its lowest point so far, after it first reached
    the sand (a bounce out of the sand)."""
    worst = 0.0
    for column in trace.low_point.T:
        touched = np.flatnonzero(column <= surface)
        if touched.size:
            after = column[touched[0]:]
            worst = max(worst, float(np.max(after - np.minimum.accumulate(after))))
    return worst


def last_seconds(trace, seconds):
    return trace.time >= trace.time[-1] - seconds


def drift(trace, seconds=5.0):
    """Base displacement (m) over the last `seconds` of the trace."""
    window = trace.base[last_seconds(trace, seconds)]
    return float(np.linalg.norm(window[-1] - window[0]))


@dataclass
class Row:
    """One line of the report: case, metric, bound (text), value, held."""
    case: str
    metric: str
    bound: str
    value: float
    held: bool


def _row(case, metric, value, bound_text, test):
    held = bool(value is not None and np.isfinite(value) and test(value))
    return Row(case, metric, bound_text, value, held)


class Suite:
    """Collects rows, traces for plots and timing while the cases run."""

    def __init__(self, quick, log):
        self.quick, self.log = quick, log
        self.rows, self.drops, self.standing = [], {}, {}

    def add(self, *args):
        row = _row(*args)
        self.rows.append(row)
        self.log(f'{"held" if row.held else "NOT HELD"}: {row.case}: {row.metric} = '
                 f'{_fmt(row.value)} ({row.bound})')

    # --- the cases ---------------------------------------------------------------------
    def drops_case(self):
        heights = (0.1, 1.0) if self.quick else (0.1, 0.5, 1.0)
        for body, scene, duration in (('plate', 'plate_drop', 2.0), ('hexapod', 'hexapod', 3.0)):
            for height in heights:
                overrides = {'drop_height': height}
                if scene == 'hexapod':
                    overrides['gait'] = 'none'
                run = trace(scene, overrides, 1.5 if self.quick else duration)
                self.drops[(body, height)] = run
                case = f'drop {body} from {height:g} m'
                self.add(case, 'stable (no NaN, no divergence)', float(run.stable), 'true',
                         lambda v: v == 1.0)
                self.add(case, 'rebound of a foot after touching sand (m)', rebound(run),
                         f'< {REBOUND_BOUND_M:g}', lambda v: v < REBOUND_BOUND_M)
                self.add(case, 'final speed (m/s)', float(run.speed[-1]),
                         f'< {REST_SPEED_BOUND_MPS:g}', lambda v: v < REST_SPEED_BOUND_MPS)

    def standing_case(self):
        settle, hold = (1.5, 2.0) if self.quick else (3.0, 10.0)
        for label, scene, overrides in (
                ('hexapod standing (gait none)', 'hexapod', {'gait': 'none'}),
                ('loaded plate (2 kg) resting', 'plate_drop', {'mass': 2.0, 'drop_height': 0.0})):
            run = trace(scene, overrides, settle + hold)
            self.standing[label] = run
            window = min(5.0, hold)
            last = last_seconds(run, window)
            self.add(label, f'max speed over the last {window:g} s (m/s)',
                     float(run.speed[last].max()), f'< {REST_SPEED_BOUND_MPS:g}',
                     lambda v: v < REST_SPEED_BOUND_MPS)
            self.add(label, f'drift over the last {window:g} s (m)', drift(run, window),
                     f'< {DRIFT_BOUND_M:g}', lambda v: v < DRIFT_BOUND_M)

    def start_stop_case(self):
        metrics = _scene_metrics('blade_drag', {})
        case = 'blade stopped mid-stroke, held 2 s, restarted'
        self.add(case, 'creep while held (m)', metrics['hold_creep_m'], '< 1e-4',
                 lambda v: v < 1e-4)
        self.add(case, 'rms speed while held (m/s)', metrics['hold_rms_speed_mps'], '< 1e-3',
                 lambda v: v < 1e-3)
        self.add(case, 'restart force peak / steady force', metrics['restart_peak_over_steady'],
                 '<= 1.05', lambda v: v <= 1.05)

    def extreme_sand_case(self):
        for zeta in ((0.1, 50.0) if self.quick else (0.1, 0.5, 20.0, 50.0)):
            run = trace('hexapod', {'zeta': zeta}, 2.5 if self.quick else 6.0)
            case = f'hexapod walking, zeta {zeta:g} N/cm^3'
            self.add(case, 'stable and finite', float(run.stable), 'true', lambda v: v == 1.0)
            landed = run.time >= 1.0  # s: the drop is over
            self.add(case, 'max base speed after landing (m/s)',
                     float(np.nanmax(run.speed[landed])), '< 0.5', lambda v: v < 0.5)
            self.add(case, 'final base height (m)', float(run.base[-1, 2]),
                     'finite (sinks in loose sand)', np.isfinite)

    def timestep_case(self):
        timesteps = (0.00025, 0.001, 0.002) if self.quick else (0.00025, 0.0005, 0.001, 0.002)
        for scene, overrides, keys in (
                ('plate_drop', {}, ('max_sinkage_m',)),
                ('hexapod', {}, ('forward_distance_m', 'mean_sinkage_m'))):
            results = {dt: _scene_metrics(scene, {**overrides, 'timestep': dt},
                                          duration=3.0 if (self.quick and scene == 'hexapod')
                                          else None)
                       for dt in timesteps}
            reference = results[timesteps[0]]
            for dt in timesteps[1:]:
                for key in keys:
                    value = results[dt][key]
                    error = (abs(value - reference[key]) / abs(reference[key])
                             if value is not None and reference[key] else math.inf)
                    self.add(f'{scene}, dt {dt * 1e3:g} ms vs 0.25 ms', f'{key} relative change',
                             error, f'<= {TIMESTEP_TOLERANCE:.0%}',
                             lambda v: v <= TIMESTEP_TOLERANCE)

    def fast_intrusion_case(self):
        speed, lam, density = 1.0, 1.0, 1600.0
        plain = _scene_metrics('plate_press', {'speed': speed}, duration=0.04)
        dynamic = _scene_metrics('plate_press', {'speed': speed,
                                                 'rft.dynamic': {'lambda': lam,
                                                                 'density': density}},
                                 duration=0.04)
        case = 'plate driven in at 1 m/s'
        self.add(case, 'force per depth / (zeta A)', plain['force_per_sinkage_error'] + 1,
                 '1 +- 0.01 (finite, linear in depth)', lambda v: abs(v - 1) <= 0.01)
        area = plain['expected_force_per_sinkage_N_per_m'] / zeta_to_si(3.75)
        added = (dynamic['max_force_N'] - plain['max_force_N']) / area
        expected = lam * density * speed ** 2
        self.add(case + ', dynamic term on', 'added stress / (lambda rho v^2)',
                 added / expected, '1 +- 0.02', lambda v: abs(v - 1) <= 0.02)

    def divergence_case(self):
        summary = _scene_summary('blade_drag', {'servo_kp': 1e10}, duration=1.0)
        self.add('blade servo with absurd gain (kp = 1e10 N/m)',
                 'reported as diverged (stable false with a reason)',
                 float(summary['stable'] is False and bool(summary['reason'])), 'true',
                 lambda v: v == 1.0)

    def treatments_case(self):
        """The treatments side by side on the cases that tell them apart."""
        self.comparison = []
        for label, overrides in TREATMENTS:
            drop = _scene_summary('plate_drop', {**overrides, 'drop_height': 1.0}, duration=1.5)
            blade = _scene_summary('blade_drag', overrides)
            walk = _scene_summary('hexapod', overrides, duration=2.5 if self.quick else None)
            self.comparison.append({
                'treatment': label,
                'drop_1m_sinkage_error': _metric(drop, 'max_sinkage_error'),
                'drop_1m_rebound_m': _metric(drop, 'rebound_m'),
                'drop_1m_settled_speed_mps': _metric(drop, 'settled_speed_mps'),
                'blade_hold_rms_speed_mps': _metric(blade, 'hold_rms_speed_mps'),
                'blade_hold_force_std_N': _metric(blade, 'hold_force_std_N'),
                'hexapod_forward_distance_m': _metric(walk, 'forward_distance_m'),
                'hexapod_stable': walk['stable']})
            self.log(f'treatment {label}: {self.comparison[-1]}')


def _scene_summary(scene, overrides, duration=None):
    from ..sim.runner import run_scene
    return run_scene(load_scene(scene, overrides), duration=duration, progress=False,
                     plots=False)


def _scene_metrics(scene, overrides, duration=None):
    summary = _scene_summary(scene, overrides, duration)
    return summary['metrics'] if summary['stable'] else {k: None for k in summary['metrics']}


def _metric(summary, key):
    return summary['metrics'].get(key) if summary['stable'] else None


def _fmt(value):
    if value is None:
        return 'n/a'
    if isinstance(value, float) and (value == 0 or 1e-3 <= abs(value) < 1e4):
        return f'{value:.4g}'
    return f'{value:.3e}'


def _markdown(suite, wall):
    held = sum(r.held for r in suite.rows)
    lines = ['# Stability suite', '',
             f'{held} of {len(suite.rows)} checks held ({"quick" if suite.quick else "full"} run, '
             f'{wall:.0f} s). Default settings: implicit low-velocity treatment, each scene\'s '
             'default timestep and plates.', '',
             '| case | metric | bound | value | held |', '|---|---|---|---|---|']
    lines += [f'| {r.case} | {r.metric} | {r.bound} | {_fmt(r.value)} | '
              f'{"yes" if r.held else "**NO**"} |' for r in suite.rows]
    if getattr(suite, 'comparison', None):
        lines += ['', '## Low-velocity treatments compared', '',
                  'Plate dropped from 1 m (max depth against the energy balance, rebound, settled '
                  'speed: its mean over the last 0.5 s); blade held mid-stroke (rms speed, force '
                  'fluctuation); hexapod walking (distance).', '',
                  '| treatment | drop: depth error | drop: rebound (m) '
                  '| drop: settled speed (m/s) | blade hold: rms speed (m/s) '
                  '| blade hold: force std (N) | hexapod distance (m) | hexapod stable |',
                  '|---|---|---|---|---|---|---|---|']
        for c in suite.comparison:
            lines.append('| ' + ' | '.join([c['treatment']] + [_fmt(c[k]) for k in (
                'drop_1m_sinkage_error', 'drop_1m_rebound_m', 'drop_1m_settled_speed_mps',
                'blade_hold_rms_speed_mps', 'blade_hold_force_std_N',
                'hexapod_forward_distance_m')] + [str(c['hexapod_stable'])]) + ' |')
    return '\n'.join(lines) + '\n'


def _plots(out, suite):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for (body, height), run in suite.drops.items():
        ax = axes[0] if body == 'plate' else axes[1]
        ax.plot(run.time, run.low_point.min(axis=1) * 100, label=f'{height:g} m')
    for ax, body in zip(axes, ('plate', 'hexapod (lowest foot point)')):
        ax.axhline(0, color='0.6', linestyle=':')
        ax.set_title(f'drop: {body}')
        ax.set_xlabel('sim time (s)')
        ax.set_ylabel('lowest point (cm, 0 = sand surface)')
        ax.legend(title='drop height')
    fig.tight_layout()
    fig.savefig(out / 'stability_drops.png', dpi=100)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(6, 4))
    for label, run in suite.standing.items():
        displacement = np.linalg.norm(run.base - run.base[0], axis=1)
        ax.plot(run.time, (displacement - displacement[-1]) * 1e3, label=label)
    ax.set_xlabel('sim time (s)')
    ax.set_ylabel('base position relative to the end (mm)')
    ax.set_ylim(-2, 2)
    ax.set_title('standing still: drift')
    ax.legend(fontsize='small')
    fig.tight_layout()
    fig.savefig(out / 'stability_standing.png', dpi=100)
    plt.close(fig)


def run_stability(out, quick=False, log=print):
    """Run the suite; write stability.md and plots under `out`; return the Suite."""
    started = time.perf_counter()
    suite = Suite(quick, log)
    for case in (suite.drops_case, suite.standing_case, suite.start_stop_case,
                 suite.extreme_sand_case, suite.timestep_case, suite.fast_intrusion_case,
                 suite.divergence_case, suite.treatments_case):
        case()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / 'stability.md').write_text(_markdown(suite, time.perf_counter() - started))
    _plots(out, suite)
    return suite
