"""Compiled kernels that turn MuJoCo state into sand wrenches (no Python loops per plate).

Conventions: MuJoCo arrays are passed as the views mjData/mjModel expose (world frame,
z up, SI). A "sand body" is a body a scene names as touching sand; its plates are stored in
its body frame (`xpos`/`xmat`), grouped into spatial clusters of a few dozen plates with a
bounding sphere each, so plates above the sand are skipped a cluster at a time. A "slot" is a
sand body with at least one plate in the sand this step; slots are numbered 0..S-1 in the
order bodies are visited. Body twists and wrenches are 6-vectors [linear (3); angular (3)] at
the body's centre of mass (`xipos`), world axes: the convention of mjData.xfrc_applied.

Low-velocity treatment (`implicit_wrenches`): RFT is rate independent, so its force on a
plate jumps when the direction of motion does, and explicit integration makes a loaded body
chatter or bounce out of the sand. The default scheme treats the law implicitly, like
implicit Coulomb friction. For each plate, let G be the RFT force for its current direction of
motion d and speed |v|, w its velocity at the end of the step, w_perp the part of w across d,
a = d.w / v_reg with v_reg a small regularisation speed, and c its across damper
(`across_damper`). Over the step the plate feels
    F = min(a, 1) G - c w_perp    while it leads (a >= 0),     F = 0    once it trails (a < 0).
While it keeps moving along d (a >= 1) the along part is exactly RFT's G; a plate coming to
rest (0 <= a < 1) feels a G, so the sand can stop it within a step but never push it back
past rest. The across damper c = |G| / max(2 |v|, v_reg) x min(1, turn_speed / max(|v|, v_reg))
is the first-order turn of a drag-like force towards the direction of motion at mid-step,
stiff for a plate at rest (which the sand then holds across d as well), and fading once the
plate moves faster than its sand could change within one step (turn_speed: dt x the slot's
summed |G| x its inverse effective mass), where the explicit direction is the better one.
The law is continuous at a = 1, so the implicit solve settles in one or two passes; a plate
that would return to a set it already had in the step is frozen (see `implicit_wrenches`).
A loaded body at rest creeps at most ~v_reg * load / capacity.
"""
import numpy as np
from numba import njit

from ..rft.kernel import stage_leading, staged_forces

MOVING, RESTING, OFF, FROZEN = 1, 0, 2, 3  # a >= 1, 0 <= a < 1, a < 0; anti-cycling

#: Solves per step at most (the active set settles in one or two almost always).
MAX_ITERATIONS = 16


def cluster_plates(centroids, size=32):
    """Order plates into spatial clusters of at most `size` by recursive halving along the
    widest axis. Returns (order, cluster_start): plates order[cluster_start[c]:
    cluster_start[c+1]] form cluster c."""
    order, starts = [], [0]
    pending = [np.arange(len(centroids))]
    while pending:
        group = pending.pop()
        if len(group) <= size:
            order.extend(group)
            starts.append(len(order))
            continue
        points = centroids[group]
        axis = np.argmax(np.ptp(points, axis=0))
        ranked = group[np.argsort(points[:, axis], kind='stable')]
        half = len(ranked) // 2
        pending.extend([ranked[half:], ranked[:half]])
    return np.array(order, dtype=np.int64), np.array(starts, dtype=np.int64)


