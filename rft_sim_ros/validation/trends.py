"""The paper's trends, checked on the sweep results: each is held or not held, with the
numbers that decide it. Thresholds are stated here and printed in the report."""
from dataclasses import dataclass

import numpy as np

#: Torque increase counts as speed independent if 0.5 and 2 rad/s differ by at most this.
SPEED_INDEPENDENCE_TOLERANCE = 0.10

#: Walking = at least this forward distance over the 5 cycles, m (10 % of the no-slip
#: 0.5 m of a 50 mm stroke); less is "little or no progress".
WALKING_DISTANCE_M = 0.05


@dataclass(frozen=True)
class Trend:
    """One trend: what the paper says, whether our runs show it, and the evidence."""
    name: str
    paper: str
    held: bool
    evidence: str


def torque_increase(cases):
    """{speed: peak servo torque increase, N m} of the rotating-intruder cases."""
    return {speed: case.metrics['peak_torque_increase_Nm'] for speed, case in cases.items()}


def rail_progress(cases):
    """{(shape, speed): carriage displacement, m} of the rail cases."""
    return {key: case.metrics['carriage_displacement_m'] for key, case in cases.items()}


def _monotonic(values, rising):
    steps = np.diff(np.asarray(values, dtype=float))
    return bool(np.all(steps > 0) if rising else np.all(steps < 0))


def check(settings, torque, rails, hexapod):
    """[Trend] for the sweep results (dicts of Cases, as from `experiments`)."""
    trends = []
    inc = torque_increase(torque)
    slow, fast = inc[min(inc)], inc[max(inc)]
    change = abs(fast - slow) / max(abs(slow), abs(fast))
    trends.append(Trend(
        'Intrusion torque independent of rotation speed',
        'peak torque increase +0.055 N m at 0.5, 1 and 2 rad/s',
        change <= SPEED_INDEPENDENCE_TOLERANCE,
        f'peak increase {slow:.3f} N m at {min(inc):g} rad/s, {fast:.3f} N m at {max(inc):g} '
        f'rad/s: {100 * change:.1f} % apart '
        f'(tolerance {100 * SPEED_INDEPENDENCE_TOLERANCE:.0f} %)'))

    trends += shape_ordering(settings, rails)
    sink = {key: case.metrics['mean_sinkage_m'] for key, case in hexapod.items()}
    zetas, payloads = settings.hexapod_zetas, settings.payloads
    bad = [f'zeta {z:g}' for z in zetas if not _monotonic([sink[z, p] for p in payloads], True)]
    trends.append(Trend(
        'Hexapod sinkage grows with payload', 'sinkage increases with payload (Fig. C, E)',
        not bad, 'mean stance sinkage (mm) for payloads ' + ', '.join(f'{p:g}' for p in payloads)
        + ' kg: ' + '; '.join(f'zeta {z:g}: ' + '/'.join(f'{1e3 * sink[z, p]:.1f}'
                                                          for p in payloads) for z in zetas)
        + (f'. Not monotonic at {", ".join(bad)}' if bad else '')))
    bad = [f'{p:g} kg' for p in payloads if not _monotonic([sink[z, p] for z in zetas], False)]
    trends.append(Trend(
        'Hexapod sinkage falls as zeta grows', 'sinkage decreases with zeta (Fig. C)',
        not bad, 'see the sinkage table; ' + ('decreasing at every payload' if not bad else
                                              f'not monotonic for payload {", ".join(bad)}')))

    distance = {key: case.metrics['forward_distance_m'] for key, case in hexapod.items()}
    loose = min(zetas)
    walking = all(distance[z, p] >= WALKING_DISTANCE_M for z in zetas if z >= 0.5
                  for p in payloads)
    stalled = all(distance[loose, p] < WALKING_DISTANCE_M for p in payloads)
    trends.append(Trend(
        f'Hexapod walks at zeta >= 0.5, little or no progress at zeta {loose:g}',
        'walks at zeta 0.5, fails to progress below 0.5',
        walking and stalled and loose < 0.5,
        f'forward distance over 5 cycles (threshold {100 * WALKING_DISTANCE_M:.0f} cm), '
        'payloads ' + '/'.join(f'{p:g}' for p in payloads) + ' kg: '
        + '; '.join(f'zeta {z:g}: ' + '/'.join(f'{100 * distance[z, p]:.1f}' for p in payloads)
                    + ' cm' for z in zetas)))

    trends.append(payload_optimum(settings, hexapod))
    return trends


def shape_ordering(settings, rails, loop=''):
    """The rail trends (ordering, open C least) for rail cases {(shape, speed): Case}; `loop`
    is appended to their names (e.g. " (the authors' loop)")."""
    progress = rail_progress(rails)
    rows, order_ok, open_ok = [], True, True
    for speed in settings.speeds:
        flat, open_c, closed_c = (progress[s, speed] for s in ('flat', 'open_c', 'closed_c'))
        order_ok &= closed_c > flat > open_c
        open_ok &= open_c < flat and open_c < closed_c
        rows.append(f'{speed:g} rad/s: closed {100 * closed_c:.1f}, flat {100 * flat:.1f}, '
                    f'open {100 * open_c:.1f} cm')
    return [Trend('Carriage progress closed C > flat > open C at every speed' + loop,
                  'ordering held at all three speeds (simulation and experiment)',
                  order_ok, '; '.join(rows)),
            Trend('Open C progresses least at every speed (part of the ordering)' + loop,
                  'open C -25 % vs flat in simulation, -53 % in experiment',
                  open_ok, '; '.join(rows))]


def payload_optimum(settings, hexapod, loop=''):
    """The payload trend for hexapod cases {(zeta, payload): Case} over settings.speed_zetas
    x settings.speed_payloads; `loop` is appended to its name."""
    peaks = {}
    for zeta in settings.speed_zetas:
        speeds = [hexapod[zeta, p].metrics['mean_speed_mps'] for p in settings.speed_payloads]
        best = int(np.argmax(speeds))
        peaks[zeta] = (0 < best < len(speeds) - 1, settings.speed_payloads[best])
    low, high = settings.speed_zetas
    return Trend(
        f'Hexapod speed peaks at an intermediate payload at zeta {low:g}, not at zeta {high:g}'
        + loop,
        'intermediate optimum at zeta 3.75 (as in experiment), none at zeta 5',
        peaks[low][0] and not peaks[high][0],
        '; '.join(f'zeta {z:g}: fastest at {peaks[z][1]:g} kg '
                  f'({"intermediate" if peaks[z][0] else "an end of the range"})'
                  for z in settings.speed_zetas))


def check_paper_loop(settings, rails, hexapod):
    """The rail and payload trends again for the runs with the authors' loop."""
    loop = " (the authors' loop)"
    return shape_ordering(settings, rails, loop) + [payload_optimum(settings, hexapod, loop)]
