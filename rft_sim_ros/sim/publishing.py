"""When a publish cycle ends: at the requested rate on average, on whole steps.

A state is published after whole steps only (its stamp is a step's sim time), and the
publish period 1 / rate is rarely a whole number of timesteps (the hexapod: 10 ms of
0.8 ms steps = 12.5). Rounding it to whole steps would change the rate (13 steps: 96.15 Hz,
12: 104.17 Hz). Instead cycle n ends at the step nearest to n publish periods (Bresenham's
rule on the exact ratio of periods to steps), so cycles take either of the two neighbouring
whole numbers of steps (12 or 13) and n cycles always span n / rate within half a step:
the mean rate is the requested one. The node and the headless runs (`run_scene`, the bag)
both use this schedule.
"""
from fractions import Fraction
import math

#: Largest denominator of the steps-per-period ratio (a rate given to ~6 significant digits).
_DENOMINATOR = 1_000_000


class PublishSchedule:
    """Publish cycles at `rate_hz` (per second of sim time) of a simulation stepping
    `timestep` s. A rate above one per step publishes every step (rate 1 / timestep)."""

    def __init__(self, rate_hz, timestep):
        rate_hz, timestep = float(rate_hz), float(timestep)
        if not (math.isfinite(rate_hz) and rate_hz > 0 and math.isfinite(timestep)
                and timestep > 0):
            raise ValueError(f'publish rate and timestep must be > 0, got {rate_hz} Hz and '
                             f'{timestep} s')
        ratio = Fraction(1.0 / (rate_hz * timestep)).limit_denominator(_DENOMINATOR)
        self._steps_per_cycle = max(ratio, Fraction(1))
        # end_step in integers: floor(n p / q + 1/2) = (2 n p + q) // 2 q (a Fraction
        # operation costs ~10 us, at every published state)
        self._twice_p = 2 * self._steps_per_cycle.numerator
        self._q, self._twice_q = (self._steps_per_cycle.denominator,
                                  2 * self._steps_per_cycle.denominator)
        self._timestep = timestep

    @property
    def period(self):
        """Mean sim time between publications, s (1 / rate, or one step at most)."""
        return float(self._steps_per_cycle * Fraction(self._timestep))

    @property
    def rate(self):
        """Mean publications per second of sim time, Hz."""
        return 1.0 / self.period

    def end_step(self, cycle):
        """Steps from the start at which cycle `cycle` (1, 2, ...) ends: the nearest whole
        step to `cycle` periods (halves round up); 0 for cycle 0."""
        return (cycle * self._twice_p + self._q) // self._twice_q

    def steps(self, cycle):
        """Steps that cycle `cycle` (1, 2, ...) takes."""
        return self.end_step(cycle) - self.end_step(cycle - 1)
