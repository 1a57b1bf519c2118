"""Compiled (numba) form of the RFT force law, for the simulation's inner loop.

The same law as `force_law.plate_forces`, written without atan2/sin/cos: the angles beta and
gamma enter the Li 2013 fit only through cos/sin of beta, 2 beta and gamma, which follow
algebraically from the unit normal and the unit velocity. Only f1 and f23 need transcendental
functions: tanh(y) = (e^2y - 1)/(e^2y + 1) and atanh(x) = log((1 + x)/(1 - x))/2, with an
exponential over its bounded range and a logarithm of a ratio in plain arithmetic, so the plates,
given as a structure-of-arrays table, run through one branch-free loop that the compiler
vectorises. Tests hold this kernel to the numpy reference (1e-9 relative).

Units as in `force_law`: SI arrays, zeta already converted to N/m^3 (`units.zeta_to_si`).
Compiled functions are cached on disk (numba cache=True), so only a cold start compiles.
"""
import math

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

from ..kernel_cache import forget_stale
from . import coefficients as co
from .force_law import HORIZONTAL_NZ, TANGENTIAL
from .law_rows import AREA, DIRECTION, LAW_ROWS, NORMAL, NORMAL_SPEED, SCALE  # (the table's rows)

_TANH_A3 = float(np.tanh(co._F1_A3))
_ATANH_B3 = float(np.arctanh(co._F23_B3))
_A1, _A2, _A3 = co._F1_A1, co._F1_A2, co._F1_A3
_B1, _B2, _B3 = co._F23_B1, co._F23_B2, co._F23_B3
_A00, _A10, _B11, _B01, _BM11 = co.A00, co.A10, co.B11, co.B01, co.BM11
_C11, _C01, _CM11, _D10 = co.C11, co.C01, co.CM11, co.D10
_ALPHA_Y = co.ALPHA_Y


#: Taylor coefficients 1/n! of e^y, n = 0 .. 14.
_EXP = tuple(1.0 / math.factorial(n) for n in range(15))


@njit(cache=True, inline='always')
def _exp_bounded(x):
    """e^x for |x| <= 4.3 (relative error < 4e-15) in plain arithmetic, so that loops using
    it vectorise: a degree-14 Taylor polynomial of e^(x/8) (by Estrin's scheme, whose
    dependency chain is 4 multiply-adds deep instead of Horner's 14), squared three times."""
    y = x * 0.125
    y2 = y * y
    y4 = y2 * y2
    low = ((_EXP[0] + _EXP[1] * y) + (_EXP[2] + _EXP[3] * y) * y2
           + ((_EXP[4] + _EXP[5] * y) + (_EXP[6] + _EXP[7] * y) * y2) * y4)
    high = ((_EXP[8] + _EXP[9] * y) + (_EXP[10] + _EXP[11] * y) * y2
            + ((_EXP[12] + _EXP[13] * y) + _EXP[14] * y2) * y4)
    p = low + high * (y4 * y4)
    p = p * p
    p = p * p
    return p * p



_SQRT2 = float(np.sqrt(2.0))
_LN2 = float(np.log(2.0))


@intrinsic
def _bits(typingctx, value):
    """The IEEE 754 bit pattern of a float64, as an int64 (no conversion)."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))
    return types.int64(types.float64), codegen


@intrinsic
def _from_bits(typingctx, bits):
    """The float64 with the given IEEE 754 bit pattern (inverse of `_bits`)."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())
    return types.float64(types.int64), codegen


#: Coefficients 1/(2i + 1) of atanh(s)/s as a series in s^2, i = 0 .. 11.
_ATANH = tuple(1.0 / (2 * i + 1) for i in range(12))
_MANTISSA = (1 << 52) - 1
_ONE = 1023 << 52  # exponent bits of 1.0


@njit(cache=True, inline='always')
def _log_ratio(numerator, denominator):
    """log(numerator / denominator) for positive normal floats (relative error < 1e-15) in
    plain arithmetic, so that loops using it vectorise, with one division: each argument split
    into 2^e m (m in [1, 2)) from its bits, the ratio of the m made to lie in [1/sqrt 2,
    sqrt 2) by one doubling, then log = e ln 2 + 2 atanh(s), s = (m1 - m2)/(m1 + m2),
    |s| < 0.172, by the odd series to s^23 (Estrin's scheme, as in `_exp_bounded`)."""
    top, bottom = _bits(numerator), _bits(denominator)
    m1 = _from_bits((top & _MANTISSA) | _ONE)
    m2 = _from_bits((bottom & _MANTISSA) | _ONE)
    exponent = (top >> 52) - (bottom >> 52)
    big = m1 >= _SQRT2 * m2
    m2 = m2 * 2.0 if big else m2
    exponent = exponent + 1 if big else exponent
    small = _SQRT2 * m1 < m2
    m1 = m1 * 2.0 if small else m1
    exponent = exponent - 1 if small else exponent
    s = (m1 - m2) / (m1 + m2)
    t = s * s
    t2 = t * t
    t4 = t2 * t2
    p = ((_ATANH[0] + _ATANH[1] * t) + (_ATANH[2] + _ATANH[3] * t) * t2
         + ((_ATANH[4] + _ATANH[5] * t) + (_ATANH[6] + _ATANH[7] * t) * t2) * t4
         + ((_ATANH[8] + _ATANH[9] * t) + (_ATANH[10] + _ATANH[11] * t) * t2) * (t4 * t4))
    return 2.0 * s * p + float(exponent) * _LN2


