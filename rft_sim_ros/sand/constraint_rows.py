"""MuJoCo's own constraint rows in the sand's implicit solve (`implicit_solve._implicit_step`):
equalities (two-sided), joint and tendon limits and contacts with pyramidal cones
(one-sided), and contacts with elliptic cones (a contact's rows together: `elliptic_cones`),
as mj_step1 makes them in mjData (Jacobian rows, efc_D, efc_aref). A row is MuJoCo's soft
constraint f = -D jar, jar = J (qvel+ - qvel) / dt - aref (N or N m; jar: the constraint's
acceleration less its reference, m/s^2 or rad/s^2). `take_constraint_rows` takes them from
mjData, zeroing their Jacobian rows there so that mj_step2's own solve adds no force of
theirs; after the solve `report_constraint_forces` makes mj_step2 report the solve's forces
for them (efc_force, touch sensors, contact forces), or, in a step where the solve could not
settle them, `return_constraint_rows` gives them back for mj_step2 to solve. Tendon friction
stays MuJoCo's. Left to MuJoCo's solve after the sand's in every step, such a constraint
undid the end velocities the sand's solve chose (a knee at its stop, a stiff tendon coupling
of a leg's joints, a load resting on the robot, a foot on a rigid rock) and the feet cycled
through their sets every step.

The rows of a step: `constraints` = (jac, columns, counts, rows, flags, n): Jacobian rows
(dense, nv wide), their nonzero columns (columns[r, :counts[r]]), columns ROW_D ... per
row, and flags (`active_set`) of the n rows taken (a cone's on its first row).
"""
from numba import njit

from ..kernel_cache import forget_stale
from .active_set import SOLVED, STATE, VISITED, next_set
from .layout import (ACTIVE, CONE, INACTIVE, KEPT, ONE_SIDED, ROW_AREF, ROW_D, ROW_DIM, ROW_FORCE,
                     ROW_FRICTION, ROW_KIND, ROW_PUSH, ROW_REPORT, ROW_START)



@njit(cache=True)
def take_constraint_rows(kinds, efc_type, efc_id, efc_j, efc_d, efc_aref, rownnz, rowadr,
                         colind, sparse, contact_mu, contact_friction, contact_dim,
                         contact_efc, jac, columns, counts, rows, efc_rows):
    """The rows of MuJoCo's constraints that the implicit law solves, taken from mjData
    after mj_step1 made them: each row e whose kind kinds[efc_type[e]] is not KEPT (left to
    MuJoCo) is copied, its Jacobian row into jac (dense, nv wide) with its nonzero columns
    in columns[:, :counts], its efc_D and efc_aref into rows (ROW_D ...), its index e into
    efc_rows, and its Jacobian row and aref zeroed in mjData (mj_step2's solve then gives it
    no generalised force, and, until `report_constraint_forces`, no force). efc_j:
    mjData.efc_J, dense (nefc x nv, flat) or, with `sparse`, its nonzeros (rownnz, rowadr,
    colind). A CONE row also gets its contact's (efc_id[e]) friction coefficients from
    mjData.contact's mu, friction, dim and efc_address. Returns the rows taken, or minus
    the rows needed where jac has fewer (then nothing is changed)."""
    nefc, nv = efc_type.shape[0], jac.shape[1]
    needed = 0
    for e in range(nefc):
        needed += kinds[efc_type[e]] != KEPT
    if needed > jac.shape[0]:
        return -needed
    n = 0
    for e in range(nefc):
        kind = kinds[efc_type[e]]
        if kind == KEPT:
            continue
        row = jac[n]
        for c in range(nv):
            row[c] = 0.0
        start, stop = (rowadr[e], rowadr[e] + rownnz[e]) if sparse else (e * nv, e * nv + nv)
        count = 0
        for a in range(start, stop):
            c = colind[a] if sparse else a - start
            if efc_j[a] != 0.0:
                row[c] = efc_j[a]
                columns[n, count] = c
                count += 1
            efc_j[a] = 0.0
        counts[n] = count
        rows[n, ROW_D], rows[n, ROW_AREF], rows[n, ROW_KIND] = efc_d[e], efc_aref[e], kind
        if kind == CONE:
            contact = efc_id[e]
            along = e - contact_efc[contact]  # 0: the normal row
            rows[n, ROW_FRICTION] = (contact_mu[contact] if along == 0
                                     else contact_friction[contact, along - 1])
            rows[n, ROW_DIM] = contact_dim[contact] if along == 0 else 0
        efc_rows[n] = e
        efc_aref[e] = 0.0
        n += 1
    return n


