"""The compiled force kernel agrees with the numpy reference (the law is written twice: once
with atan2/sin/cos as published, once algebraically for speed)."""
import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from rft_sim_ros.rft import DynamicTerm, plate_forces
from rft_sim_ros.rft.coefficients import NORMALISATIONS
from rft_sim_ros.rft import kernel
from rft_sim_ros.rft.kernel import plate_forces_compiled
from rft_sim_ros.units import zeta_to_si


def _compare(positions, normals, areas, velocities, zeta, surface=0.0, norm='treers',
             dynamic=None):
    reference = plate_forces(positions, normals, areas, velocities, zeta, surface,
                             normalisation=norm, dynamic=dynamic)
    n = NORMALISATIONS[norm]
    dyn = 0.0 if dynamic is None else dynamic.lam * dynamic.density
    fast = plate_forces_compiled(positions, normals, areas, velocities, zeta_to_si(zeta),
                                 surface, n.a4, n.b4, dyn)
    scale = np.maximum(np.linalg.norm(reference, axis=1), 1e-300)
    error = np.linalg.norm(fast - reference, axis=1) / scale
    assert np.all((fast == reference).all(axis=1) | (error <= 1e-9)), error.max()
    return reference


finite = st.floats(-1.0, 1.0, allow_nan=False)


@given(data=arrays(np.float64, (64, 9), elements=finite),
       zeta=st.floats(0.1, 50.0), norm=st.sampled_from(sorted(NORMALISATIONS)),
       dynamic=st.booleans())
def test_kernel_matches_reference_on_random_plates(data, zeta, norm, dynamic):
    positions = data[:, 0:3] * 0.05
    normals = data[:, 3:6] + np.array([0.0, 0.0, 1e-3])
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    velocities = data[:, 6:9]
    areas = np.full(64, 2e-5)
    _compare(positions, normals, areas, velocities, zeta, norm=norm,
             dynamic=DynamicTerm(1.0, 1600.0) if dynamic else None)


def test_kernel_matches_reference_on_edge_cases():
    rng = np.random.default_rng(7)
    n = 400
    normals = rng.normal(size=(n, 3))
    normals[:100] = [0.0, 0.0, -1.0]                       # horizontal, facing down
    normals[100:150] = [0.0, 0.0, 1.0]                     # horizontal, facing up
    normals[150:200, 2] = -1.0 + 0.5e-3                    # at the near-horizontal threshold
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    velocities = rng.normal(size=(n, 3))
    velocities[:50] = [0.0, 0.0, -0.1]                     # straight down (e2 undefined)
    velocities[50:60] = 0.0                                # v = 0
    velocities[100:120] = [0.0, 0.0, 0.1]                  # straight up
    positions = rng.normal(size=(n, 3)) * 0.02
    positions[200:260, 2] = 0.0                            # exactly at the surface
    reference = _compare(positions, normals, np.full(n, 1e-5), velocities, 3.75)
    assert np.count_nonzero(np.linalg.norm(reference, axis=1)) > 50


def test_arithmetic_log_and_exp_match_numpy_over_their_ranges():
    """The law's vectorisable exp holds 4e-15 relative over the range the law feeds it
    (tanh's argument within [-2 a3, 2 (a2 - a3)]) and the documented margin beyond; its log of
    a ratio 2e-15 relative over atanh's ratios (within [0.013, 4.6]) and beyond, and 2e-15
    of max(|log|, 1) for any positive normal numerator and denominator."""
    x = np.linspace(-4.3, 4.3, 20001)
    exp = np.array([kernel._exp_bounded(value) for value in x])
    assert np.max(np.abs(exp / np.exp(x) - 1)) < 4e-15
    y = np.geomspace(2 ** -7.5, 2 ** 2.5, 20001)
    log = np.array([kernel._log_ratio(value, 1.0) for value in y])
    assert np.max(np.abs(log - np.log(y)) / np.maximum(np.abs(np.log(y)), 1e-3)) < 2e-15
    rng = np.random.default_rng(3)
    numerator, denominator = 10.0 ** rng.uniform(-300, 300, (2, 20000))
    log = np.array([kernel._log_ratio(a, b) for a, b in zip(numerator, denominator)])
    exact = np.log(numerator.astype(np.longdouble)) - np.log(denominator.astype(np.longdouble))
    assert np.max(np.abs(log - exact) / np.maximum(np.abs(exact), 1.0)) < 2e-15
