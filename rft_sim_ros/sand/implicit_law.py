"""The sand's implicit low-velocity law, per plate and per slot, compiled.

RFT is rate independent, so its force on a plate jumps when the direction of motion does,
and explicit integration makes a loaded body chatter or bounce out of the sand. The default
scheme treats the law implicitly, like implicit Coulomb friction. For each plate, let G be
the RFT force for its current direction of motion d and speed |v|, w its velocity at the end
of the step, w_perp the part of w across d, a = d.w / v_reg with v_reg a small
regularisation speed, and c its across damper (`across_damper`). Over the step the plate
feels
    F = min(a, 1) G - c w_perp    while it leads (a >= 0),     F = 0    once it trails (a < 0).
While it keeps moving along d (a >= 1) the along part is exactly RFT's G; a plate coming to
rest (0 <= a < 1) feels a G, so the sand can stop it within a step but never push it back
past rest. The across damper c = |G| / max(2 |v|, v_reg) x min(1, turn_speed / max(|v|, v_reg))
is the first-order turn of a drag-like force towards the direction of motion at mid-step,
stiff for a plate at rest (which the sand then holds across d as well), and fading once the
plate moves faster than its sand could change within one step (turn_speed: dt x the slot's
summed |G| x its inverse effective mass), where the explicit direction is the better one.
The law is continuous at a = 1, so the implicit solve (`implicit_solve`) settles in one or
two passes; a plate that would return to a set it already had in the step is frozen
(`active_set`). A loaded body at rest creeps at most ~v_reg * load / capacity.

Conventions: a plate is in one set, MOVING (a >= 1), RESTING (0 <= a < 1), OFF (a < 0) or
FROZEN; plates are columns of the gathered table (`layout`), slot by slot. A slot's
linearised response is kept as accumulators (`accumulate_slot`) and its twist response, a
6x6 block on twists [linear; angular] at the body's centre of mass, world axes
(`resting_block`). N, m/s, N s/m.
"""
from numba import njit

from ..kernel_cache import forget_stale
from ..rft.law_rows import DIRECTION
from .active_set import FROZEN, STATE
from .table_readers import float_matrix, float_vector, int8_matrix, int_vector
from .layout import ACROSS, GATHERED, IMPLICIT, LEVER, REST_SPEED, SPEED

MOVING, RESTING, OFF = 1, 0, 2  # a >= 1, 0 <= a < 1, a < 0 (and FROZEN: anti-cycling)


@njit(cache=True, inline='always')
def _point_velocity(lever, j, twist, base):
    """Velocity (3,) of plate j at lever[:, j] from the COM for the twist twist[base:base+6]."""
    wx, wy, wz = twist[base + 3], twist[base + 4], twist[base + 5]
    return (twist[base] + wy * lever[2, j] - wz * lever[1, j],
            twist[base + 1] + wz * lever[0, j] - wx * lever[2, j],
            twist[base + 2] + wx * lever[1, j] - wy * lever[0, j])


@njit(cache=True, inline='always')
def across_damper(magnitude, speed, v_reg, turn_speed):
    """Across-d damper c of a plate (N s/m) with RFT force magnitude |G| (N) and speed |v|:
    |G| / max(2 |v|, v_reg) - stiff at rest, then the first-order turn of a drag-like force
    to the direction of motion at mid-step while the step can turn the plate's motion -
    fading as turn_speed / |v| once the plate moves faster than its sand could change within
    a step (turn_speed, m/s), where the explicit direction is the better one."""
    return magnitude / max(2.0 * speed, v_reg) * min(1.0, turn_speed / max(speed, v_reg))


@njit(cache=True, inline='always')
def _along_factor(state, speed, inv_reg, v_reg):
    """Coefficient of a plate's linear along response G (d.w) x factor, 1/(m/s), by set:
    1/v_reg resting, 1/max(|v|, v_reg) frozen (a secant through its current speed), else 0."""
    secant = 1.0 / max(speed, v_reg)  # selects, no branches: the callers' loops vectorise
    return inv_reg if state == RESTING else (secant if state == FROZEN else 0.0)


@njit(cache=True, inline='always')
def set_coefficients(j, state, speed, across, inv_reg, v_reg, coef_along, coef_across,
                      coef_moving):
    """Plate j's accumulator coefficients for its set: along factor (`_along_factor`),
    across damper (0 once off) and moving (1 or 0)."""
    coef_along[j] = _along_factor(state, speed, inv_reg, v_reg)
    coef_across[j] = 0.0 if state == OFF else across
    coef_moving[j] = 1.0 if state == MOVING else 0.0