@njit(cache=True)
def add_row_forces(jac, columns, counts, rows, n, qfrc):
    """qfrc += J^T f over the first n rows (N or N m per dof; jac, columns, counts, rows as
    `take_constraint_rows` leaves them, f in rows[:, ROW_FORCE]). Compiled on its own,
    without fastmath: its products and sums round as written, whoever calls it."""
    for r in range(n):
        force_r = rows[r, ROW_FORCE]
        for c in columns[r, :counts[r]]:
            qfrc[c] += jac[r, c] * force_r


@njit(cache=True)
def report_constraint_forces(rows, efc_rows, n, efc_aref):
    """The forces the implicit solve gave the n rows it took (`take_constraint_rows`), made
    the forces MuJoCo's solve in mj_step2 reports for them (efc_force, and from it touch
    sensors, contact forces, cfrc_ext): with the row's Jacobian zero, MuJoCo's solve sees
    jar = -aref, so aref is set to ROW_REPORT (`constraint_forces`; generalised force J^T f
    still zero: the engine's is in qfrc_passive)."""
    for r in range(n):
        efc_aref[efc_rows[r]] = rows[r, ROW_REPORT]


@njit(cache=True)
def return_constraint_rows(jac, rows, efc_rows, n, efc_j, efc_aref, rownnz, rowadr, colind,
                           sparse, nv):
    """The n rows taken (`take_constraint_rows`) given back to mjData as MuJoCo made them
    (Jacobian rows and aref), for mj_step2's own solve: a step whose rows did not settle in
    the implicit solve (`implicit_solve._implicit_step`)."""
    for r in range(n):
        e = efc_rows[r]
        start, stop = (rowadr[e], rowadr[e] + rownnz[e]) if sparse else (e * nv, e * nv + nv)
        for a in range(start, stop):
            efc_j[a] = jac[r, colind[a] if sparse else a - start]
        efc_aref[e] = rows[r, ROW_AREF]


@njit(cache=True)
def constraint_start(constraints, qvel, timestep, matrix, momentum):
    """A step's start of its constraint rows (`implicit_solve._implicit_step`): with
    f = D (aref - J (qvel+ - qvel) / dt), dt J^T f adds D J^T J to the system and J^T push,
    push = D (J qvel + dt aref), to the right-hand side. Each row's push into ROW_PUSH; the
    two-sided rows' D J^T J into matrix (nv x nv, overwritten; added by every solve) and
    their J^T push to momentum; the one-sided rows active where aref > 0; a cone's rows'
    start (ROW_START: `elliptic_cones.cone_start`). Returns the two-sided rows."""
    jac, columns, counts, rows, flags, n = constraints
    nv = qvel.shape[0]
    for i in range(nv):
        for c in range(nv):
            matrix[i, c] = 0.0
    two_sided = 0
    for r in range(n):
        row, used = jac[r], columns[r, :counts[r]]
        speed = 0.0
        for c in used:
            speed += row[c] * qvel[c]
        damper = rows[r, ROW_D]
        push = damper * (speed + timestep * rows[r, ROW_AREF])
        rows[r, ROW_PUSH] = push
        if rows[r, ROW_KIND] == CONE:
            rows[r, ROW_START] = speed / timestep + rows[r, ROW_AREF]
            continue
        if rows[r, ROW_KIND] == ONE_SIDED:
            state = ACTIVE if rows[r, ROW_AREF] > 0.0 else INACTIVE
            flags[STATE, r] = state
            flags[VISITED, r] = 1 << state
            continue
        two_sided += 1
        for i in used:
            momentum[i] += row[i] * push
            scaled, target = damper * row[i], matrix[i]
            for c in used:
                target[c] += scaled * row[c]
    return two_sided


