"""Compiled (numba) form of the RFT force law, for the simulation's inner loop.

The same law as `force_law.plate_forces`, written per plate without atan2/sin/cos: the
angles beta and gamma enter the Li 2013 fit only through cos/sin of beta, 2 beta and gamma,
which follow algebraically from the unit normal and the unit velocity. Only f1 and f23 need
transcendental functions. Tests hold this kernel to the numpy reference (1e-9 relative).

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
def unit_stress(nx, ny, nz, ux, uy, uz, a4, b4):
    """RFT stress per unit depth and per unit zeta, for outward unit normal n and unit
    velocity u of a leading plate: returns (sx, sy, sz), dimensionless, world axes.
    The force on the plate is zeta_si * depth * area * s."""
    # e2: horizontal direction of the normal, or of the velocity for near-horizontal plates;
    # the other one where that vanishes, +x where both do (see force_law._e2_directions).
    if abs(nz) < HORIZONTAL_NZ:
        hx, hy, gx, gy = nx, ny, ux, uy
    else:
        hx, hy, gx, gy = ux, uy, nx, ny
    length = np.sqrt(hx * hx + hy * hy)
    if length < 1e-12:
        hx, hy = gx, gy
        length = np.sqrt(hx * hx + hy * hy)
    if length < 1e-12:
        e2x, e2y = 1.0, 0.0
    else:
        e2x, e2y = hx / length, hy / length
    e1x, e1y = e2y, -e2x  # e1 = e2 x E3
    u_e1 = ux * e1x + uy * e1y
    v23x, v23y, v23z = ux - u_e1 * e1x, uy - u_e1 * e1y, uz
    vt = min(abs(u_e1), 1.0)
    vn = min(np.sqrt(v23x * v23x + v23y * v23y + v23z * v23z), 1.0)

    # beta = atan2(nz, n.e2) + pi/2  ->  sin(beta) = c0, cos(beta) = -s0.
    n_e2 = nx * e2x + ny * e2y
    rho = np.sqrt(nz * nz + n_e2 * n_e2)
    c0, s0 = n_e2 / rho, nz / rho
    cos2b = s0 * s0 - c0 * c0
    sin2b = -2.0 * c0 * s0
    # gamma = -atan2(v23_z, v23.e2).
    v23_e2 = v23x * e2x + v23y * e2y
    q = np.sqrt(v23z * v23z + v23_e2 * v23_e2)
    if q > 0.0:
        cosg, sing = v23_e2 / q, -v23z / q
    else:
        cosg, sing = 1.0, 0.0
    sin_2b_g = sin2b * cosg + cos2b * sing
    sin_g_2b = sing * cos2b - cosg * sin2b
    cos_2b_g = cos2b * cosg - sin2b * sing
    cos_g_2b = cosg * cos2b + sing * sin2b
    alpha_z = _A00 + _A10 * cos2b + _B11 * sin_2b_g + _B01 * sing + _BM11 * sin_g_2b
    alpha_x = _C11 * cos_2b_g + _C01 * cosg + _CM11 * cos_g_2b + _D10 * sin2b

    f1 = _A1 * (np.tanh(_A2 * vt - _A3) + _TANH_A3) / a4
    f23 = _B1 * (np.arctanh(_B2 * vn - _B3) + _ATANH_B3) / b4
    sign = 1.0 if u_e1 > 0.0 else (-1.0 if u_e1 < 0.0 else 0.0)
    lateral = -f1 * _ALPHA_Y * sign
    return (lateral * e1x - f23 * alpha_x * e2x,
            lateral * e1y - f23 * alpha_x * e2y,
            f23 * alpha_z)


@njit(cache=True, inline='always', error_model='numpy')
def plate_force(nx, ny, nz, vx, vy, vz, depth, area, zeta_si, a4, b4, dyn_lam_rho):
    """Force (N, world axes) on one plate: normal n (unit), velocity v (m/s), depth (m, > 0
    below the surface), area (m^2). dyn_lam_rho = lambda * rho (kg/m^3) of the dynamic term,
    0 to switch it off. Zero for plates above the surface or trailing (n . v <= 0)."""
    n_v = nx * vx + ny * vy + nz * vz
    speed = np.sqrt(vx * vx + vy * vy + vz * vz)
    if depth <= 0.0 or n_v <= 0.0 or speed <= 0.0:
        return 0.0, 0.0, 0.0
    sx, sy, sz = unit_stress(nx, ny, nz, vx / speed, vy / speed, vz / speed, a4, b4)
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
                                 a4, b4, dyn_lam_rho)
        out[j, 0], out[j, 1], out[j, 2] = fx, fy, fz
    return out