@njit(cache=True, inline='always', fastmath=True)
def resting_block(k_rank, iso, out):
    """Slot twist response of its plates' linear parts: rank part minus sum c P^T P,
    P = [I, -[r]x] (plate velocity from the twist)."""
    g, sx, sy, sz = iso[0], iso[1], iso[2], iso[3]
    xx, yy, zz, xy, yz, zx = iso[4], iso[5], iso[6], iso[7], iso[8], iso[9]
    for a in range(6):
        for b in range(6):
            out[a, b] = k_rank[a, b]
    for a in range(3):
        out[a, a] -= g
    # -[S1]x in the (force, omega) block, +[S1]x in the (torque, velocity) block
    out[0, 4] -= sz
    out[0, 5] += sy
    out[1, 3] += sz
    out[1, 5] -= sx
    out[2, 3] -= sy
    out[2, 4] += sx
    out[4, 0] -= sz
    out[5, 0] += sy
    out[3, 1] += sz
    out[5, 1] -= sx
    out[3, 2] -= sy
    out[4, 2] += sx
    # -(tr(S2) I - S2) in the (torque, omega) block
    trace = xx + yy + zz
    out[3, 3] -= trace - xx
    out[4, 4] -= trace - yy
    out[5, 5] -= trace - zz
    out[3, 4] += xy
    out[4, 3] += xy
    out[4, 5] += yz
    out[5, 4] += yz
    out[3, 5] += zx
    out[5, 3] += zx

@njit(cache=True, error_model='numpy')
def implicit_plate_forces(arrays):
    """`plate_forces` of the plates the last implicit step gathered (counter GATHERED), of
    the engine's implicit array table (`layout.ImplicitArrays`; settings REST_SPEED, m/s),
    into its `applied` (3, n; N, world axes, on the body). A table kernel
    (`kernel_names.TABLE_KERNELS`)."""
    ids = IMPLICIT
    plate_forces(int_vector(arrays, ids.counters)[GATHERED], int_vector(arrays, ids.out_slot),
                 float_matrix(arrays, ids.table), float_matrix(arrays, ids.force),
                 float_matrix(arrays, ids.work), int8_matrix(arrays, ids.flags),
                 float_vector(arrays, ids.xi_new), float_vector(arrays, ids.settings)[REST_SPEED],
                 float_matrix(arrays, ids.applied))


@njit(cache=True, inline='always', error_model='numpy')
def plate_forces(k, out_slot, table, force, work, flags, xi_new, v_reg, out):
    """Per-plate forces (N, world, on the body; out[:, :k]) that an implicit step applied,
    from the plates' final sets and across dampers (rows STATE of `flags`, ACROSS of `work`,
    left by `implicit_solve._implicit_step`) and the end-of-step twists xi_new: G - c w_perp
    if moving, a G - c w_perp if resting (frozen: with |v| in place of v_reg in a), 0 if off (module
    docstring); the terms of the step's wrench."""
    inv_reg = 1.0 / v_reg
    lever = table[LEVER:LEVER + 3]
    for j in range(k):
        state = flags[STATE, j]
        if state == OFF:
            for a in range(3):
                out[a, j] = 0.0
            continue
        vx, vy, vz = _point_velocity(lever, j, xi_new, 6 * out_slot[j])
        dx, dy, dz = table[DIRECTION, j], table[DIRECTION + 1, j], table[DIRECTION + 2, j]
        along = vx * dx + vy * dy + vz * dz
        factor = 1.0 if state == MOVING else along * _along_factor(
            state, table[SPEED, j], inv_reg, v_reg)
        across = work[ACROSS, j]
        out[0, j] = factor * force[0, j] - across * (vx - along * dx)
        out[1, j] = factor * force[1, j] - across * (vy - along * dy)
        out[2, j] = factor * force[2, j] - across * (vz - along * dz)