@njit(cache=True, error_model='numpy')
def gather_plates(body_ids, radii, body_cluster_start, cluster_plate_start, cluster_center,
                  cluster_radius, local_pos, local_normal, areas,
                  xpos, xmat, xipos, cvel, subtree_com, body_rootid,
                  surface_height, zeta_si, inv_a4, inv_b4, dyn_lam_rho, include_trailing,
                  out_plate, out_slot, out_lever, out_force, out_dir, out_speed, slot_body,
                  soa, lead_at, lead_force, law_scratch):
    """Find the plates in the sand and their RFT force for the current direction of motion.

    Bodies whose bounding sphere (radius `radii`, about the body origin), and then clusters
    whose bounding sphere, lies above the surface are skipped without touching their plates.
    For every plate below the surface that leads (n . v > 0), or for every plate below the
    surface when `include_trailing`, writes at index k: plate index, slot, lever arm from the
    body's COM (m, world), RFT force (N, world; inv_a4, inv_b4 are the reciprocal
    normalisers), unit direction of motion and speed (m/s).
    Returns (plates written, of those leading, slots S); slot_body[s] = sand-body index.
    """
    k = 0
    leading_count = 0
    slots = 0
    for i in range(body_ids.shape[0]):
        b = body_ids[i]
        if xpos[b, 2] - radii[i] >= surface_height:
            continue
        first = k
        root = body_rootid[b]
        wx, wy, wz = cvel[b, 0], cvel[b, 1], cvel[b, 2]
        for c in range(body_cluster_start[i], body_cluster_start[i + 1]):
            cz = (xpos[b, 2] + xmat[b, 6] * cluster_center[c, 0]
                  + xmat[b, 7] * cluster_center[c, 1] + xmat[b, 8] * cluster_center[c, 2])
            if cz - cluster_radius[c] >= surface_height:
                continue
            for j in range(cluster_plate_start[c], cluster_plate_start[c + 1]):
                lx, ly, lz = local_pos[j, 0], local_pos[j, 1], local_pos[j, 2]
                pz = xpos[b, 2] + xmat[b, 6] * lx + xmat[b, 7] * ly + xmat[b, 8] * lz
                depth = surface_height - pz
                if depth <= 0.0:
                    continue
                px = xpos[b, 0] + xmat[b, 0] * lx + xmat[b, 1] * ly + xmat[b, 2] * lz
                py = xpos[b, 1] + xmat[b, 3] * lx + xmat[b, 4] * ly + xmat[b, 5] * lz
                mx, my, mz = local_normal[j, 0], local_normal[j, 1], local_normal[j, 2]
                nx = xmat[b, 0] * mx + xmat[b, 1] * my + xmat[b, 2] * mz
                ny = xmat[b, 3] * mx + xmat[b, 4] * my + xmat[b, 5] * mz
                nz = xmat[b, 6] * mx + xmat[b, 7] * my + xmat[b, 8] * mz
                # plate velocity from the com-based twist cvel = [omega; v at the root's com]
                rx = px - subtree_com[root, 0]
                ry = py - subtree_com[root, 1]
                rz = pz - subtree_com[root, 2]
                vx = cvel[b, 3] + wy * rz - wz * ry
                vy = cvel[b, 4] + wz * rx - wx * rz
                vz = cvel[b, 5] + wx * ry - wy * rx
                n_v = nx * vx + ny * vy + nz * vz
                leading = n_v > 0.0
                if not (leading or include_trailing):
                    continue
                speed = np.sqrt(vx * vx + vy * vy + vz * vz)
                inv = 1.0 / speed if speed > 0.0 else 0.0
                if leading:  # inputs of the law, evaluated for all plates at once below
                    stage_leading(soa, leading_count, nx, ny, nz, vx * inv, vy * inv,
                                  vz * inv, n_v, zeta_si * depth * areas[j], areas[j])
                    lead_at[leading_count] = k
                    leading_count += 1
                out_force[k, 0], out_force[k, 1], out_force[k, 2] = 0.0, 0.0, 0.0
                out_plate[k] = j
                out_slot[k] = slots
                out_lever[k, 0] = px - xipos[b, 0]
                out_lever[k, 1] = py - xipos[b, 1]
                out_lever[k, 2] = pz - xipos[b, 2]
                out_dir[k, 0], out_dir[k, 1], out_dir[k, 2] = vx * inv, vy * inv, vz * inv
                out_speed[k] = speed
                k += 1
        if k > first:
            slot_body[slots] = i
            slots += 1
    staged_forces(leading_count, soa, lead_at, inv_a4, inv_b4, dyn_lam_rho, lead_force,
                  law_scratch, out_force)
    return k, leading_count, slots


