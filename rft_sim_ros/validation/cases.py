"""One validation case = one headless run of a bundled scene with overrides; the sweep
settings of the quick and the full validation; and `run_cases`, which runs many cases on all
cores (the study machinery's process pool, rft_sim_ros/study/pool.py)."""
import math
import time
from dataclasses import dataclass, field
from typing import Optional

from ..scenes.config import load_scene
from ..sim.simulation import Simulation, SimulationDiverged
from ..study.cost import dearest_first, run_cost
from ..study.pool import map_unordered


@dataclass(frozen=True)
class Settings:
    """What `rft-sim validate` sweeps. Plates per sand body, timesteps in s, zeta in N/cm^3,
    payloads in kg, speeds in rad/s."""
    quick: bool
    rail_plates: int
    leg_plates: int
    leg_timestep: float
    hexapod_plates: int
    leg_zetas: tuple
    hexapod_zetas: tuple
    speed_payloads: tuple
    speeds: tuple = (0.5, 1.0, 2.0)
    payloads: tuple = (0.0, 1.0, 2.277)
    speed_zetas: tuple = (3.75, 5.0)
    torque_depths: tuple = (0.005, 0.0075, 0.01)


QUICK = Settings(quick=True, rail_plates=300, leg_plates=300, leg_timestep=0.0005,
                 hexapod_plates=100, leg_zetas=(0.1, 0.5, 3.75),
                 hexapod_zetas=(0.1, 0.5, 3.75, 5.0), speed_payloads=(0.0, 1.0, 2.277))

FULL = Settings(quick=False, rail_plates=2000, leg_plates=2000, leg_timestep=0.00025,
                hexapod_plates=500, leg_zetas=(0.1, 0.5, 1.0, 2.0, 3.75, 5.0),
                hexapod_zetas=(0.1, 0.5, 1.0, 2.0, 3.75, 5.0, 5.8),
                speed_payloads=(0.0, 0.5, 1.0, 1.5, 2.0, 2.277, 3.0))


@dataclass
class Case:
    """Outcome of one run: scene metrics (SI), the scenario's `series()` (arrays), wall time
    (s), whether it stayed stable (with the reason if not) and the plate count."""
    scene: str
    overrides: dict
    metrics: dict = field(default_factory=dict)
    series: dict = field(default_factory=dict)
    wall_s: float = 0.0
    stable: bool = True
    reason: Optional[str] = None
    plates_total: int = 0


@dataclass(frozen=True)
class CaseSpec:
    """A case to run: a label for the log, bundled scene, overrides (as --set) and sim
    duration (s, None: the scene's)."""
    label: str
    scene: str
    overrides: dict
    duration: Optional[float] = None


def run_spec(spec):
    """Run a CaseSpec: its Case."""
    return run_case(spec.scene, spec.overrides, spec.duration)


def run_cases(groups, workers=None, log=print):
    """Run every CaseSpec of `groups` ({group: {key: CaseSpec}}) on `workers` processes
    (default: all cores; the dearest first, study/cost.py), logging each as it finishes; return {group: {key: Case}} in the
    order given. Raises RuntimeError if a case cannot run (its worker died twice)."""
    jobs = [(group, key, spec) for group, specs in groups.items() for key, spec in specs.items()]
    jobs = [jobs[i] for i in dearest_first([
        run_cost(load_scene(spec.scene, spec.overrides), spec.duration) for _, _, spec in jobs])]
    done = {}
    for outcome in map_unordered(run_spec, [spec for _, _, spec in jobs], workers):
        group, key, spec = jobs[outcome.index]
        if outcome.error is not None:
            raise RuntimeError(f'{spec.label}: {outcome.error}')
        case = outcome.value
        state = 'ok' if case.stable else f'UNSTABLE ({case.reason})'
        log(f'{spec.label:48s} {case.wall_s:6.1f} s  {state}')
        done[group, key] = case
    return {group: {key: done[group, key] for key in specs} for group, specs in groups.items()}


def run_case(scene, overrides, duration=None):
    """Run bundled `scene` with `overrides` ({key: value}, as `--set`) for `duration` s
    (None: the scene's own duration)."""
    started = time.perf_counter()
    config = load_scene(scene, overrides)
    sim = Simulation(config)
    case = Case(scene, dict(overrides), plates_total=sim.engine.plates_total)
    if duration is None:
        duration = config.duration if config.duration is not None else sim.scenario.duration()
    try:
        sim.step(int(math.ceil(duration / sim.timestep - 1e-9)))
    except SimulationDiverged as error:
        case.stable, case.reason = False, str(error)
    case.metrics = sim.scenario.metrics(sim)
    case.series = sim.scenario.series()
    case.wall_s = time.perf_counter() - started
    return case
