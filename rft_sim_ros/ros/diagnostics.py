"""When /diagnostics goes out, and the real-time factor it reports.

ROS-free; shared by the node and the headless bag recorder so both follow one rule:
a status every `period_s` (the node counts wall seconds, as diagnostic_updater does; the
headless recorder counts sim seconds, so its bags are reproducible) and at once when what
the status says changes: zeta, stable/diverged, paused/running, the robot going down (a fall,
upside down, a collapse or sinking).
`outcome_values`: what /diagnostics says of the run's outcome (sim/outcome.py).
"""
import math

from rft_sim_ros.sim.ways_down import DOWN


def status_key(zeta, stable, paused, down=False):
    """What makes a new /diagnostics due at once: a change of the last published state's
    zeta (N/cm^3), or of whether the run is stable or paused (messages.RunStatus), or
    whether the robot has gone down (`Simulation.down`: fallen, upside down, collapsed or
    sunk)."""
    return zeta, stable, paused, down


def outcome_values(outcome):
    """[(key, value)] of /diagnostics for a run's `outcome` (summary.json's, sim/outcome.py;
    None: none yet): outcome (its words); for each way down (sim/ways_down.py's DOWN) whether
    it happened and when (fell, fell_at_s, upside_down, upside_down_at_s, collapsed,
    collapsed_at_s, sank, sank_at_s; nan: it did not); max_tilt_deg, final_up_angle_deg
    (nan: not watched), deepest_body ('' where no geom went below the surface),
    deepest_sinkage_m, deepest_has_plates, unsettled_step_share and max_uncovered_sinkage_m
    (nan: every watched body carries plates)."""
    if outcome is None:
        return []
    deepest = outcome['deepest'] or {'body': '', 'sinkage_m': 0.0, 'has_plates': True}

    def number(value):
        return float('nan') if value is None else float(value)
    values = [('outcome', outcome['words'])]
    for key, at_key, _ in DOWN:
        values += [(key, bool(outcome[key])), (at_key, number(outcome[at_key]))]
    return values + [
        ('max_tilt_deg', float(outcome['max_tilt_deg'])),
        ('final_up_angle_deg', number(outcome['final_up_angle_deg'])),
        ('deepest_body', deepest['body']), ('deepest_sinkage_m', float(deepest['sinkage_m'])),
        ('deepest_has_plates', bool(deepest['has_plates'])),
        ('unsettled_step_share', float(outcome['unsettled_step_share'])),
        ('max_uncovered_sinkage_m', number(outcome['max_uncovered_sinkage_m']))]


class DiagnosticsSchedule:
    """`due(now, key)`: True every `period_s` of `now`'s clock (s) and whenever `key` differs
    from the key of the last due status. Calling `due` with a True answer records it."""

    def __init__(self, period_s=1.0):
        if not (math.isfinite(period_s) and period_s > 0.0):
            raise ValueError(f'period_s must be a finite number > 0, got {period_s}')
        self.period_s = float(period_s)
        self._time = None
        self._key = None

    def due(self, now, key):
        if self._time is not None and key == self._key and now - self._time < self.period_s:
            return False
        self._time, self._key = now, key
        return True


class RateMeter:
    """Real-time factor achieved between successive `rate` calls: sim seconds advanced per
    wall second (nan for the first call or no wall time elapsed)."""

    def __init__(self):
        self._last = None

    def rate(self, sim_time, wall):
        last, self._last = self._last, (sim_time, wall)
        if last is None or wall <= last[1]:
            return math.nan
        return (sim_time - last[0]) / (wall - last[1])