@njit(cache=True, error_model='numpy')
def prepare_solve(slots, slot_body, body_ids, xipos, subtree_com, cdof, body_rootid,
                  body_dofnum, body_dofadr, body_parentid, dof_parentid, qfrc_passive,
                  qfrc_actuator, qfrc_applied, qfrc_bias, rows):
    """Right-hand sides of the implicit solve: rows 6s..6s+5 of `rows` ((6S+1) x nv) become
    d[v_com; omega]/d qvel of each slot's body (the linear part at the body's centre of mass,
    world axes, as mujoco.mj_jac at xipos), and row 6S the generalised force without sand,
    tau_free = passive + actuator + applied - bias (N or N m per dof)."""
    rows[:6 * slots + 1, :] = 0.0
    for s in range(slots):
        b = body_ids[slot_body[s]]
        root = body_rootid[b]
        ox = xipos[b, 0] - subtree_com[root, 0]
        oy = xipos[b, 1] - subtree_com[root, 1]
        oz = xipos[b, 2] - subtree_com[root, 2]
        owner = b
        while owner > 0 and body_dofnum[owner] == 0:
            owner = body_parentid[owner]
        if owner == 0:
            continue
        i = body_dofadr[owner] + body_dofnum[owner] - 1
        while i >= 0:
            ax, ay, az = cdof[i, 0], cdof[i, 1], cdof[i, 2]
            rows[6 * s + 0, i] = cdof[i, 3] + ay * oz - az * oy
            rows[6 * s + 1, i] = cdof[i, 4] + az * ox - ax * oz
            rows[6 * s + 2, i] = cdof[i, 5] + ax * oy - ay * ox
            rows[6 * s + 3, i] = ax
            rows[6 * s + 4, i] = ay
            rows[6 * s + 5, i] = az
            i = dof_parentid[i]
    for i in range(qfrc_bias.shape[0]):
        rows[6 * slots, i] = qfrc_passive[i] + qfrc_actuator[i] + qfrc_applied[i] - qfrc_bias[i]


_TRN_JOINT = 0     # mjtTrn.mjTRN_JOINT
_AFFINE = 1        # mjtGain.mjGAIN_AFFINE == mjtBias.mjBIAS_AFFINE
_HINGE_OR_SLIDE = (2, 3)  # mjtJoint.mjJNT_SLIDE, mjJNT_HINGE


@njit(cache=True, error_model='numpy')
def implicit_damping(damper, actuators, dof_damping, trntype, trnid, gear, jnt_type,
                     jnt_dofadr, dyntype, gaintype, gainprm, biastype, biasprm, forcelimited,
                     forcerange, ctrl, act, actadr, actuator_force, out):
    """The velocity damping D (diagonal, per dof; N s/m or N m s/rad) that MuJoCo's step
    integrates implicitly, solving (M + dt D) qacc = force: joint damping when `damper`, and
    when `actuators` (implicit/implicitfast integrators) the velocity gains of actuators
    driving a hinge or slide directly (zero while the actuator force is clamped)."""
    for i in range(out.shape[0]):
        out[i] = dof_damping[i] if damper else 0.0
    if not actuators:
        return
    for a in range(trntype.shape[0]):
        joint = trnid[a, 0]
        if trntype[a] != _TRN_JOINT or not (jnt_type[joint] == 2 or jnt_type[joint] == 3):
            continue
        if forcelimited[a] and (actuator_force[a] <= forcerange[a, 0]
                                or actuator_force[a] >= forcerange[a, 1]):
            continue
        slope = biasprm[a, 2] if biastype[a] == _AFFINE else 0.0  # d force / d velocity
        if gaintype[a] == _AFFINE:
            slope += gainprm[a, 2] * (act[actadr[a]] if dyntype[a] != 0 else ctrl[a])
        out[jnt_dofadr[joint]] -= gear[a, 0] * gear[a, 0] * slope


