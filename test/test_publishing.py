"""The publish schedule: whole steps per cycle, the requested rate on average."""
import math
from fractions import Fraction

import pytest

from rft_sim_ros.sim.publishing import PublishSchedule


@pytest.mark.parametrize('rate, timestep, step_counts', [
    (100.0, 0.0008, {12, 13}),     # the hexapod: 12.5 steps per period
    (100.0, 0.001, {10}),          # a whole number of steps
    (30.0, 0.001, {33, 34}),       # 33.33...
    (2000.0, 0.001, {1})])         # faster than the steps: every step
def test_cycles_are_whole_steps_and_n_cycles_span_n_periods(rate, timestep, step_counts):
    schedule = PublishSchedule(rate, timestep)
    period = max(1.0 / rate, timestep)
    assert schedule.period == pytest.approx(period, rel=1e-12)
    assert {schedule.steps(n) for n in range(1, 1001)} == step_counts
    for n in (1, 7, 1000, 123_457):
        assert abs(schedule.end_step(n) * timestep - n * period) <= 0.5 * timestep + 1e-12 * n


def test_hexapod_publishes_at_100_hz_not_104():
    schedule = PublishSchedule(100.0, 0.0008)
    assert schedule.end_step(100) * 0.0008 == pytest.approx(1.0)   # 100 cycles in 1 s
    assert schedule.rate == pytest.approx(100.0)


@pytest.mark.parametrize('rate, timestep', [(0.0, 0.001), (-1.0, 0.001), (math.nan, 0.001),
                                            (100.0, 0.0), (math.inf, 0.001)])
def test_bad_rates_are_refused(rate, timestep):
    with pytest.raises(ValueError, match='must be > 0'):
        PublishSchedule(rate, timestep)


@pytest.mark.parametrize('rate, timestep', [(100.0, 0.0008), (30.0, 0.001), (59.94, 0.0007),
                                            (2000.0, 0.001), (1.0, 0.002)])
def test_end_step_is_the_nearest_whole_step_halves_rounding_up(rate, timestep):
    """Integer arithmetic gives floor(n x steps per period + 1/2) exactly (as Fractions)."""
    schedule = PublishSchedule(rate, timestep)
    ratio = max(Fraction(1.0 / (rate * timestep)).limit_denominator(1_000_000), Fraction(1))
    for n in [*range(0, 300), 10**6 + 3, 2**40 + 1]:
        assert schedule.end_step(n) == math.floor(n * ratio + Fraction(1, 2))
