"""Compiled (numba) form of the RFT force law, for the simulation's inner loop.

The same law as `force_law.plate_forces`, written without atan2/sin/cos: the angles beta and
gamma enter the Li 2013 fit only through cos/sin of beta, 2 beta and gamma, which follow
algebraically from the unit normal and the unit velocity. Only f1 and f23 need transcendental
functions: tanh(y) = (e^2y - 1)/(e^2y + 1) with an arithmetic exponential, and
atanh(x) = log((1 + x)/(1 - x))/2. The plates are processed as structure-of-arrays in
branch-free loops that the compiler vectorises. Tests hold this kernel to the numpy reference
(1e-9 relative).

Units as in `force_law`: SI arrays, zeta already converted to N/m^3 (`units.zeta_to_si`).
Compiled functions are cached on disk (numba cache=True), so only a cold start compiles.
"""
import numpy as np
from numba import njit

from . import coefficients as co
from .force_law import HORIZONTAL_NZ

_TANH_A3 = float(np.tanh(co._F1_A3))
_ATANH_B3 = float(np.arctanh(co._F23_B3))
_A1, _A2, _A3 = co._F1_A1, co._F1_A2, co._F1_A3
_B1, _B2, _B3 = co._F23_B1, co._F23_B2, co._F23_B3
_A00, _A10, _B11, _B01, _BM11 = co.A00, co.A10, co.B11, co.B01, co.BM11
_C11, _C01, _CM11, _D10 = co.C11, co.C01, co.CM11, co.D10
_ALPHA_Y = co.ALPHA_Y


@njit(cache=True, inline='always')
def _exp_bounded(x):
    """e^x for |x| <= 4.3 (relative error < 3e-15) in plain arithmetic, so that loops using
    it vectorise: a degree-14 Taylor polynomial of e^(x/8), squared three times."""
    y = x * 0.125
    p = 1.0 / 87178291200.0
    p = 1.0 / 6227020800.0 + y * p
    p = 1.0 / 479001600.0 + y * p
    p = 1.0 / 39916800.0 + y * p
    p = 1.0 / 3628800.0 + y * p
    p = 1.0 / 362880.0 + y * p
    p = 1.0 / 40320.0 + y * p
    p = 1.0 / 5040.0 + y * p
    p = 1.0 / 720.0 + y * p
    p = 1.0 / 120.0 + y * p
    p = 1.0 / 24.0 + y * p
    p = 1.0 / 6.0 + y * p
    p = 0.5 + y * p
    p = 1.0 + y * p
    p = 1.0 + y * p
    p = p * p
    p = p * p
    return p * p


@njit(cache=True, error_model='numpy')
def leading_forces(count, nx, ny, nz, ux, uy, uz, n_v, scale, area, inv_a4, inv_b4,
                   dyn_lam_rho, fx, fy, fz, scratch):
    """RFT forces (N, world axes) on `count` leading plates in the sand, given as arrays:
    outward unit normal (nx, ny, nz), unit velocity (ux, uy, uz), n . v (m/s), scale =
    zeta_si * depth * area (N), area (m^2); inv_a4, inv_b4: reciprocal normalisers;
    dyn_lam_rho = lambda * rho (kg/m^3) of the dynamic term, 0 for none. Writes fx, fy, fz.

    Branch-free loops over structure-of-arrays, so the compiler vectorises all of it but the
    logarithm of f23 (its own scalar loop); scratch: (6, >= count) work space.
    """
    for j in range(count):
        # e2: horizontal direction of the normal, or of the velocity for near-horizontal
        # plates; the other one where that vanishes, +x where both do.
        flat = abs(nz[j]) >= HORIZONTAL_NZ
        hx = ux[j] if flat else nx[j]
        hy = uy[j] if flat else ny[j]
        gx = nx[j] if flat else ux[j]
        gy = ny[j] if flat else uy[j]
        length2 = hx * hx + hy * hy
        fallback = length2 < 1e-24
        hx = gx if fallback else hx
        hy = gy if fallback else hy
        length2 = hx * hx + hy * hy
        undefined = length2 < 1e-24
        inv_length = 1.0 / np.sqrt(1.0 if undefined else length2)
        e2x = 1.0 if undefined else hx * inv_length
        e2y = 0.0 if undefined else hy * inv_length
        # e1 = e2 x E3 = (e2y, -e2x, 0); v23 = u - (u.e1) e1 lies in the (e2, E3) plane
        u_e1 = ux[j] * e2y - uy[j] * e2x
        u_e2 = ux[j] * e2x + uy[j] * e2y  # = v23 . e2
        vt = min(abs(u_e1), 1.0)
        vn = np.sqrt(u_e2 * u_e2 + uz[j] * uz[j])
        # beta = atan2(nz, n.e2) + pi/2  ->  sin(beta) = c0, cos(beta) = -s0; for a plate
        # that is not flat, (n.e2, nz) is already a unit vector.
        n_e2 = nx[j] * e2x + ny[j] * e2y
        inv_rho = 1.0 / np.sqrt(nz[j] * nz[j] + n_e2 * n_e2) if flat else 1.0
        c0 = n_e2 * inv_rho
        s0 = nz[j] * inv_rho
        cos2b = s0 * s0 - c0 * c0
        sin2b = -2.0 * c0 * s0
        # gamma = -atan2(v23_z, v23.e2).
        moving = vn > 0.0
        inv_vn = 1.0 / (vn if moving else 1.0)
        cosg = u_e2 * inv_vn if moving else 1.0
        sing = -uz[j] * inv_vn if moving else 0.0
        alpha_z = (_A00 + _A10 * cos2b + _B11 * (sin2b * cosg + cos2b * sing) + _B01 * sing
                   + _BM11 * (sing * cos2b - cosg * sin2b))
        alpha_x = (_C11 * (cos2b * cosg - sin2b * sing) + _C01 * cosg
                   + _CM11 * (cosg * cos2b + sing * sin2b) + _D10 * sin2b)
        growth = _exp_bounded(2.0 * (_A2 * vt - _A3))  # tanh = (e^2y - 1) / (e^2y + 1)
        f1 = _A1 * ((growth - 1.0) / (growth + 1.0) + _TANH_A3) * inv_a4
        x = _B2 * min(vn, 1.0) - _B3
        sign = 1.0 if u_e1 > 0.0 else (-1.0 if u_e1 < 0.0 else 0.0)
        scratch[0, j] = (1.0 + x) / (1.0 - x)  # atanh(x) = log(this) / 2
        scratch[1, j] = -f1 * _ALPHA_Y * sign  # along e1
        scratch[2, j] = alpha_x
        scratch[3, j] = alpha_z
        scratch[4, j] = e2x
        scratch[5, j] = e2y
    for j in range(count):
        scratch[0, j] = np.log(scratch[0, j])
    for j in range(count):
        f23 = _B1 * (0.5 * scratch[0, j] + _ATANH_B3) * inv_b4
        lateral = scratch[1, j]
        along = f23 * scratch[2, j]
        e2x = scratch[4, j]
        e2y = scratch[5, j]
        dyn = dyn_lam_rho * n_v[j] * n_v[j] * area[j]
        fx[j] = scale[j] * (lateral * e2y - along * e2x) - dyn * nx[j]
        fy[j] = scale[j] * (-lateral * e2x - along * e2y) - dyn * ny[j]
        fz[j] = scale[j] * f23 * scratch[3, j] - dyn * nz[j]


