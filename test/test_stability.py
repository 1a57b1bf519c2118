"""Fast versions of the stability suite's checks (`rft-sim validate --stability --quick`
cases: coarser plates, shorter holds, fewer heights and zetas), and the suite's own
measurements on made-up traces, so that each check is seen to fail when it should."""
import numpy as np
import pytest

from rft_sim_ros.validation import stability
from rft_sim_ros.validation.stability import REBOUND_BOUND_M, Suite, Trace


@pytest.fixture(scope='module')
def suite():
    return Suite(quick=True, log=lambda line: None)


@pytest.mark.parametrize('case', ['drops_case', 'standing_case', 'start_stop_case',
                                  'extreme_sand_case', 'timestep_case', 'fast_intrusion_case',
                                  'divergence_case'])
def test_quick_suite_case_holds_at_the_default_settings(suite, case):
    before = len(suite.rows)
    getattr(suite, case)()
    rows = suite.rows[before:]
    assert rows
    failed = [f'{r.case}: {r.metric} = {r.value} ({r.bound})' for r in rows if not r.held]
    assert not failed


def test_raw_explicit_rft_fails_the_rebound_check_that_the_default_passes():
    """The check tells the treatments apart: a 1 m drop bounces with raw explicit RFT."""
    default = stability.trace('plate_drop', {'drop_height': 1.0}, 1.0)
    explicit = stability.trace('plate_drop', {'drop_height': 1.0,
                                              'rft.low_velocity.method': 'none'}, 1.0)
    assert stability.rebound(default) < REBOUND_BOUND_M < stability.rebound(explicit)


def _trace(low_points, base=None):
    low = np.asarray(low_points, dtype=float).reshape(len(low_points), -1)
    n = len(low)
    base = np.zeros((n, 3)) if base is None else np.asarray(base, dtype=float)
    return Trace('made_up', {}, np.arange(n) * 0.1, base, np.zeros(n), low)


def test_rebound_is_the_largest_rise_after_first_touching_the_sand():
    # falls, touches at -0.01, sinks to -0.03, rises to -0.02, sinks again
    assert stability.rebound(_trace([0.5, 0.1, -0.01, -0.03, -0.02, -0.04])) == pytest.approx(0.01)
    assert stability.rebound(_trace([0.5, 0.2, 0.3, 0.1])) == 0.0  # never reached the sand
    # two feet: the worst one counts
    two = _trace([[0.1, 0.1], [-0.01, -0.01], [-0.02, 0.005], [-0.02, -0.02]])
    assert stability.rebound(two) == pytest.approx(0.015)


def test_drift_is_the_base_displacement_over_the_last_seconds():
    base = np.zeros((31, 3))
    base[:, 0] = np.linspace(0.0, 0.003, 31)  # 1 mm per second over 3 s
    run = _trace(np.zeros(31), base)
    assert stability.drift(run, seconds=1.0) == pytest.approx(0.001)
    assert stability.drift(run, seconds=5.0) == pytest.approx(0.003)


def test_a_row_holds_only_for_a_finite_value_within_its_bound():
    test = lambda v: v < 1e-3  # noqa: E731
    assert stability._row('c', 'm', 5e-4, '< 1e-3', test).held
    assert not stability._row('c', 'm', 2e-3, '< 1e-3', test).held
    assert not stability._row('c', 'm', float('nan'), '< 1e-3', test).held
    assert not stability._row('c', 'm', None, '< 1e-3', test).held
