"""Compiled kernels that turn MuJoCo state into sand wrenches (no Python loops per plate).

Conventions: MuJoCo arrays are passed as the views mjData/mjModel expose (world frame,
z up, SI). A "sand body" is a body a scene names as touching sand; its plates are stored in
its body frame (`xpos`/`xmat`). A "slot" is a sand body that has at least one plate in the
sand this step; slots are numbered 0..S-1 in the order bodies are visited. Body twists and
wrenches are 6-vectors [linear (3); angular (3)] at the body's centre of mass (`xipos`),
world axes: the convention of mjData.xfrc_applied.

Low-velocity treatment (see `implicit_wrenches`): RFT is rate independent, so its force on a
plate jumps when the direction of motion does, and explicit integration makes a loaded body
chatter or bounce out of the sand. The default scheme treats the law implicitly, like
implicit Coulomb friction. For each plate, let G be the RFT force for its current direction of
motion d, v+ its velocity at the end of the step, v_reg a small regularisation speed and
a = d.v+ / v_reg, b = |v+ - (d.v+) d| / v_reg. Over the step the plate feels
    G                                    if it keeps moving (a >= 1, or b > 1 and a >= 0),
    (a G - b |G| e_perp)                 if it comes to rest (0 <= a <= 1, b <= 1),
    0                                    if it would move back (a < 0: it no longer leads),
with e_perp the unit direction of v+ across d. So while a plate moves the force is exactly
RFT's; the sand can stop a plate within a step, and holds a plate at rest against motion in
any direction with a stiff damper of the plate's RFT magnitude, but never pushes it back past
rest. A loaded body at rest creeps at most at ~v_reg * load / capacity.
"""
import numpy as np
from numba import njit

from ..rft.kernel import plate_force

MOVING, RESTING, OFF = 1, 0, 2


@njit(cache=True, error_model='numpy')
def gather_plates(body_ids, radii, plate_start, local_pos, local_normal, areas,
                  xpos, xmat, xipos, cvel, subtree_com, body_rootid,
                  surface_height, zeta_si, a4, b4, dyn_lam_rho, include_trailing,
                  out_plate, out_slot, out_lever, out_force, out_dir, out_speed, slot_body):
    """Find the plates in the sand and their RFT force for the current direction of motion.

    Bodies whose bounding sphere (radius `radii`, about the body origin) is above the
    surface are skipped without touching their plates. For every plate below the surface
    that leads (n . v > 0), or for every plate below the surface when `include_trailing`,
    writes at index k: global plate index, slot, lever arm from the body's COM (m, world),
    RFT force (N, world), unit direction of motion and speed (m/s).
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
        for j in range(plate_start[i], plate_start[i + 1]):
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
            # velocity of the plate point from the com-based twist cvel = [omega; v(root com)]
            rx = px - subtree_com[root, 0]
            ry = py - subtree_com[root, 1]
            rz = pz - subtree_com[root, 2]
            vx = cvel[b, 3] + wy * rz - wz * ry
            vy = cvel[b, 4] + wz * rx - wx * rz
            vz = cvel[b, 5] + wx * ry - wy * rx
            speed = np.sqrt(vx * vx + vy * vy + vz * vz)
            leading = speed > 0.0 and nx * vx + ny * vy + nz * vz > 0.0
            if not (leading or include_trailing):
                continue
            leading_count += leading
            fx, fy, fz = plate_force(nx, ny, nz, vx, vy, vz, depth, areas[j], zeta_si,
                                     a4, b4, dyn_lam_rho)
            out_plate[k] = j
            out_slot[k] = slots
            out_lever[k, 0] = px - xipos[b, 0]
            out_lever[k, 1] = py - xipos[b, 1]
            out_lever[k, 2] = pz - xipos[b, 2]
            out_force[k, 0], out_force[k, 1], out_force[k, 2] = fx, fy, fz
            inv = 1.0 / speed if speed > 0.0 else 0.0
            out_dir[k, 0], out_dir[k, 1], out_dir[k, 2] = vx * inv, vy * inv, vz * inv
            out_speed[k] = speed
            k += 1
        if k > first:
            slot_body[slots] = i
            slots += 1
    return k, leading_count, slots


@njit(cache=True, error_model='numpy')
def slot_jacobians(slots, slot_body, body_ids, xipos, subtree_com, cdof, body_rootid,
                   body_dofnum, body_dofadr, body_parentid, dof_parentid, jac):
    """Rows 6s..6s+5 of `jac` (S*6 x nv): d[v_com; omega]/d qvel of each slot's body, the
    linear part at the body's centre of mass, world axes (as mujoco.mj_jac at xipos)."""
    jac[:6 * slots, :] = 0.0
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
            jac[6 * s + 0, i] = cdof[i, 3] + ay * oz - az * oy
            jac[6 * s + 1, i] = cdof[i, 4] + az * ox - ax * oz
            jac[6 * s + 2, i] = cdof[i, 5] + ax * oy - ay * ox
            jac[6 * s + 3, i] = ax
            jac[6 * s + 4, i] = ay
            jac[6 * s + 5, i] = az
            i = dof_parentid[i]


