"""When /diagnostics goes out, and the real-time factor it reports.

ROS-free; shared by the node and the headless bag recorder so both follow one rule:
a status every `period_s` (the node counts wall seconds, as diagnostic_updater does; the
headless recorder counts sim seconds, so its bags are reproducible) and at once when what
the status says changes: zeta, stable/diverged, paused/running, the robot going down (a fall,
upside down, a collapse or sinking).
`outcome_values`: what /diagnostics says of the run's outcome (sim/outcome.py).
"""
import math



def status_key(zeta, stable, paused, down=False):
    """What makes a new /diagnostics due at once: a change of the last published state's
    zeta (N/cm^3), or of whether the run is stable or paused (messages.RunStatus), or
    whether the robot has gone down (`Simulation.down`: fallen, upside down, collapsed or
    sunk)."""
    return zeta, stable, paused, down


def outcome_values(outcome):
    """[(key, value)] of /diagnostics for a run's `outcome` (summary.json's, sim/outcome.py;
    None: none yet): outcome (its words), fell, fell_at_s (nan: it did not fall),
    max_tilt_deg, collapsed, collapsed_at_s (nan: it did not collapse), sank, sank_at_s (nan:
    it did not sink), deepest_body ('' where no geom went below the surface), deepest_sinkage_m,
    deepest_has_plates, unsettled_step_share, max_uncovered_sinkage_m (nan: every watched
    body carries plates), upside_down, upside_down_at_s (nan: it was not) and
    final_up_angle_deg (nan: not judged); the last three after the others, which keep their
    places."""
    if outcome is None:
        return []
    deepest = outcome['deepest'] or {'body': '', 'sinkage_m': 0.0, 'has_plates': True}

    def number(value):
        return float('nan') if value is None else float(value)
    return [('outcome', outcome['words']), ('fell', bool(outcome['fell'])),
            ('fell_at_s', number(outcome['fell_at_s'])),
            ('max_tilt_deg', float(outcome['max_tilt_deg'])),
            ('collapsed', bool(outcome['collapsed'])),
            ('collapsed_at_s', number(outcome['collapsed_at_s'])),
            ('sank', bool(outcome['sank'])), ('sank_at_s', number(outcome['sank_at_s'])),
            ('deepest_body', deepest['body']), ('deepest_sinkage_m', float(deepest['sinkage_m'])),
            ('deepest_has_plates', bool(deepest['has_plates'])),
            ('unsettled_step_share', float(outcome['unsettled_step_share'])),
            ('max_uncovered_sinkage_m', number(outcome['max_uncovered_sinkage_m'])),
            ('upside_down', bool(outcome['upside_down'])),
            ('upside_down_at_s', number(outcome['upside_down_at_s'])),
            ('final_up_angle_deg', number(outcome['final_up_angle_deg']))]


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
