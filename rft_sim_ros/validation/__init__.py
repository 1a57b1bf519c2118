"""`rft-sim validate`: reproduce the RFT-SiM paper's experiments and trends as a report.

Runs the sweeps (`experiments`) over the bundled scenes on all cores (`cases.run_cases`),
the rail and the hexapod's payload rows both with exact coupling and with the authors' loop
(`rft.coupling: paper`), checks the paper's trends
(`trends`), draws PNG plots (`plots`) and writes `report.md` (`report`) plus the raw
figures as `results.json` into an output folder. `--quick` uses coarse plates and fewer
cases (under a minute); the full run uses the scenes' timesteps and 2000 plates on the
intruders and the leg, 500 on the hexapod (about a minute).
"""
import datetime
import json
import time
from dataclasses import dataclass
from pathlib import Path

from . import experiments, plots, report, trends
from .cases import FULL, QUICK, Settings, run_cases


@dataclass
class Results:
    """Everything the report needs: settings, the cases of each sweep, trends, plot names,
    when and where it ran and how long it took (s)."""
    settings: Settings
    torque: dict
    depths: dict
    rails: dict
    legs: dict
    hexapod: dict
    rails_paper: dict
    hexapod_paper: dict
    hexapod_ema: object
    trends: list
    plots: list
    date: str
    machine: str
    wall_s: float
    case_count: int


def run_validation(out_dir, quick=False, log=print, settings=None, workers=None):
    """Run the validation into `out_dir` (created); return the Results. settings: what to
    sweep (default: QUICK if `quick` else FULL); workers: processes the cases run on
    (default: all cores; the cases are independent runs, their results do not depend on it)."""
    from ..sim.runner import machine_info
    settings = settings or (QUICK if quick else FULL)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    cases = run_cases({name: getattr(experiments, name)(settings) for name in (
        'torque_vs_speed', 'torque_vs_depth', 'rail_shapes', 'leg_vs_zeta', 'hexapod_grid',
        'hexapod_paper_smoothing', 'rail_shapes_paper_loop', 'hexapod_payload_paper_loop')},
        workers, log)
    torque, depths, rails = (cases[k] for k in ('torque_vs_speed', 'torque_vs_depth',
                                                'rail_shapes'))
    legs, hexapod = cases['leg_vs_zeta'], cases['hexapod_grid']
    ema = cases['hexapod_paper_smoothing'][None]
    rails_paper, hexapod_paper = (cases[k] for k in ('rail_shapes_paper_loop',
                                                     'hexapod_payload_paper_loop'))
    names = [
        plots.torque_vs_angle(out, torque),
        plots.rail_displacement_vs_angle(out, rails, settings.speeds),
        plots.rail_displacement_vs_speed(out, rails, settings.speeds, rails_paper),
        plots.articulated_leg(out, legs),
        plots.hexapod_position_vs_time(out, hexapod, 3.75),
        plots.hexapod_sinkage_vs_zeta(out, hexapod, settings.hexapod_zetas, settings.payloads),
        plots.hexapod_speed_vs_payload(out, hexapod, settings.speed_zetas,
                                       settings.speed_payloads, hexapod_paper),
    ]
    info = machine_info()
    results = Results(
        settings=settings, torque=torque, depths=depths, rails=rails, legs=legs,
        hexapod=hexapod, rails_paper=rails_paper, hexapod_paper=hexapod_paper, hexapod_ema=ema,
        trends=(trends.check(settings, torque, rails, hexapod)
                + trends.check_paper_loop(settings, rails_paper, hexapod_paper)),
        plots=names, date=datetime.date.today().isoformat(),
        machine=f'{info["cpu"]}, Python {info["python"]}, MuJoCo {info["mujoco"]}',
        wall_s=time.perf_counter() - started,
        case_count=sum(len(group) for group in cases.values()))
    report.write(out / 'report.md', results)
    (out / 'results.json').write_text(json.dumps(_as_json(results), indent=2))
    return results


def _as_json(r):
    """The figures of `r` as plain JSON (metrics per case; no time series)."""
    def cases(group, label):
        return [{**dict(zip(label, key if isinstance(key, tuple) else (key,))),
                 'stable': c.stable, 'reason': c.reason, 'wall_s': c.wall_s,
                 'plates_total': c.plates_total, 'metrics': c.metrics}
                for key, c in sorted(group.items())]
    return {
        'quick': r.settings.quick, 'date': r.date, 'machine': r.machine, 'wall_s': r.wall_s,
        'trends': [{'name': t.name, 'held': t.held, 'paper': t.paper, 'evidence': t.evidence}
                   for t in r.trends],
        'rotating_intruder': cases(r.torque, ('speed_radps',)),
        'rotating_intruder_depth': cases(r.depths, ('max_sinkage_m',)),
        'rail': cases(r.rails, ('shape', 'speed_radps')),
        'articulated_leg': cases(r.legs, ('zeta',)),
        'hexapod': cases(r.hexapod, ('zeta', 'payload_kg')),
        'rail_paper_loop': cases(r.rails_paper, ('shape', 'speed_radps')),
        'hexapod_paper_loop': cases(r.hexapod_paper, ('zeta', 'payload_kg')),
        'hexapod_paper_smoothing': cases({0: r.hexapod_ema}, ('zeta',))[0],
    }