@njit(cache=True, inline='always')
def stage_leading(soa, m, nx, ny, nz, ux, uy, uz, n_v, scale, area):
    """Put leading plate number m into the (9, N) staging array of `staged_forces`: unit
    normal, unit velocity, n . v (m/s), scale = zeta_si * depth * area (N), area (m^2)."""
    soa[0, m], soa[1, m], soa[2, m] = nx, ny, nz
    soa[3, m], soa[4, m], soa[5, m] = ux, uy, uz
    soa[6, m] = n_v
    soa[7, m] = scale
    soa[8, m] = area


@njit(cache=True, error_model='numpy')
def staged_forces(count, soa, where, inv_a4, inv_b4, dyn_lam_rho, force, scratch, out):
    """RFT forces of the `count` leading plates staged in `soa` (`stage_leading`), written
    to out[where[m]] (N, world). force: (3, >= count), scratch: (6, >= count) work space."""
    leading_forces(count, soa[0], soa[1], soa[2], soa[3], soa[4], soa[5], soa[6], soa[7],
                   soa[8], inv_a4, inv_b4, dyn_lam_rho, force[0], force[1], force[2], scratch)
    for m in range(count):
        at = where[m]
        out[at, 0], out[at, 1], out[at, 2] = force[0, m], force[1, m], force[2, m]


@njit(cache=True, error_model='numpy')
def plate_forces_compiled(positions, normals, areas, velocities, zeta_si, surface_height,
                          a4, b4, dyn_lam_rho):
    """Compiled `force_law.plate_forces`: arrays as there (SI; zeta_si in N/m^3). Returns
    (N, 3) forces, N. Plates above the surface or trailing (n . v <= 0) feel zero."""
    n = areas.shape[0]
    soa = np.empty((9, n))
    where = np.empty(n, dtype=np.int64)
    count = 0
    for j in range(n):
        depth = surface_height - positions[j, 2]
        vx, vy, vz = velocities[j, 0], velocities[j, 1], velocities[j, 2]
        n_v = normals[j, 0] * vx + normals[j, 1] * vy + normals[j, 2] * vz
        speed = np.sqrt(vx * vx + vy * vy + vz * vz)
        if depth <= 0.0 or n_v <= 0.0 or speed <= 0.0:
            continue
        inv = 1.0 / speed
        stage_leading(soa, count, normals[j, 0], normals[j, 1], normals[j, 2], vx * inv,
                      vy * inv, vz * inv, n_v, zeta_si * depth * areas[j], areas[j])
        where[count] = j
        count += 1
    out = np.zeros((n, 3))
    staged_forces(count, soa, where, 1.0 / a4, 1.0 / b4, dyn_lam_rho, np.empty((3, count)),
                  np.empty((6, count)), out)
    return out
