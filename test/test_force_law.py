"""The RFT force law against analytic values, the published coefficient table and symmetries."""
import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from rft_sim_ros.rft import DynamicTerm, alpha_x, alpha_z, body_wrench, plate_forces
from rft_sim_ros.rft import coefficients as co
from rft_sim_ros.units import zeta_to_si

ZETA = 3.75


# --- the coefficient table of facts.md (Li 2013 generic, zeta = 1) -------------------------
@pytest.mark.parametrize('beta, gamma, az, ax', [
    (0.0, np.pi / 2, 1.000, 0.0),
    (0.0, -np.pi / 2, -0.250, 0.0),
    (0.0, 0.0, 0.375, 0.136),
    (np.pi / 2, 0.0, 0.037, 0.370),
    (np.pi / 2, np.pi / 2, 0.128, 0.0),
    (np.pi / 4, np.pi / 2, 0.564, 0.219),
])
def test_li_coefficient_table(beta, gamma, az, ax):
    assert alpha_z(beta, gamma) == pytest.approx(az, abs=5e-4)
    assert alpha_x(beta, gamma) == pytest.approx(ax, abs=5e-4)


def test_generic_coefficients_sum_to_one():
    total = co.A00 + co.A10 + co.B11 + co.B01 + co.BM11
    assert total == pytest.approx(1.0, abs=1e-12)


def test_normalisation_presets():
    treers, rft_sim = co.normalisation('treers'), co.normalisation('rft_sim')
    assert co.f1(1.0, treers) == pytest.approx(1.0, abs=1e-9)
    assert co.f23(1.0, treers) == pytest.approx(1.0, abs=1e-9)
    assert co.f1(1.0, rft_sim) == pytest.approx(2.03, abs=5e-3)
    assert co.f23(1.0, rft_sim) == pytest.approx(1.348, abs=5e-4)
    with pytest.raises(ValueError, match='unknown RFT normalisation'):
        co.normalisation('nope')


# --- a horizontal plate pushed straight down ----------------------------------------------
def _press(depth, area, speed=0.01, zeta=ZETA, **options):
    return plate_forces([[0.0, 0.0, -depth]], [[0.0, 0.0, -1.0]], [area],
                        [[0.0, 0.0, -speed]], zeta, **options)[0]


def test_horizontal_plate_pushed_down_feels_zeta_area_depth():
    depth, area = 0.02, 1e-4
    force = _press(depth, area)
    expected = zeta_to_si(ZETA) * area * depth  # 3.75 N/cm^3 * 1 cm^2 * 2 cm = 7.5 N
    assert expected == pytest.approx(7.5)
    assert force[2] == pytest.approx(expected, rel=1e-2)
    assert np.hypot(force[0], force[1]) < 1e-9 * expected


def test_press_is_linear_in_depth_and_area():
    base = _press(0.01, 1e-4)[2]
    assert _press(0.03, 1e-4)[2] == pytest.approx(3 * base, rel=1e-12)
    assert _press(0.01, 5e-4)[2] == pytest.approx(5 * base, rel=1e-12)


def test_press_is_rate_independent_below_20_cm_per_s():
    assert _press(0.02, 1e-4, speed=0.01)[2] == pytest.approx(
        _press(0.02, 1e-4, speed=0.15)[2], rel=1e-12)


def test_rft_sim_preset_scales_vertical_stress_by_1_348():
    ratio = _press(0.02, 1e-4, normalisation='rft_sim')[2] / _press(0.02, 1e-4)[2]
    assert ratio == pytest.approx(1.348, abs=5e-4)


# --- a vertical plate dragged sideways --------------------------------------------------------
def test_vertical_plate_dragged_sideways_feels_drag_and_lift():
    # a 2 cm x 4 cm vertical plate facing +x, spanning depths 0..4 cm, in 20 strips
    depths = (np.arange(20) + 0.5) * 0.002
    positions = np.column_stack([np.zeros(20), np.zeros(20), -depths])
    normals = np.tile([1.0, 0.0, 0.0], (20, 1))
    areas = np.full(20, 0.02 * 0.002)
    velocities = np.tile([0.05, 0.0, 0.0], (20, 1))
    force = plate_forces(positions, normals, areas, velocities, ZETA).sum(axis=0)
    scale = zeta_to_si(ZETA) * areas.sum() * depths.mean()
    assert force[0] == pytest.approx(-0.370 * scale, rel=2e-3)
    assert force[2] == pytest.approx(0.037 * scale, rel=2e-2)
    assert abs(force[1]) < 1e-9 * scale