@njit(cache=True, error_model='numpy')
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


@njit(cache=True, error_model='numpy')
def implicit_wrenches(k, slots, out_slot, lever, force, direction, speed, v_reg,
                      jac, minv_rows, qvel, timestep, applied, wrench):
    """Plate forces over the coming step by the implicit law of the module docstring, summed
    into slot wrenches.

    jac: (>= 6S, nv) slot Jacobians. minv_rows: (>= 6S+1, nv) rows M^-1 jac_r^T for the 6S
    Jacobian rows, then M^-1 tau_free, where tau_free is every generalised force except
    the sand's (passive + actuator + applied - bias). With each plate moving (force G),
    resting (linear in v+) or off, the end-of-step twists solve
        (I - dt A K) xi+ = xi_free + dt A W_moving,   A = jac M^-1 jac^T,
    K the resting plates' linear response, W_moving the moving plates' wrench; plates then
    change set until the solution is consistent (an active-set iteration; a set is left for
    a neighbouring one). Plates faster than v_reg start as moving. Writes applied[:k]
    (N, world, on the body) and wrench[:S] (6 per slot, [force; torque about COM]).
    """
    n6 = 6 * slots
    nv = qvel.shape[0]
    xi_free = np.zeros(n6)
    a_matrix = np.zeros((n6, n6))
    for r in range(n6):
        acc_now = 0.0
        acc_acc = 0.0
        for i in range(nv):
            acc_now += jac[r, i] * qvel[i]
            acc_acc += jac[r, i] * minv_rows[n6, i]
        xi_free[r] = acc_now + timestep * acc_acc
        for c in range(n6):
            acc = 0.0
            for i in range(nv):
                acc += jac[r, i] * minv_rows[c, i]
            a_matrix[r, c] = acc
    state = np.empty(k, dtype=np.int8)
    for j in range(k):
        state[j] = MOVING if speed[j] > v_reg else RESTING
    magnitude = np.empty(k)
    for j in range(k):
        magnitude[j] = np.sqrt(force[j, 0] ** 2 + force[j, 1] ** 2 + force[j, 2] ** 2)
    h = np.zeros(6)
    column = np.zeros(3)
    k3 = np.zeros((3, 3))
    xi_new = np.zeros(n6)
    inv_reg = 1.0 / v_reg
    for _ in range(12):
        k_blocks = np.zeros((slots, 6, 6))
        w_moving = np.zeros(n6)
        for j in range(k):
            s = out_slot[j]
            if state[j] == MOVING:
                _wrench_row(lever[j], force[j], h)
                for a in range(6):
                    w_moving[6 * s + a] += h[a]
            elif state[j] == RESTING:
                # plate force = K3 v+, K3 = (G d^T - |G| (I - d d^T)) / v_reg
                d = direction[j]
                for a in range(3):
                    for b in range(3):
                        k3[a, b] = (force[j, a] * d[b] + magnitude[j] * d[a] * d[b]) * inv_reg
                    k3[a, a] -= magnitude[j] * inv_reg
                # body block += [I; [r]x] K3 [I, -[r]x]; column b of K3 [I, -[r]x] is
                # K3 e_b (b < 3) or K3 (e_{b-3} x r) (b >= 3)
                rx, ry, rz = lever[j, 0], lever[j, 1], lever[j, 2]
                for b in range(6):
                    if b < 3:
                        for a in range(3):
                            column[a] = k3[a, b]
                    else:
                        ex = 1.0 if b == 3 else 0.0
                        ey = 1.0 if b == 4 else 0.0
                        ez = 1.0 if b == 5 else 0.0
                        cx, cy, cz = ey * rz - ez * ry, ez * rx - ex * rz, ex * ry - ey * rx
                        for a in range(3):
                            column[a] = k3[a, 0] * cx + k3[a, 1] * cy + k3[a, 2] * cz
                    _wrench_row(lever[j], column, h)
                    for a in range(6):
                        k_blocks[s, a, b] += h[a]
        system = np.eye(n6)
        rhs = xi_free.copy()
        for r in range(n6):
            for s in range(slots):
                for b in range(6):
                    acc = 0.0
                    for a in range(6):
                        acc += a_matrix[r, 6 * s + a] * k_blocks[s, a, b]
                    system[r, 6 * s + b] -= timestep * acc
            acc = 0.0
            for c in range(n6):
                acc += a_matrix[r, c] * w_moving[c]
            rhs[r] += timestep * acc
        xi_new = _solve(system, rhs)
        changed = False
        for j in range(k):
            vx, vy, vz = _point_velocity(lever[j], xi_new, 6 * out_slot[j])
            d = direction[j]
            along = vx * d[0] + vy * d[1] + vz * d[2]
            a_ratio = along * inv_reg
            b_ratio = np.sqrt(max((vx * vx + vy * vy + vz * vz) - along * along, 0.0)) * inv_reg
            moving = a_ratio >= 1.0 or (b_ratio > 1.0 and a_ratio >= 0.0)
            if state[j] == RESTING:
                wanted = MOVING if moving else (OFF if a_ratio < 0.0 else RESTING)
            elif state[j] == MOVING:  # a set is left only for a neighbouring one
                wanted = MOVING if moving else RESTING
            else:
                wanted = OFF if a_ratio <= 0.0 else RESTING
            if wanted != state[j]:
                state[j] = wanted
                changed = True
        if not changed:
            break
    wrench[:slots, :] = 0.0
    for j in range(k):
        if state[j] == MOVING:
            for a in range(3):
                applied[j, a] = force[j, a]
        elif state[j] == OFF:
            for a in range(3):
                applied[j, a] = 0.0
        else:
            vx, vy, vz = _point_velocity(lever[j], xi_new, 6 * out_slot[j])
            d = direction[j]
            along = vx * d[0] + vy * d[1] + vz * d[2]
            a_ratio = min(max(along * inv_reg, 0.0), 1.0)
            px, py, pz = vx - along * d[0], vy - along * d[1], vz - along * d[2]
            perp = np.sqrt(px * px + py * py + pz * pz)
            damp = magnitude[j] * inv_reg if perp * inv_reg <= 1.0 else magnitude[j] / perp
            applied[j, 0] = a_ratio * force[j, 0] - damp * px
            applied[j, 1] = a_ratio * force[j, 1] - damp * py
            applied[j, 2] = a_ratio * force[j, 2] - damp * pz
        _wrench_row(lever[j], applied[j], h)
        for a in range(6):
            wrench[out_slot[j], a] += h[a]


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
