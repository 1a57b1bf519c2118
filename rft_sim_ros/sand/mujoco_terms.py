"""MuJoCo's side of the implicit sand step, compiled: the Jacobian rows of each slot's body
and the generalised force without sand (`prepare_solve`), the velocity damping MuJoCo's step
integrates implicitly and its step matrix Mh = M + dt D (`implicit_damping`,
`implicit_mass`), and the slots' wrenches out into mjData.xfrc_applied (`scatter_wrenches`,
which the explicit treatments use too).

Conventions: MuJoCo arrays as mjData/mjModel expose them (world frame, z up, SI); per dof
N or N m, N s/m or N m s/rad. A slot is a sand body with plates in the sand this step
(`gather`); body twists and wrenches are 6-vectors [linear (3); angular (3)] at the body's
centre of mass (`xipos`), world axes: the convention of mjData.xfrc_applied.
"""
from numba import njit

from ..kernel_cache import forget_stale


@njit(cache=True, error_model='numpy')
def prepare_solve(slots, slot_body, body_ids, xipos, subtree_com, cdof, body_rootid,
                  body_dofnum, body_dofadr, body_parentid, dof_parentid, qfrc_passive,
                  qfrc_actuator, qfrc_applied, qfrc_constraint, qfrc_bias, rows, chain,
                  chain_count):
    """Right-hand sides of the implicit solve: rows 6s..6s+5 of `rows` ((6S+1) x nv) become
    d[v_com; omega]/d qvel of each slot's body (the linear part at the body's centre of mass,
    world axes, as mujoco.mj_jac at xipos), and row 6S the generalised force without sand,
    tau_free = passive + actuator + applied + constraint - bias (N or N m per dof), the
    constraint force of the constraints the solve leaves to MuJoCo (tendon friction) being
    MuJoCo's of the step before (`implicit_solve._implicit_step`; mj_step2 computes this step's after the
    solve, and the last one is the estimate).
    chain[s, :chain_count[s]] (S x nv, S) become the dofs slot s's rows reach: its kinematic
    chain, leaf to root."""
    rows[:6 * slots + 1, :] = 0.0
    chain_count[:slots] = 0
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
            chain[s, chain_count[s]] = i
            chain_count[s] += 1
            i = dof_parentid[i]
    for i in range(qfrc_bias.shape[0]):
        rows[6 * slots, i] = (qfrc_passive[i] + qfrc_actuator[i] + qfrc_applied[i]
                              + qfrc_constraint[i] - qfrc_bias[i])


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


@njit(cache=True, error_model='numpy')
def implicit_mass(mass, damping, timestep):
    """mass += dt D in place: the dense joint-space inertia M (nv x nv) becomes Mh = M + dt D,
    with D the diagonal damping of `implicit_damping`: MuJoCo's own step matrix, so predicted
    end-of-step velocities match what mj_step2 integrates. Mh is SPD."""
    for i in range(mass.shape[0]):
        mass[i, i] += timestep * damping[i]
@njit(cache=True, error_model='numpy')
def scatter_wrenches(slots, slot_body, slot_wrench, body_ids, body_wrenches, xfrc_applied,
                     xipos, wrench_sum):
    """Slot wrenches -> per-sand-body wrenches (zero for bodies out of the sand) and
    mjData.xfrc_applied rows of the sand bodies; adds each body's wrench to its row of
    wrench_sum (nb, 6) as [force; torque about the world origin] (xipos: COMs, m, world),
    so that sums over steps give mean wrenches."""
    body_wrenches[:, :] = 0.0
    for s in range(slots):
        for a in range(6):
            body_wrenches[slot_body[s], a] = slot_wrench[s, a]
    for i in range(body_ids.shape[0]):
        b = body_ids[i]
        for a in range(6):
            xfrc_applied[b, a] = body_wrenches[i, a]
        fx, fy, fz = body_wrenches[i, 0], body_wrenches[i, 1], body_wrenches[i, 2]
        x, y, z = xipos[b, 0], xipos[b, 1], xipos[b, 2]
        wrench_sum[i, 0] += fx
        wrench_sum[i, 1] += fy
        wrench_sum[i, 2] += fz
        wrench_sum[i, 3] += body_wrenches[i, 3] + y * fz - z * fy
        wrench_sum[i, 4] += body_wrenches[i, 4] + z * fx - x * fz
        wrench_sum[i, 5] += body_wrenches[i, 5] + x * fy - y * fx


forget_stale(globals())  # (kernel_cache: drops kernels compiled from older sources)
