"""When /diagnostics goes out, and the real-time factor it reports.

ROS-free; shared by the node and the headless bag recorder so both follow one rule:
a status every `period_s` (the node counts wall seconds, as diagnostic_updater does; the
headless recorder counts sim seconds, so its bags are reproducible) and at once when what
the status says changes: zeta, stable/diverged, paused/running.
"""
import math


def status_key(zeta, stable, paused):
    """What makes a new /diagnostics due at once: a change of the last published state's
    zeta (N/cm^3), or of whether the run is stable or paused (messages.RunStatus)."""
    return zeta, stable, paused


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
