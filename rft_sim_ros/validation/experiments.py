"""The sweeps of the validation, one function per experiment of the paper. Each returns
{key: Case}; `log(text)` is told about every finished run."""
import math

from .cases import run_case

#: Extra sim time after a rotation: the carriage comes to rest, s.
SETTLE_AFTER_ROTATION_S = 0.5

RAIL_SHAPES = ('flat', 'open_c', 'closed_c')


def _logged(log, label, case):
    state = 'ok' if case.stable else f'UNSTABLE ({case.reason})'
    log(f'{label:48s} {case.wall_s:6.1f} s  {state}')
    return case


def torque_vs_speed(settings, log):
    """Fixed-base rotating intruder at each speed: {speed rad/s: Case}."""
    return {speed: _logged(log, f'rotating_intruder speed={speed:g}', run_case(
        'rotating_intruder', {'rft.plates_per_body': settings.rail_plates, 'speed': speed},
        math.pi / speed + 0.1)) for speed in settings.speeds}


def torque_vs_depth(settings, log):
    """Fixed-base intruder at 2 rad/s, shallow immersions: {max depth m: Case}."""
    return {depth: _logged(log, f'rotating_intruder max_depth={depth:g}', run_case(
        'rotating_intruder', {'rft.plates_per_body': settings.rail_plates, 'speed': 2.0,
                              'max_depth': depth}, math.pi / 2.0 + 0.1))
            for depth in settings.torque_depths}


def rail_shapes(settings, log):
    """Rail carriage for each shape and speed: {(shape, speed rad/s): Case}."""
    cases = {}
    for shape in RAIL_SHAPES:
        for speed in settings.speeds:
            cases[shape, speed] = _logged(log, f'rail_{shape} speed={speed:g}', run_case(
                f'rail_{shape}', {'rft.plates_per_body': settings.rail_plates, 'speed': speed},
                math.pi / speed + SETTLE_AFTER_ROTATION_S))
    return cases


def leg_vs_zeta(settings, log):
    """Articulated leg, 3 steps, at each zeta: {zeta N/cm^3: Case}."""
    return {zeta: _logged(log, f'articulated_leg zeta={zeta:g}', run_case(
        'articulated_leg', {'rft.plates_per_body': settings.leg_plates,
                            'timestep': settings.leg_timestep, 'zeta': zeta}))
            for zeta in settings.leg_zetas}


def hexapod_grid(settings, log):
    """Hexapod drop + 5 tripod cycles over zeta x payload (the sinkage grid and the two
    speed-vs-payload rows): {(zeta N/cm^3, payload kg): Case}."""
    keys = {(z, p) for z in settings.hexapod_zetas for p in settings.payloads}
    keys |= {(z, p) for z in settings.speed_zetas for p in settings.speed_payloads}
    return {(zeta, payload): _logged(log, f'hexapod zeta={zeta:g} payload={payload:g}', run_case(
        'hexapod', {'rft.plates_per_body': settings.hexapod_plates, 'zeta': zeta,
                    'payload': payload})) for zeta, payload in sorted(keys)}


def hexapod_paper_smoothing(settings, log):
    """Hexapod at zeta 3.75 without payload under the paper's force smoothing (EMA, alpha
    0.1) instead of the default low-velocity treatment: one Case."""
    return _logged(log, 'hexapod zeta=3.75 low_velocity=ema', run_case(
        'hexapod', {'rft.plates_per_body': settings.hexapod_plates,
                    'rft.low_velocity.method': 'ema', 'rft.low_velocity.ema_alpha': 0.1}))
