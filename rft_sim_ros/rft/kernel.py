"""Compiled (numba) form of the RFT force law, for the simulation's inner loop.

The same law as `force_law.plate_forces`, written per plate without atan2/sin/cos: the
angles beta and gamma enter the Li 2013 fit only through cos/sin of beta, 2 beta and gamma,
which follow algebraically from the unit normal and the unit velocity. Only f1 and f23 need
transcendental functions, evaluated as tanh(y) = (e^2y - 1)/(e^2y + 1) and
atanh(x) = log((1 + x)/(1 - x))/2. Tests hold this kernel to the numpy reference (1e-9
relative).

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


@njit(cache=True, inline='always', error_model='numpy')
def unit_stress(nx, ny, nz, ux, uy, uz, inv_a4, inv_b4):
    """RFT stress per unit depth and per unit zeta, for outward unit normal n and unit
    velocity u of a leading plate: returns (sx, sy, sz), dimensionless, world axes.
    The force on the plate is zeta_si * depth * area * s. inv_a4, inv_b4: 1 / normalisers."""
    # e2: horizontal direction of the normal, or of the velocity for near-horizontal plates;
    # the other one where that vanishes, +x where both do (see force_law._e2_directions).
    flat = abs(nz) >= HORIZONTAL_NZ
    if flat:
        hx, hy, gx, gy = ux, uy, nx, ny
    else:
        hx, hy, gx, gy = nx, ny, ux, uy
    length2 = hx * hx + hy * hy
    if length2 < 1e-24:
        hx, hy = gx, gy
        length2 = hx * hx + hy * hy
    if length2 < 1e-24:
        e2x, e2y = 1.0, 0.0
    else:
        inv_length = 1.0 / np.sqrt(length2)
        e2x, e2y = hx * inv_length, hy * inv_length
    # e1 = e2 x E3 = (e2y, -e2x, 0); v23 = u - (u.e1) e1 lies in the (e2, E3) plane
    u_e1 = ux * e2y - uy * e2x
    u_e2 = ux * e2x + uy * e2y  # = v23 . e2
    vt = min(abs(u_e1), 1.0)
    vn = np.sqrt(u_e2 * u_e2 + uz * uz)
    # beta = atan2(nz, n.e2) + pi/2  ->  sin(beta) = c0, cos(beta) = -s0.
    n_e2 = nx * e2x + ny * e2y
    if flat:
        inv_rho = 1.0 / np.sqrt(nz * nz + n_e2 * n_e2)
        c0, s0 = n_e2 * inv_rho, nz * inv_rho
    else:  # e2 is n's own horizontal direction, so (n.e2, nz) is already a unit vector
        c0, s0 = n_e2, nz
    cos2b = s0 * s0 - c0 * c0
    sin2b = -2.0 * c0 * s0
    # gamma = -atan2(v23_z, v23.e2).
    if vn > 0.0:
        inv_vn = 1.0 / vn
        cosg, sing = u_e2 * inv_vn, -uz * inv_vn
    else:
        cosg, sing = 1.0, 0.0
    vn = min(vn, 1.0)
    sin_2b_g = sin2b * cosg + cos2b * sing
    sin_g_2b = sing * cos2b - cosg * sin2b
    cos_2b_g = cos2b * cosg - sin2b * sing
    cos_g_2b = cosg * cos2b + sing * sin2b
    alpha_z = _A00 + _A10 * cos2b + _B11 * sin_2b_g + _B01 * sing + _BM11 * sin_g_2b
    alpha_x = _C11 * cos_2b_g + _C01 * cosg + _CM11 * cos_g_2b + _D10 * sin2b

    # tanh and atanh through one exp and one log (4x cheaper than the libm calls here)
    growth = np.exp(2.0 * (_A2 * vt - _A3))
    f1 = _A1 * ((growth - 1.0) / (growth + 1.0) + _TANH_A3) * inv_a4
    x = _B2 * vn - _B3
    f23 = _B1 * (0.5 * np.log((1.0 + x) / (1.0 - x)) + _ATANH_B3) * inv_b4
    sign = 1.0 if u_e1 > 0.0 else (-1.0 if u_e1 < 0.0 else 0.0)
    lateral = -f1 * _ALPHA_Y * sign
    along = f23 * alpha_x
    # e1 = (e2y, -e2x, 0)
    return (lateral * e2y - along * e2x,
            -lateral * e2x - along * e2y,
            f23 * alpha_z)


@njit(cache=True, inline='always', error_model='numpy')
def plate_force(nx, ny, nz, vx, vy, vz, depth, area, zeta_si, inv_a4, inv_b4, dyn_lam_rho):
    """Force (N, world axes) on one plate: normal n (unit), velocity v (m/s), depth (m, > 0
    below the surface), area (m^2). inv_a4, inv_b4: reciprocal normalisers. dyn_lam_rho =
    lambda * rho (kg/m^3) of the dynamic term, 0 to switch it off. Zero for plates above the
    surface or trailing (n . v <= 0)."""
    n_v = nx * vx + ny * vy + nz * vz
    speed = np.sqrt(vx * vx + vy * vy + vz * vz)
    if depth <= 0.0 or n_v <= 0.0 or speed <= 0.0:
        return 0.0, 0.0, 0.0
    return leading_plate_force(nx, ny, nz, vx, vy, vz, n_v, 1.0 / speed, depth, area, zeta_si,
                               inv_a4, inv_b4, dyn_lam_rho)


@njit(cache=True, inline='always', error_model='numpy')
def leading_plate_force(nx, ny, nz, vx, vy, vz, n_v, inv_speed, depth, area, zeta_si,
                        inv_a4, inv_b4, dyn_lam_rho):
    """`plate_force` for a plate known to be in the sand and leading, with n . v and
    1 / |v| already computed."""
    sx, sy, sz = unit_stress(nx, ny, nz, vx * inv_speed, vy * inv_speed, vz * inv_speed,
                             inv_a4, inv_b4)
    scale = zeta_si * depth * area
    dyn = dyn_lam_rho * n_v * n_v * area
    return scale * sx - dyn * nx, scale * sy - dyn * ny, scale * sz - dyn * nz


@njit(cache=True, error_model='numpy')
def plate_forces_compiled(positions, normals, areas, velocities, zeta_si, surface_height,
                          a4, b4, dyn_lam_rho):
    """Vectorised `plate_force` over N plates: arrays as in `force_law.plate_forces`
    (SI; zeta_si in N/m^3). Returns (N, 3) forces, N."""
    n = areas.shape[0]
    out = np.zeros((n, 3))
    for j in range(n):
        fx, fy, fz = plate_force(normals[j, 0], normals[j, 1], normals[j, 2],
                                 velocities[j, 0], velocities[j, 1], velocities[j, 2],
                                 surface_height - positions[j, 2], areas[j], zeta_si,
                                 1.0 / a4, 1.0 / b4, dyn_lam_rho)
        out[j, 0], out[j, 1], out[j, 2] = fx, fy, fz
    return out
