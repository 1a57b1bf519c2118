"""Leg kinematics (rft_sim_ros.scenes.leg_kinematics) and built-in gaits (rft_sim_ros.scenes.gaits);
pure numpy, no MuJoCo (test_hexapod_model.py checks both against the MJCF)."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rft_sim_ros.scenes import hexapod
from rft_sim_ros.scenes.gaits import StandGait, TripodGait, make_gait

LEGS = hexapod.LEGS
TRIPOD_A = ('R1', 'L2', 'R3')
TRIPOD_B = ('L1', 'R2', 'L3')


def leg_index(names):
    return [LEGS.names.index(n) for n in names]


def sample(fn, times):
    return np.array([fn(t) for t in times])


angles = st.tuples(st.floats(-1.75, 0.35), st.floats(-1.92, 0.0))


@settings(max_examples=200, deadline=None)
@given(angles)
def test_inverse_kinematics_undoes_forward_kinematics(q):
    knee, ankle = np.full(6, q[0]), np.full(6, q[1])  # the arched branch: ankle <= droop
    foot = LEGS.forward(knee, ankle)
    assert foot[:, 0] == pytest.approx(LEGS.knee_xyz[:, 0])  # legs move in the y-z plane
    assert LEGS.reachable(foot[:, 1], foot[:, 2]).all()
    knee_back, ankle_back = LEGS.inverse(foot[:, 1], foot[:, 2])
    assert knee_back == pytest.approx(knee, abs=1e-6)
    assert ankle_back == pytest.approx(ankle, abs=1e-6)


def test_kinematics_geometry_and_signs():
    assert LEGS.dactyl_length == pytest.approx(0.1090, abs=1e-4)
    assert LEGS.mid_length == pytest.approx(0.075)
    zero = LEGS.forward(np.zeros(6), np.zeros(6))  # the published zero pose
    assert np.abs(zero[:, 1]) == pytest.approx(np.full(6, 0.458))
    assert zero[:, 2] == pytest.approx(np.full(6, -0.015))
    raised = LEGS.forward(np.full(6, 0.2), np.zeros(6)) - zero
    assert (raised[:, 2] > 0.01).all()  # knee > 0: foot up on both sides ...
    assert (np.sign(raised[:, 1]) == -LEGS.side).all()  # ... and inward
    lifted = LEGS.forward(np.zeros(6), np.full(6, 0.2)) - zero
    assert (lifted[:, 2] > 0.01).all()  # ankle > 0: foot up
    neutral = LEGS.neutral_feet()
    assert np.abs(neutral[:, 1]) == pytest.approx(np.full(6, 0.275))  # under the knee axis
    assert neutral[:, 2] == pytest.approx(np.full(6, -0.176))
    knee, ankle = LEGS.neutral_angles()
    assert LEGS.forward(knee, ankle) == pytest.approx(neutral, abs=1e-12)
    # the arched stance: the ankle above the knee-to-foot line, the dactyl pointing down
    ankle_axis_up = LEGS.mid_length * np.sin(knee)
    assert (ankle_axis_up > -0.176 / 2).all()


def test_reachable_rejects_targets_outside_the_workspace():
    neutral = LEGS.neutral_feet()
    assert LEGS.reachable(neutral[:, 1], neutral[:, 2]).all()
    assert not LEGS.reachable(neutral[:, 1], neutral[:, 2] - 0.02).any()  # beyond the reach
    assert not LEGS.reachable(neutral[:, 1] + 0.3, neutral[:, 2]).any()
    assert not LEGS.reachable(neutral[:, 1], neutral[:, 2] + 0.2).any()  # knee past 0.35 rad


def test_stand_gait_holds_the_neutral_stance():
    gait = make_gait('none')
    assert isinstance(gait, StandGait)
    knee, ankle = LEGS.neutral_angles()
    for t in (0.0, 0.37, 12.5):
        assert gait.targets(t) == pytest.approx(np.stack([knee, ankle], axis=-1).ravel())
    assert tuple(gait.target_dict(1.0)) == hexapod.JOINT_NAMES


def test_tripod_defaults_are_the_papers():
    gait = make_gait('tripod')
    assert isinstance(gait, TripodGait)
    assert (gait.frequency_hz, gait.stance_fraction) == (1.0, 0.5)
    assert (gait.step_length_m, gait.step_height_m) == (0.05, 0.06)
    assert gait.phase_offsets == {'R1': 0.0, 'L2': 0.0, 'R3': 0.0,
                                  'L1': 0.5, 'R2': 0.5, 'L3': 0.5}
    assert gait.joint_names == hexapod.JOINT_NAMES
    targets = gait.target_dict(1.3)
    assert list(targets) == list(hexapod.JOINT_NAMES)
    assert list(targets.values()) == pytest.approx(gait.targets(1.3))


def test_tripods_alternate_half_a_cycle_apart():
    gait = make_gait('tripod', ramp_time_s=0.0)
    a, b = leg_index(TRIPOD_A), leg_index(TRIPOD_B)
    for t in np.linspace(0.0, 3.0, 61):
        dy, dz = gait.foot_offsets(t)
        assert np.ptp(dy[a]) < 1e-12 and np.ptp(dy[b]) < 1e-12  # tripods move as one
        assert np.ptp(dz[a]) < 1e-12 and np.ptp(dz[b]) < 1e-12
        dy_later, dz_later = gait.foot_offsets(t + 0.5)
        assert dy_later[b] == pytest.approx(dy[a], abs=1e-12)
        assert dz_later[b] == pytest.approx(dz[a], abs=1e-12)
    for t in np.linspace(0.01, 0.49, 25) + 2.0:  # first half of a cycle: A stands, B swings
        dy, dz = gait.foot_offsets(t)
        assert (dz[a] == 0.0).all() and (dz[b] > 0.0).all()


def test_stance_pushes_the_body_sideways_and_swing_lifts_by_the_step_height():
    gait = make_gait('tripod', ramp_time_s=0.0, step_length_m=0.04, step_height_m=0.05)
    r1 = leg_index(['R1'])[0]
    stance = np.linspace(0.0, 0.4999, 200)
    swing = np.linspace(0.5, 0.9999, 2000)
    dy = sample(lambda t: gait.foot_offsets(t)[0][r1], stance)
    assert dy[0] == pytest.approx(0.02) and dy[-1] == pytest.approx(-0.02, abs=1e-5)
    assert (np.diff(dy) < 0).all()  # feet move to -y relative to the body: it walks to +y
    assert np.diff(dy) == pytest.approx(np.full(199, dy[1] - dy[0]))  # at constant speed
    feet = sample(lambda t: gait.foot_targets(t)[r1, 0], stance)
    assert feet == pytest.approx(LEGS.neutral_feet()[r1, 1] + dy)  # the right leg too
    lift = sample(lambda t: gait.foot_offsets(t)[1][r1], swing)
    assert lift.max() == pytest.approx(0.05, abs=1e-6)
    assert sample(lambda t: gait.foot_offsets(t)[0][r1], swing).max() == pytest.approx(
        0.02, abs=0.002)  # swing returns the foot to the front (small overshoot)


def test_frequency_and_stance_fraction_are_respected():
    gait = make_gait('tripod', ramp_time_s=0.0, frequency_hz=2.0, stance_fraction=0.7)
    r1 = leg_index(['R1'])[0]
    t = np.linspace(0.0, 0.5, 5001)[:-1]  # one cycle
    on_ground = sample(lambda x: gait.foot_offsets(x)[1][r1], t) == 0.0
    assert on_ground.mean() == pytest.approx(0.7, abs=1e-3)
    assert gait.targets(0.123) == pytest.approx(gait.targets(0.623))  # period 0.5 s


@pytest.mark.parametrize('params', [{}, {'frequency_hz': 1.7, 'stance_fraction': 0.6},
                                    {'step_length_m': -0.05, 'start_time_s': 0.3}])
def test_targets_have_continuous_position_and_velocity(params):
    gait = make_gait('tripod', **params)
    dt = 2e-4
    q = sample(gait.targets, np.arange(0.0, 2.0, dt))  # ramp, then every switch at least once
    assert np.isfinite(q).all()
    velocity = np.abs(np.diff(q, axis=0)).max() / dt
    acceleration = np.abs(np.diff(q, 2, axis=0)).max() / dt ** 2
    assert velocity < 20.0  # rad/s (the fastest swing: 17): a 5 mrad jump would read 25
    assert acceleration < 1000.0  # rad/s^2: a velocity kink of 0.2 rad/s would read 1e3
    finer = sample(gait.targets, np.arange(0.0, 2.0, dt / 2))
    assert np.abs(np.diff(finer, axis=0)).max() / (dt / 2) < 1.01 * velocity  # no jump


def test_velocity_matches_across_stance_swing_switches():
    gait = make_gait('tripod', frequency_hz=1.3, stance_fraction=0.55)
    h = 1e-6
    for k in range(2, 8):
        for switch in (0.0, gait.stance_fraction):
            tb = (k + switch) / gait.frequency_hz
            before = (gait.targets(tb) - gait.targets(tb - h)) / h
            after = (gait.targets(tb + h) - gait.targets(tb)) / h
            assert after == pytest.approx(before, abs=1e-3)


def test_ramp_starts_smoothly_from_the_neutral_stance():
    smooth = make_gait('tripod', start_time_s=0.5, ramp_time_s=0.5)
    neutral = make_gait('none').targets(0.0)
    assert smooth.targets(0.2) == pytest.approx(neutral)
    assert smooth.targets(0.5 + 1e-6) == pytest.approx(neutral, abs=1e-6)
    assert smooth.targets(1.7) == pytest.approx(make_gait('tripod', ramp_time_s=0.0,
                                                          start_time_s=0.5).targets(1.7))
    abrupt = make_gait('tripod', start_time_s=0.5, ramp_time_s=0.0)
    assert np.abs(abrupt.targets(0.5) - neutral).max() > 0.1  # without a ramp they jump


@pytest.mark.parametrize('params, message', [
    ({'stance_fraction': 1.0}, 'stance_fraction'),
    ({'frequency_hz': 0.0}, 'frequency_hz'),
    ({'step_length_m': float('nan')}, 'finite'),
    ({'step_height_m': 0.2}, 'out of reach'),
    ({'step_length_m': 0.3}, 'out of reach'),
    ({'phase_offsets': {'L1': 0.0}}, 'phase_offsets'),
])
def test_bad_parameters_are_rejected(params, message):
    with pytest.raises(ValueError, match=message):
        make_gait('tripod', **params)


def test_unknown_gait_is_rejected():
    with pytest.raises(ValueError, match='unknown gait'):
        make_gait('wave')