# --- which plates feel force --------------------------------------------------------------
def test_trailing_plates_feel_nothing():
    # bottom face moving up, and a side face moving away from its normal
    forces = plate_forces([[0, 0, -0.02], [0, 0, -0.02]], [[0, 0, -1], [1, 0, 0]],
                          [1e-4, 1e-4], [[0, 0, 0.1], [-0.1, 0, 0]], ZETA)
    assert np.all(forces == 0.0)


def test_plates_above_or_at_the_surface_feel_nothing():
    forces = plate_forces([[0, 0, 0.31], [0, 0, 0.3], [0, 0, 0.29]], [[0, 0, -1]] * 3,
                          [1e-4] * 3, [[0, 0, -0.1]] * 3, ZETA, surface_height=0.3)
    assert np.all(forces[:2] == 0.0)
    assert forces[2, 2] == pytest.approx(zeta_to_si(ZETA) * 1e-4 * 0.01, rel=1e-9)


def test_plates_at_rest_feel_nothing():
    assert np.all(plate_forces([[0, 0, -0.02]], [[0, 0, -1]], [1e-4], [[0, 0, 0]], ZETA) == 0)


@pytest.mark.parametrize('bad', [0.0, -1.0, float('nan'), float('inf'), 101.0, 'soft'])
def test_invalid_zeta_is_refused_with_reason(bad):
    with pytest.raises(ValueError, match='zeta must be'):
        _press(0.01, 1e-4, zeta=bad)


def test_symmetric_body_pushed_down_has_no_lateral_force_or_torque():
    import trimesh
    for mesh in (trimesh.creation.icosphere(4, radius=0.03),
                 trimesh.creation.cylinder(radius=0.02, height=0.05, sections=64)):
        force, torque = body_wrench(mesh, [0, 0, -0.01], np.eye(3), [0, 0, -0.05], [0, 0, 0],
                                    ZETA)
        assert force[2] > 0
        assert np.hypot(force[0], force[1]) < 1e-9 * force[2]
        assert np.linalg.norm(torque) < 1e-9 * force[2] * 0.03


def test_dynamic_term_adds_density_times_normal_speed_squared():
    term = DynamicTerm(lam=1.2, density=1500.0)
    for speed in (0.5, 1.0, 2.0):
        extra = _press(0.02, 1e-4, speed=speed, dynamic=term)[2] - _press(0.02, 1e-4, speed=speed)[2]
        assert extra == pytest.approx(1.2 * 1500.0 * speed ** 2 * 1e-4, rel=1e-12)


# --- properties -------------------------------------------------------------------------------
unit = st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).filter(
    lambda v: np.linalg.norm(v) > 1e-3)


@given(normal=unit, velocity=unit, depth=st.floats(1e-4, 0.2), angle=st.floats(-np.pi, np.pi))
def test_turning_the_scene_about_the_vertical_turns_the_force(normal, velocity, depth, angle):
    n = np.array(normal) / np.linalg.norm(normal)
    v = np.array(velocity)
    assume(abs(n @ v) > 1e-9 * np.linalg.norm(v))  # leading-edge test is a step at n.v = 0
    c, s = np.cos(angle), np.sin(angle)
    turn = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    point = np.array([[0.1, -0.2, -depth]])
    before = plate_forces(point, [n], [1e-4], [v], ZETA)[0]
    after = plate_forces(point @ turn.T, [turn @ n], [1e-4], [turn @ v], ZETA)[0]
    assert np.allclose(after, turn @ before, atol=1e-9 * max(1.0, np.linalg.norm(before)))


@given(normal=unit, velocity=unit, depth=st.floats(1e-4, 0.2))
def test_sand_never_does_positive_work_and_mirrors(normal, velocity, depth):
    n = np.array(normal) / np.linalg.norm(normal)
    v = np.array(velocity)
    force = plate_forces([[0, 0, -depth]], [n], [1e-4], [v], ZETA)[0]
    assert force @ v <= 0.0
    mirror = np.diag([1.0, -1.0, 1.0])
    mirrored = plate_forces([[0, 0, -depth]], [mirror @ n], [1e-4], [mirror @ v], ZETA)[0]
    assert np.allclose(mirrored, mirror @ force, atol=1e-12 * max(1.0, np.linalg.norm(force)))