@njit(cache=True, inline='always')
def add_matrix(matrix, system):
    """system += matrix (same square shapes), element by element."""
    for i in range(matrix.shape[0]):
        for c in range(matrix.shape[1]):
            system[i, c] += matrix[i, c]


@njit(cache=True)
def constraint_terms(constraints, system, rhs):
    """The active (or frozen) one-sided rows' terms of the implicit system: D J^T J into the
    system, J^T push into the right-hand side (`constraint_start`)."""
    jac, columns, counts, rows, flags, n = constraints
    for r in range(n):
        if rows[r, ROW_KIND] != ONE_SIDED or flags[STATE, r] == INACTIVE:
            continue
        row, used = jac[r], columns[r, :counts[r]]
        damper, push = rows[r, ROW_D], rows[r, ROW_PUSH]
        for i in used:
            rhs[i] += row[i] * push
            scaled, target = damper * row[i], system[i]
            for c in used:
                target[c] += scaled * row[c]


@njit(cache=True, inline='always')
def row_jar(constraints, r, qvel, solution, timestep):
    """Row r's jar at the end velocities `solution`: J (qvel+ - qvel) / dt - aref (m/s^2 or
    rad/s^2)."""
    jac, columns, counts, rows = constraints[0], constraints[1], constraints[2], constraints[3]
    change = 0.0
    for c in columns[r, :counts[r]]:
        change += jac[r, c] * (solution[c] - qvel[c])
    return change / timestep - rows[r, ROW_AREF]


@njit(cache=True, inline='always')
def _constraint_force(constraints, r, qvel, solution, timestep):
    """Row r's force at the end velocities `solution` (N or N m): MuJoCo's soft constraint
    -D jar = D (aref - J (qvel+ - qvel) / dt)."""
    return -constraints[3][r, ROW_D] * row_jar(constraints, r, qvel, solution, timestep)


@njit(cache=True)
def constraint_sets(constraints, qvel, solution, timestep):
    """After a solve: each one-sided row's set as solved (row SOLVED), then the set its force
    asks for (active while it pushes; a return to a set it had this step: FROZEN, kept in).
    Returns the rows that changed set and of those the ones frozen."""
    rows, flags, n = constraints[3], constraints[4], constraints[5]
    changed = frozen = 0
    for r in range(n):
        if rows[r, ROW_KIND] != ONE_SIDED:
            continue
        pushing = _constraint_force(constraints, r, qvel, solution, timestep) > 0.0
        moved, cycle = next_set(flags, r, ACTIVE if pushing else INACTIVE)
        changed += moved
        frozen += cycle
    return changed, frozen


@njit(cache=True)
def constraint_forces(constraints, qvel, solution, timestep):
    """The force each row (but a cone's) applies by the last solve into ROW_FORCE: its soft
    constraint's (`_constraint_force`), zero for a one-sided row that solve had inactive (a
    frozen row stays in); and the aref that makes MuJoCo report it into ROW_REPORT: f / D.
    Returns the rows whose force is not MuJoCo's at the solution: a one-sided row in the
    system that pulls, or one out of it that would push (frozen, or the iteration ended
    first)."""
    rows, flags, n = constraints[3], constraints[4], constraints[5]
    wrong = 0
    for r in range(n):
        if rows[r, ROW_KIND] == CONE:  # (`elliptic_cones.cone_errors`)
            continue
        force = _constraint_force(constraints, r, qvel, solution, timestep)
        if rows[r, ROW_KIND] == ONE_SIDED:
            out = flags[SOLVED, r] == INACTIVE
            wrong += force > 0.0 if out else force < 0.0
            force = 0.0 if out else force
        rows[r, ROW_FORCE] = force
        rows[r, ROW_REPORT] = force / rows[r, ROW_D]
    return wrong


forget_stale(globals())  # (kernel_cache: drops kernels compiled from older sources)
