"""The sweeps of the validation, one function per experiment of the paper (and the rail and
the hexapod's payload again with the authors' loop, `rft.coupling: paper`). Each returns
{key: CaseSpec} (what to run); `cases.run_cases` runs them all on the study machinery's
process pool and hands back {key: Case}."""
import math

from ..sand.paper_loop import PAPER_SETTINGS
from .cases import CaseSpec

#: Extra sim time after a rotation: the carriage comes to rest, s.
SETTLE_AFTER_ROTATION_S = 0.5

RAIL_SHAPES = ('flat', 'open_c', 'closed_c')

#: The paper's timestep of the rail scenes, s (its hexapod's, 0.8 ms, is the scene's own):
#: the authors' loop lags one step, so its results depend on the step.
PAPER_RAIL_TIMESTEP_S = 0.001


def torque_vs_speed(settings):
    """Fixed-base rotating intruder at each speed: {speed rad/s: CaseSpec}."""
    return {speed: CaseSpec(f'rotating_intruder speed={speed:g}', 'rotating_intruder',
                            {'rft.plates_per_body': settings.rail_plates, 'speed': speed},
                            math.pi / speed + 0.1) for speed in settings.speeds}


def torque_vs_depth(settings):
    """Fixed-base intruder at 2 rad/s, shallow immersions: {max depth m: CaseSpec}."""
    return {depth: CaseSpec(f'rotating_intruder max_depth={depth:g}', 'rotating_intruder',
                            {'rft.plates_per_body': settings.rail_plates, 'speed': 2.0,
                             'max_depth': depth}, math.pi / 2.0 + 0.1)
            for depth in settings.torque_depths}


def rail_shapes(settings):
    """Rail carriage for each shape and speed: {(shape, speed rad/s): CaseSpec}."""
    return {(shape, speed): CaseSpec(
        f'rail_{shape} speed={speed:g}', f'rail_{shape}',
        {'rft.plates_per_body': settings.rail_plates, 'speed': speed},
        math.pi / speed + SETTLE_AFTER_ROTATION_S)
        for shape in RAIL_SHAPES for speed in settings.speeds}


def rail_shapes_paper_loop(settings):
    """`rail_shapes` with the authors' loop (`sand.paper_loop.PAPER_SETTINGS`) at their 1 ms
    timestep: {(shape, speed rad/s): CaseSpec}."""
    return {key: CaseSpec(spec.label + ' paper loop', spec.scene,
                          {**spec.overrides, **PAPER_SETTINGS,
                           'timestep': PAPER_RAIL_TIMESTEP_S}, spec.duration)
            for key, spec in rail_shapes(settings).items()}


def leg_vs_zeta(settings):
    """Articulated leg, 3 steps, at each zeta: {zeta N/cm^3: CaseSpec}."""
    return {zeta: CaseSpec(f'articulated_leg zeta={zeta:g}', 'articulated_leg',
                           {'rft.plates_per_body': settings.leg_plates,
                            'timestep': settings.leg_timestep, 'zeta': zeta})
            for zeta in settings.leg_zetas}


def hexapod_grid(settings):
    """Hexapod drop + 5 tripod cycles over zeta x payload (the sinkage grid and the two
    speed-vs-payload rows): {(zeta N/cm^3, payload kg): CaseSpec}."""
    keys = {(z, p) for z in settings.hexapod_zetas for p in settings.payloads}
    keys |= {(z, p) for z in settings.speed_zetas for p in settings.speed_payloads}
    return {(zeta, payload): CaseSpec(
        f'hexapod zeta={zeta:g} payload={payload:g}', 'hexapod',
        {'rft.plates_per_body': settings.hexapod_plates, 'zeta': zeta, 'payload': payload})
        for zeta, payload in sorted(keys)}


def hexapod_payload_paper_loop(settings):
    """The speed-against-payload rows of `hexapod_grid` (zeta in settings.speed_zetas) with the
    authors' loop: {(zeta N/cm^3, payload kg): CaseSpec}."""
    return {(zeta, payload): CaseSpec(
        f'hexapod zeta={zeta:g} payload={payload:g} paper loop', 'hexapod',
        {'rft.plates_per_body': settings.hexapod_plates, 'zeta': zeta, 'payload': payload,
         **PAPER_SETTINGS})
        for zeta in settings.speed_zetas for payload in settings.speed_payloads}


def hexapod_paper_smoothing(settings):
    """Hexapod at zeta 3.75 without payload under the paper's force smoothing (EMA, alpha
    0.1) instead of the default low-velocity treatment: {None: CaseSpec}."""
    return {None: CaseSpec('hexapod zeta=3.75 low_velocity=ema', 'hexapod', {
        'rft.plates_per_body': settings.hexapod_plates, 'rft.low_velocity.method': 'ema',
        'rft.low_velocity.ema_alpha': 0.1})}