@njit(cache=True, error_model='numpy', fastmath=True)
def solve_implicit_mass(mass, damping, timestep, rows, out):
    """out = rows (M + dt D)^-1 (each row solved), M the dense joint-space inertia (nv x nv),
    D the diagonal damping of `implicit_damping`: MuJoCo's own step matrix, so predicted
    end-of-step velocities match what mj_step2 integrates. Cholesky; M + dt D is SPD."""
    n = mass.shape[0]
    factor = mass.copy()
    for i in range(n):
        factor[i, i] += timestep * damping[i]
    for j in range(n):  # lower Cholesky factor in place
        acc = factor[j, j]
        for k in range(j):
            acc -= factor[j, k] * factor[j, k]
        factor[j, j] = np.sqrt(acc)
        for i in range(j + 1, n):
            acc = factor[i, j]
            for k in range(j):
                acc -= factor[i, k] * factor[j, k]
            factor[i, j] = acc / factor[j, j]
    # all right-hand sides at once, their index innermost (contiguous, vectorised)
    count = rows.shape[0]
    work = np.empty((n, count))
    for r in range(count):
        for i in range(n):
            work[i, r] = rows[r, i]
    for i in range(n):  # forward substitution: L y = b
        for k in range(i):
            f = factor[i, k]
            for r in range(count):
                work[i, r] -= f * work[k, r]
        inv = 1.0 / factor[i, i]
        for r in range(count):
            work[i, r] *= inv
    for i in range(n - 1, -1, -1):  # back substitution: L^T x = y
        for k in range(i + 1, n):
            f = factor[k, i]
            for r in range(count):
                work[i, r] -= f * work[k, r]
        inv = 1.0 / factor[i, i]
        for r in range(count):
            work[i, r] *= inv
    for r in range(count):
        for i in range(n):
            out[r, i] = work[i, r]


@njit(cache=True, error_model='numpy')
def scatter_wrenches(slots, slot_body, slot_wrench, body_ids, body_wrenches, xfrc_applied):
    """Slot wrenches -> per-sand-body wrenches (zero for bodies out of the sand) and
    mjData.xfrc_applied rows of the sand bodies."""
    body_wrenches[:, :] = 0.0
    for s in range(slots):
        for a in range(6):
            body_wrenches[slot_body[s], a] = slot_wrench[s, a]
    for i in range(body_ids.shape[0]):
        for a in range(6):
            xfrc_applied[body_ids[i], a] = body_wrenches[i, a]


@njit(cache=True, error_model='numpy', fastmath=True)
def _solve(matrix, rhs):
    """Solve the dense square system matrix x = rhs (Gaussian elimination, partial pivoting).
    Overwrites both arguments; returns x."""
    n = rhs.shape[0]
    for col in range(n):
        pivot = col
        for row in range(col + 1, n):
            if abs(matrix[row, col]) > abs(matrix[pivot, col]):
                pivot = row
        if pivot != col:
            for c in range(n):
                matrix[col, c], matrix[pivot, c] = matrix[pivot, c], matrix[col, c]
            rhs[col], rhs[pivot] = rhs[pivot], rhs[col]
        inv = 1.0 / matrix[col, col]
        for row in range(col + 1, n):
            factor = matrix[row, col] * inv
            if factor != 0.0:
                for c in range(col, n):
                    matrix[row, c] -= factor * matrix[col, c]
                rhs[row] -= factor * rhs[col]
    for row in range(n - 1, -1, -1):
        acc = rhs[row]
        for c in range(row + 1, n):
            acc -= matrix[row, c] * rhs[c]
        rhs[row] = acc / matrix[row, row]
    return rhs


@njit(cache=True, inline='always')
def _wrench_row(lever, vec, out):
    """out = [vec; lever x vec]: the body wrench of a force `vec` at `lever` from the COM (and,
    read as a row, the map from a body twist to a point's velocity along `vec`)."""
    out[0], out[1], out[2] = vec[0], vec[1], vec[2]
    out[3] = lever[1] * vec[2] - lever[2] * vec[1]
    out[4] = lever[2] * vec[0] - lever[0] * vec[2]
    out[5] = lever[0] * vec[1] - lever[1] * vec[0]


@njit(cache=True, inline='always')
def _point_velocity(lever, twist, base):
    """Velocity (3,) of a point at `lever` from the COM for the twist twist[base:base+6]."""
    wx, wy, wz = twist[base + 3], twist[base + 4], twist[base + 5]
    return (twist[base] + wy * lever[2] - wz * lever[1],
            twist[base + 1] + wz * lever[0] - wx * lever[2],
            twist[base + 2] + wx * lever[1] - wy * lever[0])


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
    if state == RESTING:
        return inv_reg
    if state == FROZEN:
        return 1.0 / max(speed, v_reg)
    return 0.0