@njit(cache=True, error_model='numpy', fastmath={'contract'})
def leading_forces(count, table, inv_a4, inv_b4, dyn_lam_rho, fx, fy, fz):
    """RFT forces (N, world axes) on the first `count` plates of a plate table (rows above:
    NORMAL ... DIRECTION), written to fx, fy, fz. inv_a4, inv_b4: reciprocal normalisers;
    dyn_lam_rho = lambda * rho (kg/m^3) of the dynamic term, 0 for none. A plate with SCALE
    and AREA 0 feels exactly zero. One branch-free loop, which the compiler vectorises, with
    multiply-adds fused (fastmath 'contract' only: no reassociation, no approximations).
    """
    for j in range(count):
        nx, ny, nz = table[NORMAL, j], table[NORMAL + 1, j], table[NORMAL + 2, j]
        ux, uy, uz = table[DIRECTION, j], table[DIRECTION + 1, j], table[DIRECTION + 2, j]
        # e2: horizontal direction of the normal, or of the velocity for near-horizontal
        # plates; the other one where that vanishes, +x where both do.
        flat = abs(nz) >= HORIZONTAL_NZ
        hx = ux if flat else nx
        hy = uy if flat else ny
        gx = nx if flat else ux
        gy = ny if flat else uy
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
        u_e1 = ux * e2y - uy * e2x
        u_e2 = ux * e2x + uy * e2y  # = v23 . e2
        vt = min(abs(u_e1), 1.0)
        vn = np.sqrt(u_e2 * u_e2 + uz * uz)
        # beta = atan2(nz, n.e2) + pi/2, so cos(2 beta) = (nz^2 - n.e2^2) / rho^2 and
        # sin(2 beta) = -2 n.e2 nz / rho^2 with rho^2 = nz^2 + n.e2^2, which is 1 for a plate
        # that is not flat.
        n_e2 = nx * e2x + ny * e2y
        inv_rho2 = 1.0 / (nz * nz + n_e2 * n_e2) if flat else 1.0
        cos2b = (nz * nz - n_e2 * n_e2) * inv_rho2
        sin2b = -2.0 * n_e2 * nz * inv_rho2
        # gamma = -atan2(v23_z, v23.e2).
        moving = vn > 0.0
        inv_vn = 1.0 / (vn if moving else 1.0)
        cosg = u_e2 * inv_vn if moving else 1.0
        sing = -uz * inv_vn if moving else 0.0
        alpha_z = (_A00 + _A10 * cos2b + _B11 * (sin2b * cosg + cos2b * sing) + _B01 * sing
                   + _BM11 * (sing * cos2b - cosg * sin2b))
        alpha_x = (_C11 * (cos2b * cosg - sin2b * sing) + _C01 * cosg
                   + _CM11 * (cosg * cos2b + sing * sin2b) + _D10 * sin2b)
        growth = _exp_bounded(2.0 * (_A2 * vt - _A3))  # tanh = (e^2y - 1) / (e^2y + 1)
        f1 = _A1 * ((growth - 1.0) / (growth + 1.0) + _TANH_A3) * inv_a4
        # atanh(x) = log((1 + x)/(1 - x)) / 2 with (1 + x)/(1 - x) in [0.013, 4.6]
        x = _B2 * min(vn, 1.0) - _B3
        f23 = _B1 * (0.5 * _log_ratio(1.0 + x, 1.0 - x) + _ATANH_B3) * inv_b4
        sign = 1.0 if u_e1 > 0.0 else (-1.0 if u_e1 < 0.0 else 0.0)
        lateral = -f1 * _ALPHA_Y * sign  # along e1
        along = f23 * alpha_x
        scale = table[SCALE, j]
        dyn = dyn_lam_rho * table[NORMAL_SPEED, j] * table[NORMAL_SPEED, j] * table[AREA, j]
        fx[j] = scale * (lateral * e2y - along * e2x) - dyn * nx
        fy[j] = scale * (-lateral * e2x - along * e2y) - dyn * ny
        fz[j] = scale * f23 * alpha_z - dyn * nz


@njit(cache=True, error_model='numpy')
def plate_forces_compiled(positions, normals, areas, velocities, zeta_si, surface_height,
                          a4, b4, dyn_lam_rho):
    """Compiled `force_law.plate_forces`: arrays as there (SI; zeta_si in N/m^3). Returns
    (N, 3) forces, N. Plates above the surface or not leading (n . v <= TANGENTIAL |v|) feel
    zero."""
    n = areas.shape[0]
    table = np.zeros((LAW_ROWS, n))
    for j in range(n):
        depth = surface_height - positions[j, 2]
        vx, vy, vz = velocities[j, 0], velocities[j, 1], velocities[j, 2]
        n_v = normals[j, 0] * vx + normals[j, 1] * vy + normals[j, 2] * vz
        speed = np.sqrt(vx * vx + vy * vy + vz * vz)
        feels = depth > 0.0 and n_v > TANGENTIAL * speed and speed > 0.0
        inv = 1.0 / speed if speed > 0.0 else 0.0
        for a in range(3):
            table[NORMAL + a, j] = normals[j, a]
            table[DIRECTION + a, j] = velocities[j, a] * inv
        table[NORMAL_SPEED, j] = n_v
        table[SCALE, j] = zeta_si * depth * areas[j] if feels else 0.0
        table[AREA, j] = areas[j] if feels else 0.0
    forces = np.empty((3, n))
    leading_forces(n, table, 1.0 / a4, 1.0 / b4, dyn_lam_rho, forces[0], forces[1], forces[2])
    return forces.T.copy()


forget_stale(globals())  # (kernel_cache: drops kernels compiled from older sources)
