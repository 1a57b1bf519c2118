"""Pacing sim time against wall time (the node's timer arithmetic)."""
import math

import pytest

from rft_sim_ros.ros.pacing import Pacer

PERIOD = 0.01  # s of sim time per publish cycle


def test_as_fast_as_possible_is_always_due():
    pacer = Pacer(0.0)
    assert pacer.due(wall=0.0, cycle_end=1e6)
    assert pacer.tick_period(PERIOD) == 0.001


@pytest.mark.parametrize('rate', [0.5, 1.0, 4.0])
def test_a_cycle_is_due_once_wall_time_catches_up(rate):
    pacer = Pacer(rate)
    pacer.restart(wall=100.0, sim_time=2.0)
    due_at = 100.0 + PERIOD / rate
    assert not pacer.due(due_at - 1e-4, 2.0 + PERIOD)
    assert pacer.due(due_at, 2.0 + PERIOD)
    assert not pacer.due(due_at, 2.0 + 2 * PERIOD)
    assert pacer.due(100.0 + 2 * PERIOD / rate, 2.0 + 2 * PERIOD)


def test_cycles_over_a_second_follow_the_factor():
    pacer = Pacer(2.0)
    pacer.restart(0.0, 0.0)
    sim = 0.0
    for wall in [k * 0.001 for k in range(1001)]:  # a 1 kHz timer for 1 s of wall time
        while pacer.due(wall, sim + PERIOD):
            sim += PERIOD
    assert sim == pytest.approx(2.0, abs=PERIOD / 2)


def test_falling_behind_forgives_the_debt_instead_of_sprinting():
    pacer = Pacer(1.0, max_lag_s=0.1)
    pacer.restart(0.0, 0.0)
    assert pacer.due(5.0, PERIOD)                 # 5 s late: run this one now ...
    assert not pacer.due(5.0, 2 * PERIOD)         # ... but no burst of 500 cycles
    assert pacer.due(5.0 + PERIOD, 2 * PERIOD)    # the next one a period later


def test_small_lag_is_caught_up():
    pacer = Pacer(1.0, max_lag_s=0.1)
    pacer.restart(0.0, 0.0)
    assert pacer.due(0.05, PERIOD)
    assert pacer.due(0.05, 2 * PERIOD)            # still within the lag: catch up


def test_changing_the_factor_re_anchors():
    pacer = Pacer(1.0)
    pacer.restart(0.0, 0.0)
    pacer.set_real_time_factor(0.1, wall=10.0, sim_time=3.0)
    assert pacer.real_time_factor == 0.1
    assert not pacer.due(10.0 + 0.05, 3.0 + PERIOD)
    assert pacer.due(10.0 + 0.1, 3.0 + PERIOD)


def test_tick_period_is_half_a_cycle_within_bounds():
    assert Pacer(1.0).tick_period(PERIOD) == pytest.approx(0.005)
    assert Pacer(100.0).tick_period(PERIOD) == 0.001
    assert Pacer(0.01).tick_period(PERIOD) == 0.05


@pytest.mark.parametrize('bad', [-1.0, math.nan, math.inf])
def test_bad_factor_is_refused(bad):
    with pytest.raises(ValueError, match='real_time_factor'):
        Pacer(bad)
    pacer = Pacer(1.0)
    with pytest.raises(ValueError, match='real_time_factor'):
        pacer.set_real_time_factor(bad, 0.0, 0.0)
    assert pacer.real_time_factor == 1.0


def test_due_needs_an_anchor():
    with pytest.raises(RuntimeError, match='restart'):
        Pacer(1.0).due(0.0, PERIOD)