@njit(cache=True, inline='always', fastmath=True)
def _resting_block(k_rank, iso, out):
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
def implicit_plate_forces(k, out_slot, lever, force, direction, speed, across, states, xi_new,
                          v_reg, out):
    """Per-plate forces (N, world, on the body) that an implicit step applied, from the
    plates' final sets, their across dampers and the end-of-step twists xi_new:
    G - c w_perp if moving, a G - c w_perp if resting (frozen: with |v| in place of v_reg in
    a), 0 if off (module docstring); the terms of the step's wrench."""
    inv_reg = 1.0 / v_reg
    for j in range(k):
        if states[j] == OFF:
            for a in range(3):
                out[j, a] = 0.0
            continue
        vx, vy, vz = _point_velocity(lever[j], xi_new, 6 * out_slot[j])
        d = direction[j]
        along = vx * d[0] + vy * d[1] + vz * d[2]
        factor = 1.0 if states[j] == MOVING else along * _along_factor(
            states[j], speed[j], inv_reg, v_reg)
        px, py, pz = vx - along * d[0], vy - along * d[1], vz - along * d[2]
        out[j, 0] = factor * force[j, 0] - across[j] * px
        out[j, 1] = factor * force[j, 1] - across[j] * py
        out[j, 2] = factor * force[j, 2] - across[j] * pz


@njit(cache=True, error_model='numpy', fastmath=True)
def _accumulate_slot(j0, j1, h, u, arm, coef_along, coef_across, coef_moving, weighted,
                     w_moving, k_rank, k_iso):
    """A slot's accumulators from its plates j0..j1-1 (module layout: h, u (6, K), arm (3, K),
    per-plate set coefficients): w_moving = sum m h, k_rank = sum (a h + c u) u^T and the 10
    moments of c (c, c r, c r r^T). Reductions over 1-d slices, which the compiler vectorises."""
    moving, damper = coef_moving[j0:j1], coef_across[j0:j1]
    along = coef_along[j0:j1]
    for a in range(6):
        h_a, u_a, weighted_a = h[a, j0:j1], u[a, j0:j1], weighted[a, j0:j1]
        acc = 0.0
        for j in range(j1 - j0):
            weighted_a[j] = along[j] * h_a[j] + damper[j] * u_a[j]
            acc += moving[j] * h_a[j]
        w_moving[a] = acc
    for a in range(6):
        weighted_a = weighted[a, j0:j1]
        for b in range(6):
            u_b = u[b, j0:j1]
            acc = 0.0
            for j in range(j1 - j0):
                acc += weighted_a[j] * u_b[j]
            k_rank[a, b] = acc
    arm_x, arm_y, arm_z = arm[0, j0:j1], arm[1, j0:j1], arm[2, j0:j1]
    g = g_x = g_y = g_z = g_xx = g_yy = g_zz = g_xy = g_yz = g_zx = 0.0
    for j in range(j1 - j0):
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
    k_iso[0], k_iso[1], k_iso[2], k_iso[3] = g, g_x, g_y, g_z
    k_iso[4], k_iso[5], k_iso[6] = g_xx, g_yy, g_zz
    k_iso[7], k_iso[8], k_iso[9] = g_xy, g_yz, g_zx


