"""The largest timestep the sand coupling resolves, estimated from the scene.

RFT makes the sand a spring in depth: a body pressed into it with its plates facing one way
(projected area A, m^2) feels zeta A z, so it has a stiffness k = zeta A (N/m) and, with the
mass m it carries (kg), a time scale tau = sqrt(m / k) (1/omega of that spring). The depth
term is integrated explicitly, so steps that are not short against tau overshoot the depth:

  plate_drop (1 kg, 10 x 10 cm, zeta 3.75, tau 5.16 ms; max depth against energy balance)
    dt/tau 0.19: 0.2 %, 0.39: 1.2 %, 0.58: 2.3 %, 0.77: 1.6 %, 0.97: 3.7 %, 1.45: 24 %,
    1.94: 14 %, 3.9: 32 %, 9.7: 529 %
  hexapod (tau 5.44 ms of the dactyls; distance of the 5-cycle walk against 0.8 ms)
    dt/tau 0.15: 0, 0.29: 0.2 %, 0.46: 0.4 %, 0.74: 0.8 %, 1.10: 2.1 %, 1.47: 4.4 %,
    2.2: -65 %, 3.7 and 9.2: walks backwards

So `RESOLVED_FRACTION` = 1: up to dt = tau both stay within 4 %; beyond 1.5 tau one or the
other fails. Per sand body, A is the largest of its plates' areas projected on the six body
axes (sum of area x max(n . axis, 0): the face that presses hardest), m its subtree mass
(what its joints carry below it; a conservative mass for a leg held by servos), and zeta the
largest the run will use (times the zeta map's largest factor). The bundled scenes' defaults
sit at 0.14 to 0.69 tau.
"""
import numpy as np

from ..units import zeta_to_si

#: dt_max = RESOLVED_FRACTION x the smallest sand time scale (see module docstring).
RESOLVED_FRACTION = 1.0

_AXES = np.vstack([np.eye(3), -np.eye(3)])
#: A timestep within this relative rounding of the bound is within it (a scene's 1 ms at a
#: bound computed as 0.9999999999999996 ms).
ROUNDING = 1e-9


def largest_factor(engine):
    """The largest factor the engine's zeta map multiplies zeta by (1 without a map)."""
    return 1.0 if engine.zeta_map is None else float(np.max(engine.zeta_map.factors))


def sand_time_scales(engine, zeta):
    """{sand body name: tau = sqrt(m / (zeta A)) in s} at zeta (N/cm^3), see module
    docstring."""
    stiffness_per_area = zeta_to_si(zeta) * largest_factor(engine)  # N/m^3
    scales = {}
    for i, (name, body) in enumerate(zip(engine.body_names, engine.body_ids)):
        first, last = engine.plate_start[i], engine.plate_start[i + 1]
        normals, areas = engine.local_normal[first:last], engine.areas[first:last]
        projected = (areas[:, None] * np.maximum(normals @ _AXES.T, 0.0)).sum(axis=0).max()
        mass = engine.model.body_subtreemass[body]
        scales[name] = (float(np.sqrt(mass / (stiffness_per_area * projected)))
                        if projected > 0 and mass > 0 else float('inf'))
    return scales


def timestep_bound(engine, zeta):
    """(dt_max in s, the sand body that sets it): the largest timestep the sand coupling
    resolves at zeta (N/cm^3)."""
    scales = sand_time_scales(engine, zeta)
    body = min(scales, key=scales.get)
    return RESOLVED_FRACTION * scales[body], body


def timestep_problem(engine, timestep, zeta):
    """Why `timestep` (s) is too long for the sand at zeta (N/cm^3), or None."""
    bound, body = timestep_bound(engine, zeta)
    if timestep <= bound * (1.0 + ROUNDING):
        return None
    factor = largest_factor(engine)
    scaled = f' x the zeta map\'s largest factor {factor:g}' if factor != 1.0 else ''
    given, resolved = _apart(timestep * 1e3, bound * 1e3)
    return (f'timestep {given} ms is longer than the {resolved} ms the sand '
            f'coupling resolves (sqrt(m/k) of body {body!r} at zeta {zeta:g} N/cm^3{scaled}; '
            'see rft_sim_ros/sand/timestep.py): results are not to be trusted')


def _apart(value, bound):
    """value (6 or more significant digits) and bound (3 or more) as texts, with as many
    digits as tell them apart."""
    for digits in range(3, 18):
        texts = f'{value:.{max(digits, 6)}g}', f'{bound:.{digits}g}'
        if texts[0] != texts[1]:
            return texts
    return texts