def test_nearly_horizontal_plate_moving_vertically_turns_with_the_scene():
    """Regression: e2 fell back to a fixed +x here, breaking rotation invariance."""
    n = np.array([0.0, 0.03125, 1.0]) / np.linalg.norm([0.0, 0.03125, 1.0])
    c, s = np.cos(1.0), np.sin(1.0)
    turn = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    before = plate_forces([[0, 0, -0.1]], [n], [1e-4], [[0, 0, 1.0]], ZETA)[0]
    after = plate_forces([[0, 0, -0.1]], [turn @ n], [1e-4], [[0, 0, 1.0]], ZETA)[0]
    assert np.linalg.norm(before) > 0
    assert np.allclose(after, turn @ before, atol=1e-12)


def test_normals_that_are_not_unit_vectors_are_refused():
    rng = np.random.default_rng(3)
    normals = rng.normal(size=(1606, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    args = dict(positions=np.full((1606, 3), -0.02), areas=np.full(1606, 1e-4),
                velocities=rng.normal(size=(1606, 3)), zeta=ZETA)
    plate_forces(normals=normals, **args)                 # unit: accepted
    for bad in (normals * 1.01, np.vstack([normals[:-1], [[0.0, 0.0, 0.0]]]),
                np.vstack([normals[:-1], [[np.nan, 0.0, 1.0]]])):
        with pytest.raises(ValueError, match='normals must be unit vectors'):
            plate_forces(normals=bad, **args)


@pytest.mark.parametrize('change, reason', [
    ({'positions': [[0.0, 0.0, np.nan]]}, r'positions must be finite: positions\[0, 2\] is nan'),
    ({'velocities': [[0.0, np.inf, -0.1]]}, r'velocities\[0, 1\] is inf'),
    ({'areas': [np.nan]}, r'areas must be finite'),
    ({'areas': [-1e-4]}, r'areas must be >= 0 m\^2: area 0 is -0.0001'),
    ({'surface_height': np.inf}, 'surface_height must be finite'),
    ({'positions': [[0.0, 0.0, -0.1]] * 2}, 'one position, normal, velocity and area per '
                                            'plate: got 2, 1, 1 and 1'),
])
def test_inputs_that_are_no_plates_are_refused_with_the_reason(change, reason):
    """A NaN position would feel nothing and a negative area the opposite force, silently:
    both are refused, as are plate counts that differ."""
    args = dict(positions=[[0.0, 0.0, -0.1]], normals=[[0.0, 0.0, -1.0]], areas=[1e-4],
                velocities=[[0.0, 0.0, -0.1]], zeta=ZETA)
    assert plate_forces(**args)[0, 2] == pytest.approx(zeta_to_si(ZETA) * 1e-4 * 0.1)
    with pytest.raises(ValueError, match=reason):
        plate_forces(**{**args, **change})


@pytest.mark.parametrize('rounding', [1e-17, -1e-17, 0.0])
def test_a_plate_sliding_in_its_own_plane_trails_whatever_the_rounding(rounding):
    """One leading rule (force_law.TANGENTIAL) in the reference, the compiled law and the
    engine: n . v within rounding of 0 is sliding, not leading."""
    from rft_sim_ros.rft.coefficients import NORMALISATIONS
    from rft_sim_ros.rft.force_law import TANGENTIAL
    from rft_sim_ros.rft.kernel import plate_forces_compiled
    from rft_sim_ros.sand import gather
    assert gather.TANGENTIAL is TANGENTIAL
    normal = np.array([[1.0, 0.0, 0.0]])
    velocity = np.array([[rounding, 0.05, 0.0]])          # along the plate's own plane
    args = (np.array([[0.0, 0.0, -0.02]]), normal, np.array([1e-4]), velocity)
    assert not plate_forces(*args, zeta=ZETA).any()
    norm = NORMALISATIONS['treers']
    assert not plate_forces_compiled(*args, zeta_to_si(ZETA), 0.0, norm.a4, norm.b4, 0.0).any()
    velocity[0, 0] = 1e-6                                 # a real normal component leads
    assert plate_forces(*args, zeta=ZETA).any()