@njit(cache=True, error_model='numpy', fastmath=True)
def implicit_wrenches(k, slots, out_plate, out_slot, lever, force, direction, speed, v_reg,
                      jac, minv_rows, qvel, timestep, step, plate_state, plate_step,
                      states, xi_new, across, wrench):
    """Sand wrenches over the coming step by the implicit law of the module docstring.

    jac: (>= 6S, nv) slot Jacobians. minv_rows: (>= 6S+1, nv) rows Mh^-1 jac_r^T for the 6S
    Jacobian rows, then Mh^-1 tau_free, where tau_free is every generalised force except
    the sand's (passive + actuator + applied - bias) and Mh = M + dt D is the matrix MuJoCo's
    step solves with (`solve_implicit_mass`). With each plate moving (force G), resting
    (linear in v+) or off, the end-of-step joint velocities solve
        (I - dt Mh^-1 J^T K J) qvel+ = qvel_free + dt Mh^-1 J^T W_moving,   xi+ = J qvel+,
    K the plates' linear response, W_moving the moving plates' G; plates then change set
    until the solution is consistent (an active-set iteration; moving and off are
    neighbours of resting only, so a plate passes through resting between them).
    Each plate starts from its set of the previous step if it was in the sand then
    (`plate_state`/`plate_step`, indexed by plate, updated here) and not frozen, otherwise
    as moving when faster than v_reg; so a step usually needs one solve. Writes states[:k],
    across[:k] (across dampers, N s/m), xi_new[:6S] (end-of-step twists) and wrench[:S]
    ([force; torque about COM], N, N m).
    A plate that would return to a set it already had this step is frozen for the rest of
    the step (the law is not monotone where RFT's lift makes G d^T non-symmetric, and plain
    active-set iterations can cycle): its along response becomes the secant
    (d.w / max(|v|, v_reg)) G through its current speed - the resting response for a plate
    at rest, about G for a plate that keeps its speed, less as it slows - linear and
    opposing the plate's motion (RFT's G always opposes d). The wrench is exactly what the
    last solve assumed. Returns the number of solves, negative if some plate was frozen or
    the sets had not settled within MAX_ITERATIONS.

    Each plate enters its slot's accumulators with coefficients set by its set: moving ->
    wrench h = [G; r x G]; resting -> along response h u^T / v_reg (u = [d; r x d]); all but
    off -> across damper -c (I - d d^T), i.e. c u u^T minus c P^T P (kept as the 10 moments
    c, c r, c r r^T). After a solve, only the slots with plates that changed set are summed
    again.
    """
    n6 = 6 * slots
    nv = qvel.shape[0]
    inv_reg = 1.0 / v_reg
    qvel_free = np.empty(nv)
    for i in range(nv):
        qvel_free[i] = qvel[i] + timestep * minv_rows[n6, i]
    # plates come slot by slot: slot s holds plates first[s] .. first[s + 1] - 1
    first = np.zeros(slots + 1, dtype=np.int64)
    for j in range(k):
        first[out_slot[j] + 1] += 1
    for s in range(slots):
        first[s + 1] += first[s]
    # per plate, as structure of arrays (plates innermost, so the loops vectorise):
    # h = [G; r x G], u = [d; r x d], lever arm r, |G|
    h = np.empty((6, k))
    u = np.empty((6, k))
    arm = np.empty((3, k))
    magnitude = np.empty(k)
    h0, h1, h2, h3, h4, h5 = h[0], h[1], h[2], h[3], h[4], h[5]
    u0, u1, u2, u3, u4, u5 = u[0], u[1], u[2], u[3], u[4], u[5]
    arm_x, arm_y, arm_z = arm[0], arm[1], arm[2]
    for j in range(k):
        rx, ry, rz = lever[j, 0], lever[j, 1], lever[j, 2]
        gx, gy, gz = force[j, 0], force[j, 1], force[j, 2]
        dx, dy, dz = direction[j, 0], direction[j, 1], direction[j, 2]
        arm_x[j], arm_y[j], arm_z[j] = rx, ry, rz
        h0[j], h1[j], h2[j] = gx, gy, gz
        h3[j], h4[j], h5[j] = ry * gz - rz * gy, rz * gx - rx * gz, rx * gy - ry * gx
        u0[j], u1[j], u2[j] = dx, dy, dz
        u3[j], u4[j], u5[j] = ry * dz - rz * dy, rz * dx - rx * dz, rx * dy - ry * dx
        magnitude[j] = np.sqrt(gx * gx + gy * gy + gz * gz)
    # Across dampers. Turn speed of a slot: the speed its sand could take out of it in one
    # step, dt x (sum of its plates' |G|) x its translational inverse effective mass
    # (diagonal of J Mh^-1 J^T, averaged).
    for s in range(slots):
        total = magnitude[first[s]:first[s + 1]].sum()
        inverse_mass = 0.0
        for row in range(6 * s, 6 * s + 3):
            for i in range(nv):
                inverse_mass += jac[row, i] * minv_rows[row, i]
        turn_speed = max(total * timestep * inverse_mass / 3.0, v_reg)
        for j in range(first[s], first[s + 1]):
            across[j] = across_damper(magnitude[j], speed[j], v_reg, turn_speed)
    # initial sets and each plate's coefficients for its set: along factor, across damper,
    # moving (0/1)
    visited = np.zeros(k, dtype=np.int8)  # bit per set a plate has been in this step
    coef_along = np.empty(k)
    coef_across = np.empty(k)
    coef_moving = np.empty(k)
    for j in range(k):
        p = out_plate[j]
        previous = plate_state[p]
        warm = plate_step[p] == step - 1 and previous != FROZEN
        state = previous if warm else (MOVING if speed[j] > v_reg else RESTING)
        states[j] = state
        visited[j] = 1 << state
        coef_along[j] = _along_factor(state, speed[j], inv_reg, v_reg)
        coef_across[j] = 0.0 if state == OFF else across[j]
        coef_moving[j] = 1.0 if state == MOVING else 0.0
    w_moving = np.zeros((slots, 6))
    k_rank = np.zeros((slots, 6, 6))
    k_iso = np.zeros((slots, 10))
    weighted = np.empty((6, k))
    dirty = np.ones(slots, dtype=np.bool_)  # slots whose accumulators must be summed again
    solved = np.empty(k, dtype=np.int8)  # sets the last solve used
    wanted = np.empty(k, dtype=np.int8)
    along = np.empty(k)  # plate velocity along d at the end of the step, u . xi+ (m/s)
    # the dofs each slot's Jacobian reaches (its kinematic chain)
    chain = np.empty((slots, nv), dtype=np.int64)
    chain_count = np.zeros(slots, dtype=np.int64)
    for s in range(slots):
        for c in range(nv):
            reaches = False
            for b in range(6):
                reaches = reaches or jac[6 * s + b, c] != 0.0
            if reaches:
                chain[s, chain_count[s]] = c
                chain_count[s] += 1
    block = np.zeros((6, 6))
    system = np.zeros((nv, nv))
    system_t = np.zeros((nv, nv))
    rhs = np.zeros(nv)
    iterations = 0
    frozen = 0  # plates frozen this step
    converged = False
    while iterations < MAX_ITERATIONS and not converged:
        iterations += 1
        for s in range(slots):
            if dirty[s]:
                _accumulate_slot(first[s], first[s + 1], h, u, arm, coef_along, coef_across,
                                 coef_moving, weighted, w_moving[s], k_rank[s], k_iso[s])
                dirty[s] = False
        # (I - dt Mh^-1 J^T K J) qvel+ = qvel_free + dt Mh^-1 J^T W_moving; xi+ = J qvel+.
        # Assembled transposed, column c of the system (a contiguous row of system_t) from
        # the slots whose Jacobian reaches dof c only, so the inner loops run over
        # contiguous rows and skip the dofs outside a slot's kinematic chain.
        for r in range(nv):
            for c in range(nv):
                system_t[r, c] = 1.0 if r == c else 0.0
            rhs[r] = qvel_free[r]
        for s in range(slots):
            _resting_block(k_rank[s], k_iso[s], block)
            for a in range(6):
                minv_row = minv_rows[6 * s + a]
                weight = timestep * w_moving[s, a]
                for r in range(nv):
                    rhs[r] += weight * minv_row[r]
            for q in range(chain_count[s]):
                c = chain[s, q]
                column = system_t[c]
                for a in range(6):
                    coefficient = 0.0
                    for b in range(6):
                        coefficient += block[a, b] * jac[6 * s + b, c]
                    coefficient *= timestep
                    minv_row = minv_rows[6 * s + a]
                    for r in range(nv):
                        column[r] -= coefficient * minv_row[r]
        for r in range(nv):
            for c in range(nv):
                system[r, c] = system_t[c, r]
        solution = _solve(system, rhs)
        for j in range(k):
            solved[j] = states[j]
        for r in range(n6):
            acc = 0.0
            for i in range(nv):
                acc += jac[r, i] * solution[i]
            xi_new[r] = acc
        for s in range(slots):
            x0, x1, x2 = xi_new[6 * s], xi_new[6 * s + 1], xi_new[6 * s + 2]
            x3, x4, x5 = xi_new[6 * s + 3], xi_new[6 * s + 4], xi_new[6 * s + 5]
            j0, j1 = first[s], first[s + 1]
            d0, d1, d2 = u[0, j0:j1], u[1, j0:j1], u[2, j0:j1]
            d3, d4, d5 = u[3, j0:j1], u[4, j0:j1], u[5, j0:j1]
            along_s, wanted_s = along[j0:j1], wanted[j0:j1]
            for j in range(j1 - j0):
                value = (d0[j] * x0 + d1[j] * x1 + d2[j] * x2 + d3[j] * x3 + d4[j] * x4
                         + d5[j] * x5)
                along_s[j] = value
                wanted_s[j] = OFF if value < 0.0 else (MOVING if value >= v_reg else RESTING)
        converged = True
        for j in range(k):
            old = states[j]
            if wanted[j] == old or old == FROZEN:
                continue
            # moving and off are reached from resting only
            new = wanted[j] if (old == RESTING or wanted[j] == RESTING) else RESTING
            if visited[j] & (1 << new):  # back to a set it had: a cycle
                frozen += 1
                new = FROZEN
            states[j] = new
            visited[j] |= 1 << new
            coef_along[j] = _along_factor(new, speed[j], inv_reg, v_reg)
            coef_across[j] = 0.0 if new == OFF else across[j]
            coef_moving[j] = 1.0 if new == MOVING else 0.0
            dirty[out_slot[j]] = True
            converged = False
    # The wrench the last solve assumed: moving plates' G plus every plate's linear response.
    for j in range(k):
        states[j] = solved[j]
    for s in range(slots):
        if dirty[s]:  # back to the coefficients of the last solve
            for j in range(first[s], first[s + 1]):
                coef_along[j] = _along_factor(solved[j], speed[j], inv_reg, v_reg)
                coef_across[j] = 0.0 if solved[j] == OFF else across[j]
                coef_moving[j] = 1.0 if solved[j] == MOVING else 0.0
            _accumulate_slot(first[s], first[s + 1], h, u, arm, coef_along, coef_across,
                             coef_moving, weighted, w_moving[s], k_rank[s], k_iso[s])
        _resting_block(k_rank[s], k_iso[s], block)
        for a in range(6):
            acc = w_moving[s, a]
            for b in range(6):
                acc += block[a, b] * xi_new[6 * s + b]
            wrench[s, a] = acc
    for j in range(k):
        plate_state[out_plate[j]] = states[j]
        plate_step[out_plate[j]] = step
    return iterations if converged and frozen == 0 else -iterations


@njit(cache=True, error_model='numpy')
def smoothed_wrenches(k, slots, out_plate, out_slot, lever, force, alpha, step,
                      ema_force, ema_step, applied, wrench):
    """Explicit RFT with the paper's per-plate exponential moving average (RFT-SiM eq. 6):
    F_s = alpha F + (1 - alpha) F_s(previous step) for a plate that was in the sand on the
    previous step, F_s = F otherwise (its history is dropped when it leaves the sand).
    alpha = 1 applies the raw RFT force. Writes applied[:k] = F_s (N, world, on the body).
    ema_force (N, 3), ema_step (N,) hold each plate's last smoothed force and the step index
    it was computed at. Writes wrench[:S] as in `implicit_wrenches`.
    """
    h = np.zeros(6)
    wrench[:slots, :] = 0.0
    for j in range(k):
        p = out_plate[j]
        for a in range(3):
            applied[j, a] = force[j, a]
            if ema_step[p] == step - 1:
                applied[j, a] = alpha * force[j, a] + (1.0 - alpha) * ema_force[p, a]
            ema_force[p, a] = applied[j, a]
        ema_step[p] = step
        _wrench_row(lever[j], applied[j], h)
        for a in range(6):
            wrench[out_slot[j], a] += h[a]
