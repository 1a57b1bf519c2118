"""Pace sim time against wall time: when may the next publish cycle run?

ROS-free arithmetic for the node's wall-clock timer. The simulation advances in whole publish
cycles (one publish period of sim time each); a cycle is due once wall time has caught up
with it at the requested real-time factor, counted from an anchor (wall time, sim time)
set at start, on resume, on reset and whenever the factor changes. A run that falls behind
by more than `max_lag_s` of wall time forgives the debt (re-anchors) instead of bursting
to catch up, so a slow machine runs as fast as it can but never sprints.
All times in s; wall time from any monotonic clock.
"""
import math

#: Wall-clock slack, s, below which a cycle counts as on time (float rounding of anchors).
_TOLERANCE_S = 1e-9


class Pacer:
    """Decides whether a publish cycle ending at a given sim time may run now.

    real_time_factor: sim seconds per wall second; 0 = as fast as possible (always due).
    max_lag_s: wall seconds the run may fall behind before the debt is forgiven.
    """

    def __init__(self, real_time_factor, max_lag_s=0.1):
        if not (math.isfinite(max_lag_s) and max_lag_s >= 0.0):
            raise ValueError(f'max_lag_s must be a finite number >= 0, got {max_lag_s}')
        self.max_lag_s = float(max_lag_s)
        self._rate = self._checked(real_time_factor)
        self._wall = None
        self._sim = None

    @staticmethod
    def _checked(real_time_factor):
        value = float(real_time_factor)
        if not (math.isfinite(value) and value >= 0.0):
            raise ValueError(f'real_time_factor must be a finite number >= 0, got {value}')
        return value

    @property
    def real_time_factor(self):
        """Sim seconds per wall second (0 = as fast as possible)."""
        return self._rate

    def restart(self, wall, sim_time):
        """Anchor pacing at wall time `wall` and sim time `sim_time` (s)."""
        self._wall, self._sim = float(wall), float(sim_time)

    def set_real_time_factor(self, value, wall, sim_time):
        """Change the factor from now on (re-anchors at `wall`, `sim_time`)."""
        self._rate = self._checked(value)
        self.restart(wall, sim_time)

    def due(self, wall, cycle_end):
        """Whether the cycle that ends at sim time `cycle_end` (s) may run at wall time `wall`.

        Re-anchors when the run is more than `max_lag_s` behind (the cycle is then due).
        """
        if self._rate == 0.0:
            return True
        if self._wall is None:
            raise RuntimeError('Pacer.restart() must be called before due()')
        due_at = self._wall + (cycle_end - self._sim) / self._rate  # wall time, s
        if wall - due_at > self.max_lag_s:
            self.restart(wall, cycle_end)  # forgive the debt: this cycle is on time now
            return True
        return due_at <= wall + _TOLERANCE_S

    def tick_period(self, publish_period, shortest=0.001, longest=0.05):
        """Wall seconds between timer ticks: half a cycle's wall duration, within
        [shortest, longest]; `shortest` when running as fast as possible."""
        if self._rate == 0.0:
            return shortest
        return min(max(0.5 * publish_period / self._rate, shortest), longest)
