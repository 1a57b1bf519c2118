"""One validation case = one headless run of a bundled scene with overrides; and the sweep
settings of the quick and the full validation."""
import math
import time
from dataclasses import dataclass, field
from typing import Optional

from ..scenes.config import load_scene
from ..sim.simulation import Simulation, SimulationDiverged


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