@njit(cache=True, inline='always', fastmath=True)
def _rank_rows(a, j0, j1, h, u, along, damper, out):
    """Rows a, a+1, a+2 (a = 0 or 3) of sum (along h + damper u) u^T over plates j0..j1-1
    into out (6, 6): one pass with 18 accumulators, few enough to stay in vector registers,
    over slices indexed from 0 (no negative-index checks), so that it vectorises."""
    h_a, h_b, h_c = h[a, j0:j1], h[a + 1, j0:j1], h[a + 2, j0:j1]
    u0, u1, u2 = u[0, j0:j1], u[1, j0:j1], u[2, j0:j1]
    u3, u4, u5 = u[3, j0:j1], u[4, j0:j1], u[5, j0:j1]
    along, damper = along[j0:j1], damper[j0:j1]
    a0 = a1 = a2 = a3 = a4 = a5 = b0 = b1 = b2 = b3 = b4 = b5 = 0.0
    c0 = c1 = c2 = c3 = c4 = c5 = 0.0
    for j in range(j1 - j0):
        v0, v1, v2, v3, v4, v5 = u0[j], u1[j], u2[j], u3[j], u4[j], u5[j]
        first = a == 0
        w_a = along[j] * h_a[j] + damper[j] * (v0 if first else v3)
        w_b = along[j] * h_b[j] + damper[j] * (v1 if first else v4)
        w_c = along[j] * h_c[j] + damper[j] * (v2 if first else v5)
        a0 += w_a * v0
        a1 += w_a * v1
        a2 += w_a * v2
        a3 += w_a * v3
        a4 += w_a * v4
        a5 += w_a * v5
        b0 += w_b * v0
        b1 += w_b * v1
        b2 += w_b * v2
        b3 += w_b * v3
        b4 += w_b * v4
        b5 += w_b * v5
        c0 += w_c * v0
        c1 += w_c * v1
        c2 += w_c * v2
        c3 += w_c * v3
        c4 += w_c * v4
        c5 += w_c * v5
    out[a, 0], out[a, 1], out[a, 2], out[a, 3], out[a, 4], out[a, 5] = a0, a1, a2, a3, a4, a5
    out[a + 1, 0], out[a + 1, 1], out[a + 1, 2] = b0, b1, b2
    out[a + 1, 3], out[a + 1, 4], out[a + 1, 5] = b3, b4, b5
    out[a + 2, 0], out[a + 2, 1], out[a + 2, 2] = c0, c1, c2
    out[a + 2, 3], out[a + 2, 4], out[a + 2, 5] = c3, c4, c5


@njit(cache=True, error_model='numpy', fastmath=True)
def accumulate_slot(j0, j1, h, u, arm, coef_along, coef_across, coef_moving, w_moving,
                     k_rank, k_iso):
    """A slot's accumulators from its plates j0..j1-1 (h, u (6, K), arm (3, K), per-plate set
    coefficients, as in `implicit_solve._implicit_step`): w_moving = sum m h,
    k_rank = sum (a h + c u) u^T and the 10 moments of c (c, c r, c r r^T). Each pass keeps
    its sums in registers."""
    _rank_rows(0, j0, j1, h, u, coef_along, coef_across, k_rank)
    _rank_rows(3, j0, j1, h, u, coef_along, coef_across, k_rank)
    h0, h1, h2 = h[0, j0:j1], h[1, j0:j1], h[2, j0:j1]
    h3, h4, h5 = h[3, j0:j1], h[4, j0:j1], h[5, j0:j1]
    arm_x, arm_y, arm_z = arm[0, j0:j1], arm[1, j0:j1], arm[2, j0:j1]
    moving, damper = coef_moving[j0:j1], coef_across[j0:j1]
    m0 = m1 = m2 = m3 = m4 = m5 = 0.0
    g = g_x = g_y = g_z = g_xx = g_yy = g_zz = g_xy = g_yz = g_zx = 0.0
    for j in range(j1 - j0):
        m = moving[j]
        m0 += m * h0[j]
        m1 += m * h1[j]
        m2 += m * h2[j]
        m3 += m * h3[j]
        m4 += m * h4[j]
        m5 += m * h5[j]
        c = damper[j]
        rx, ry, rz = arm_x[j], arm_y[j], arm_z[j]
        g += c
        g_x += c * rx
        g_y += c * ry
        g_z += c * rz
        g_xx += c * rx * rx
        g_yy += c * ry * ry
        g_zz += c * rz * rz
        g_xy += c * rx * ry
        g_yz += c * ry * rz
        g_zx += c * rz * rx
    w_moving[0], w_moving[1], w_moving[2] = m0, m1, m2
    w_moving[3], w_moving[4], w_moving[5] = m3, m4, m5
    k_iso[0], k_iso[1], k_iso[2], k_iso[3] = g, g_x, g_y, g_z
    k_iso[4], k_iso[5], k_iso[6] = g_xx, g_yy, g_zz
    k_iso[7], k_iso[8], k_iso[9] = g_xy, g_yz, g_zx


forget_stale(globals())  # (kernel_cache: drops kernels compiled from older sources)
