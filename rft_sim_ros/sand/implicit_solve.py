"""The implicit sand step, compiled: the active-set iteration that solves the plates'
implicit law (`implicit_law`), joint friction (`joint_friction`) and MuJoCo's own
constraint rows (`constraint_rows`, `elliptic_cones`) together for the end-of-step joint
velocities, in the one call the engine makes per step (`_implicit_step`), from the arrays
the gather kernel left.

It is a template compiled three times (`kernel_names.STEPS`): without MuJoCo's rows
(`implicit_step_plain`: a body with no joint limits, equalities or contacts of its own),
with them (`implicit_step_rows`) and with elliptic cones' rows too (`implicit_step_cones`).
Each compiles only the kernels it calls (the others' branches are pruned on the constants
it binds), so that a first run compiles what its model needs: the engine picks one
(`engine.step_parts`).

Joint friction (MJCF frictionloss F, N m or N) is solved in the same iteration, as the
regularised Coulomb law with the same v_reg: a joint whose end speed is below v_reg sticks
(a damper F / v_reg: at most F), otherwise it slips (F against its motion). The engine takes
it over from MuJoCo, whose friction constraint, acting after the sand's solve, would undo
the end velocities the solve chose and keep a standing robot jittering between sets. So
are MuJoCo's equality, limit and contact constraints, as the rows MuJoCo itself makes for
them (`constraint_rows`), in the same active-set iteration (`active_set`); a step whose rows
do not settle leaves them to MuJoCo's solve.

Conventions: as `gather` and `mujoco_terms`: world frame, z up, SI; slot s's six Jacobian
rows are rows 6s..6s+5 of `jac` (twists [linear; angular] at its body's centre of mass);
the system is nv x nv, solved on MuJoCo's tree (`tree_solve`).
"""
import types

import numpy as np
from numba import njit

from ..kernel_cache import forget_stale
from ..rft.law_rows import DIRECTION
from .active_set import FROZEN, MEMORY_SHIFT, SOLVED, STATE, VISITED, remembered
from .table_readers import (byte_vector, float_matrix, float_vector, int8_matrix, int8_vector,
                          int32_matrix, int32_vector, int_matrix, int_vector)
from .constraint_rows import (add_matrix, add_row_forces, constraint_forces, constraint_sets,
                              constraint_start, constraint_terms)
from .elliptic_cones import (CONE_ITERATIONS, cone_errors, cone_reports, cone_settled, cone_start,
                             cone_step, cone_terms)
from .implicit_law import (MOVING, OFF, RESTING, accumulate_slot, across_damper,
                           resting_block, set_coefficients)
from .joint_friction import friction_finish, friction_sets, friction_start, friction_terms
from .layout import (ACROSS, ACTUATORS, COEF_ACROSS, COEF_ALONG, COEF_MOVING, CONSTRAINT_ROWS,
                     DAMPER, GATHERED, HANDED_BACK, HANDED_BACK_AT, IMPLICIT, LEVER, MAGNITUDE,
                     REST_SPEED, SLOTS, SOLVES, SPEED, STEPS, UNSETTLED, WANTED, SolveSpace)
from .mujoco_terms import implicit_damping, implicit_mass, prepare_solve, scatter_wrenches
from .tree_solve import checked_solve, copy_into, translational_inverse_masses


#: Solves per step at most (the active set settles in one or two almost always).
MAX_ITERATIONS = 16

#: Constants each compiled step binds (`_step_kernel`): ROWS, whether it solves MuJoCo's
#: constraint rows with the sand; CONES, the rows of elliptic cones too. None here: the
#: template `_implicit_step` is never run itself.
ROWS = CONES = None


@njit(cache=True, inline='always', fastmath=True)
def _slot_terms(block, w_moving, slot_jac, dofs, work, product, force_terms):
    """A slot's terms of the implicit system, J^T block J into product[:n, :n] and
    J^T w_moving into force_terms[:n] (block (6, 6), w_moving (6,), slot_jac J (6, nv)), over
    the n dofs of its chain (`dofs`), where J is nonzero: on a compact copy of J's chain
    columns, with the dofs innermost and the six-term sums unrolled (in pairs), so that the
    loops vectorise. work: (12, >= n) space: J's chain columns, block J on them."""
    count = dofs.shape[0]
    j0, j1, j2 = work[0, :count], work[1, :count], work[2, :count]
    j3, j4, j5 = work[3, :count], work[4, :count], work[5, :count]
    for q in range(count):
        d = dofs[q]
        j0[q], j1[q], j2[q] = slot_jac[0, d], slot_jac[1, d], slot_jac[2, d]
        j3[q], j4[q], j5[q] = slot_jac[3, d], slot_jac[4, d], slot_jac[5, d]
    for a in range(6):  # block J on the chain
        b0, b1, b2 = block[a, 0], block[a, 1], block[a, 2]
        b3, b4, b5 = block[a, 3], block[a, 4], block[a, 5]
        out = work[6 + a, :count]
        for q in range(count):
            out[q] = ((b0 * j0[q] + b1 * j1[q]) + (b2 * j2[q] + b3 * j3[q])
                      + (b4 * j4[q] + b5 * j5[q]))
    c0, c1, c2 = work[6, :count], work[7, :count], work[8, :count]
    c3, c4, c5 = work[9, :count], work[10, :count], work[11, :count]
    w0, w1, w2 = w_moving[0], w_moving[1], w_moving[2]
    w3, w4, w5 = w_moving[3], w_moving[4], w_moving[5]
    for q in range(count):  # row q of J^T block J on the chain
        a0, a1, a2, a3, a4, a5 = j0[q], j1[q], j2[q], j3[q], j4[q], j5[q]
        force_terms[q] = (a0 * w0 + a1 * w1) + (a2 * w2 + a3 * w3) + (a4 * w4 + a5 * w5)
        row = product[q, :count]
        for p in range(count):
            row[p] = ((a0 * c0[p] + a1 * c1[p]) + (a2 * c2[p] + a3 * c3[p])
                      + (a4 * c4[p] + a5 * c5[p]))


@njit(cache=True, inline='always', fastmath=True)
def _add_slot(product, force_terms, dofs, timestep, system, rhs):
    """A slot's terms (`_slot_terms`) into the implicit system, scattered to its chain's
    dofs: system -= dt J^T block J, rhs += dt J^T w_moving."""
    count = dofs.shape[0]
    for q in range(count):
        rhs[dofs[q]] += timestep * force_terms[q]
        row, terms = system[dofs[q]], product[q]
        for p in range(count):
            row[dofs[p]] -= timestep * terms[p]


def _implicit_step(timestep, arrays):
    """One step's implicit sand wrenches over the plates the step's gather kernel left, in
    one call: `prepare_solve` (into jac, (>= 6S+1, nv) work space: the 6S slot Jacobian
    rows, then tau_free, every generalised force except the sand's), `implicit_damping`,
    `implicit_mass` (mass: the dense M of this state, made Mh = M + dt D in place, the matrix
    MuJoCo's step solves with), the solve below over the gathered plates, the frictional
    joints and the constraint rows taken this step (`take_constraint_rows`, counter
    CONSTRAINT_ROWS; when there are any), then `scatter_wrenches` into xfrc_applied (zero
    wrenches when no plate is in the sand); the joints' friction and the rows' forces
    (J^T f, `add_row_forces`) are added to qfrc_passive, which mj_step2 applies. timestep:
    s; arrays: the table of an `ArrayTable` of `ImplicitArrays`, settings REST_SPEED
    (v_reg), DAMPER, ACTUATORS. Adds the solves to the SOLVES counter, counts the step in
    UNSETTLED where it did not settle (some plate, joint, row or cone frozen, or the sets
    not settled within MAX_ITERATIONS) and in HANDED_BACK where its rows are handed back to
    MuJoCo (then none of their forces is added). The constraint force of the constraints
    left to MuJoCo is taken as mjData's qfrc_constraint of the step before
    (`prepare_solve`), except after a step whose rows were handed back, whose
    qfrc_constraint holds theirs too: then as the one that step took (held_constraint).

    The solve: sand wrenches over the coming step by the implicit law (`implicit_law`).
    With each plate moving (force G), resting (linear in v+) or off, the end-of-step joint
    velocities solve
        (Mh - dt J^T K J) qvel+ = Mh qvel + dt (tau_free + J^T W_moving),   xi+ = J qvel+,
    K the plates' linear response, W_moving the moving plates' G; plates then change set
    until the solution is consistent (an active-set iteration; moving and off are
    neighbours of resting only, so a plate passes through resting between them).
    Each plate starts from its set of the previous step if it was in the sand then
    (`memory`, indexed by plate: step << MEMORY_SHIFT | its final set; -1 for never) and
    not frozen, otherwise as moving when faster than v_reg; so a step usually needs one
    solve. Plates: columns :k of the gathered table and force, slot by slot from
    slot_start (`gather._gather_plates`; force (6, >= k): this fills rows 3..5 with r x G,
    so that it holds h); work (WORK_ROWS, >= k) and flags (FLAG_ROWS, >= k) are work space,
    of which rows STATE (final sets) and ACROSS (across dampers, N s/m) are results. Writes
    xi_new[:6S] (end-of-step twists) and wrench[:S] ([force; torque about COM], N, N m);
    space: a SolveSpace, whose chain, chain_count hold the dofs each slot's rows reach
    (`prepare_solve`), the rest work space.
    Joint friction, the J joints with friction (dofs, force, memory, flags, torque): their
    dof indices, friction F (N m or N), memory (as the plates'), flags ((3, J) int8 work
    space: rows STATE, VISITED, SOLVED) and the friction torque the step applies (N m or
    N). Each joint is in a set (`joint_friction`: sticking, a damper -F qvel+ / v_reg in the
    system; slipping, a constant -F or +F) chosen by its end speed like a plate's, starting
    from its last set.
    Constraint rows (ROWS), `constraints` = (constraint_jac, constraint_columns,
    constraint_counts, constraint_rows, flags, n): the n rows of MuJoCo's constraints the
    engine solves this step (`take_constraint_rows`: Jacobian rows, their
    nonzero columns, ROW_D ...) and their flags ((3, >= n) int8 work space: STATE, VISITED,
    SOLVED). Each row is MuJoCo's soft constraint f = D (aref - J (qvel+ - qvel) / dt) (N or
    N m): a two-sided row (an equality) is in every solve; a one-sided row (a limit, a
    contact's pyramid edge) starts active (pushing, in the system) where its reference
    acceleration pushes (aref > 0: the force it would have if nothing else acted), and
    changes set as its force at the solve's end velocities asks. An elliptic cone's rows
    (CONES, `elliptic_cones`) are in every solve, linearised at `point` ((nv,) work space:
    the end velocities they are linearised at); after a solve where some cone's force is off
    MuJoCo's, the next solve is its Newton step (`cone_step`) with every other element
    keeping its set. Their forces are written to constraint_rows[:, ROW_FORCE].
    A plate that would return to a set it already had this step is frozen for the rest of
    the step (the law is not monotone where RFT's lift makes G d^T non-symmetric, and plain
    active-set iterations can cycle): its along response becomes the secant
    (d.w / max(|v|, v_reg)) G through its current speed - the resting response for a plate
    at rest, about G for a plate that keeps its speed, less as it slows - linear and
    opposing the plate's motion (RFT's G always opposes d). The wrench is exactly what the
    last solve assumed. Where the rows' forces are not MuJoCo's at the last solve's end
    velocities (a row or cone frozen, or the iteration ended first:
    `constraint_rows.constraint_forces`), the rows are handed back: the step applies none of
    them and MuJoCo's own solve in mj_step2 solves them, exactly, with the sand's wrenches
    as this solve left them (the engine restores their rows,
    `constraint_rows.return_constraint_rows`). A joint that would return to a set is frozen
    likewise (a damper F / max(|qvel|, v_reg) through its speed at the step's start).

    Each plate enters its slot's accumulators with coefficients set by its set: moving ->
    wrench h = [G; r x G]; resting -> along response h u^T / v_reg (u = [d; r x d]); all but
    off -> across damper -c (I - d d^T), i.e. c u u^T minus c P^T P (kept as the 10 moments
    c, c r, c r r^T). After a solve, only the slots with plates that changed set are summed
    again, and only their terms of the system (J^T block J, J^T w_moving) recomputed; every
    slot's are then added to Mh in the same order as in the first solve.
    (One compiled function, not a step calling a solve: numba optimises a called kernel's
    code again in each caller, about 4 s of a first run's compile; docs/speed.md.)"""
    ids = IMPLICIT
    settings, counters = float_vector(arrays, ids.settings), int_vector(arrays, ids.counters)
    k, slots, step = counters[GATHERED], counters[SLOTS], counters[STEPS]
    v_reg = settings[REST_SPEED]
    slot_body, slot_start = int_vector(arrays, ids.slot_body), int_vector(arrays, ids.slot_start)
    out_plate = int_vector(arrays, ids.out_plate)
    table, force = float_matrix(arrays, ids.table), float_matrix(arrays, ids.force)
    body_ids, body_rootid = int_vector(arrays, ids.body_ids), int32_vector(arrays, ids.body_rootid)
    body_dofnum = int32_vector(arrays, ids.body_dofnum)
    body_dofadr = int32_vector(arrays, ids.body_dofadr)
    body_parentid = int32_vector(arrays, ids.body_parentid)
    dof_parentid = int32_vector(arrays, ids.dof_parentid)
    xipos, subtree_com = float_matrix(arrays, ids.xipos), float_matrix(arrays, ids.subtree_com)
    cdof, qvel = float_matrix(arrays, ids.cdof), float_vector(arrays, ids.qvel)
    qfrc_passive = float_vector(arrays, ids.qfrc_passive)
    qfrc_actuator = float_vector(arrays, ids.qfrc_actuator)
    qfrc_applied = float_vector(arrays, ids.qfrc_applied)
    qfrc_constraint = float_vector(arrays, ids.qfrc_constraint)
    after_hand_back = counters[HANDED_BACK_AT] > 0 and counters[HANDED_BACK_AT] == step - 1
    lagged = float_vector(arrays, ids.held_constraint) if after_hand_back else qfrc_constraint
    friction = (int_vector(arrays, ids.friction_dofs), float_vector(arrays, ids.friction_force),
                int_vector(arrays, ids.friction_memory), int8_matrix(arrays, ids.friction_flags),
                float_vector(arrays, ids.friction_torque))
    qfrc_bias = float_vector(arrays, ids.qfrc_bias)
    dof_damping, trntype = float_vector(arrays, ids.dof_damping), int32_vector(arrays, ids.trntype)
    trnid, gear = int32_matrix(arrays, ids.trnid), float_matrix(arrays, ids.gear)
    jnt_type, jnt_dofadr = int32_vector(arrays, ids.jnt_type), int32_vector(arrays, ids.jnt_dofadr)
    dyntype, gaintype = int32_vector(arrays, ids.dyntype), int32_vector(arrays, ids.gaintype)
    gainprm, biastype = float_matrix(arrays, ids.gainprm), int32_vector(arrays, ids.biastype)
    biasprm, forcelimited = float_matrix(arrays, ids.biasprm), byte_vector(arrays, ids.forcelimited)
    forcerange, ctrl = float_matrix(arrays, ids.forcerange), float_vector(arrays, ids.ctrl)
    act, actadr = float_vector(arrays, ids.act), int32_vector(arrays, ids.actadr)
    actuator_force = float_vector(arrays, ids.actuator_force)
    damping, mass = float_vector(arrays, ids.damping), float_matrix(arrays, ids.mass)
    jac, memory = float_matrix(arrays, ids.jac), int_vector(arrays, ids.memory)
    work = float_matrix(arrays, ids.work)
    flags, xi_new = int8_matrix(arrays, ids.flags), float_vector(arrays, ids.xi_new)
    wrench = float_matrix(arrays, ids.wrench)
    body_wrenches = float_matrix(arrays, ids.body_wrenches)
    xfrc_applied = float_matrix(arrays, ids.xfrc_applied)
    wrench_sum = float_matrix(arrays, ids.wrench_sum)
    space = SolveSpace(
        int_matrix(arrays, ids.chain), int_vector(arrays, ids.chain_count),
        float_vector(arrays, ids.inverse_mass), float_matrix(arrays, ids.w_moving),
        float_matrix(arrays, ids.k_rank), float_matrix(arrays, ids.k_iso),
        int8_vector(arrays, ids.dirty), float_vector(arrays, ids.momentum),
        float_matrix(arrays, ids.system), float_vector(arrays, ids.rhs),
        float_matrix(arrays, ids.factored), float_vector(arrays, ids.solution),
        float_matrix(arrays, ids.factor), float_matrix(arrays, ids.translational),
        float_matrix(arrays, ids.blocks), float_matrix(arrays, ids.products),
        float_matrix(arrays, ids.force_terms), float_matrix(arrays, ids.chain_work),
        float_matrix(arrays, ids.constraint_matrix))
    constraint_jac, constraint_rows = (float_matrix(arrays, ids.constraint_jac),
                                       float_matrix(arrays, ids.constraint_rows))
    constraint_columns = int_matrix(arrays, ids.constraint_columns)
    constraint_counts = int_vector(arrays, ids.constraint_counts)
    taken = counters[CONSTRAINT_ROWS]
    constraints = (constraint_jac, constraint_columns, constraint_counts, constraint_rows,
                   int8_matrix(arrays, ids.constraint_flags), taken)
    friction_dofs, friction_torque = friction[0], friction[4]
    if slots > 0 or friction_dofs.shape[0] > 0 or taken > 0:  # (none: zero wrenches)
        rows = jac[:6 * slots + 1]
        prepare_solve(slots, slot_body, body_ids, xipos, subtree_com, cdof, body_rootid,
                      body_dofnum, body_dofadr, body_parentid, dof_parentid, qfrc_passive,
                      qfrc_actuator, qfrc_applied, lagged, qfrc_bias, rows, space.chain,
                      space.chain_count)
        implicit_damping(settings[DAMPER] != 0.0, settings[ACTUATORS] != 0.0, dof_damping,
                         trntype, trnid, gear, jnt_type, jnt_dofadr, dyntype, gaintype, gainprm,
                         biastype, biasprm, forcelimited, forcerange, ctrl, act, actadr,
                         actuator_force, damping)
        implicit_mass(mass, damping, timestep)
        point = float_vector(arrays, ids.cone_point) if taken > 0 else qvel  # (unused: none)
        n6 = 6 * slots
        nv = qvel.shape[0]
        inv_reg = 1.0 / v_reg
        chain, chain_count = space.chain, space.chain_count
        momentum = space.momentum  # Mh qvel + dt tau_free
        for r in range(nv):
            acc = timestep * rows[n6, r]
            for c in range(nv):
                acc += mass[r, c] * qvel[c]
            momentum[r] = acc
        constrained = constraints[5] > 0
        two_sided = cones = 0
        if ROWS and constrained:
            two_sided = constraint_start(constraints, qvel, timestep, space.constraint_matrix,
                                         momentum)
            if CONES:
                cones = cone_start(constraints, timestep)
        for i in range(nv if cones else 0):
            point[i] = qvel[i]
        cone_steps = cones_off = 0  # the cones' Newton steps; cones off MuJoCo's at the last solve
        first = slot_start  # slot s holds plates first[s] .. first[s + 1] - 1
        h, u = force, table[DIRECTION:DIRECTION + 6]  # [G; r x G], [d; r x d]
        magnitude = work[MAGNITUDE]
        across, coef_along, coef_across = work[ACROSS], work[COEF_ALONG], work[COEF_ACROSS]
        coef_moving = work[COEF_MOVING]
        states, visited = flags[STATE], flags[VISITED]  # visited: bit per set had this step
        solved, wanted = flags[SOLVED], flags[WANTED]  # sets the last solve used; asks for
        arm = table[LEVER:LEVER + 3]
        speed = table[SPEED]
        for j in range(k):  # torque rows of h, |G|
            rx, ry, rz = arm[0, j], arm[1, j], arm[2, j]
            gx, gy, gz = force[0, j], force[1, j], force[2, j]
            force[3, j] = ry * gz - rz * gy
            force[4, j] = rz * gx - rx * gz
            force[5, j] = rx * gy - ry * gx
            magnitude[j] = np.sqrt(gx * gx + gy * gy + gz * gz)
        # Across dampers. Turn speed of a slot: the speed its sand could take out of it in one
        # step, dt x (sum of its plates' |G|) x its translational inverse effective mass
        # (diagonal of J Mh^-1 J^T, averaged).
        inverse_mass = space.inverse_mass
        translational_inverse_masses(mass, dof_parentid, rows, slots, space.factor,
                                      space.translational, inverse_mass)
        for s in range(slots):
            total = magnitude[first[s]:first[s + 1]].sum()
            turn_speed = max(total * timestep * inverse_mass[s] / 3.0, v_reg)
            magnitude_s, speed_s = magnitude[first[s]:first[s + 1]], speed[first[s]:first[s + 1]]
            across_s = across[first[s]:first[s + 1]]
            for j in range(first[s + 1] - first[s]):
                across_s[j] = across_damper(magnitude_s[j], speed_s[j], v_reg, turn_speed)
        # initial sets and each plate's coefficients for its set: along factor, across damper,
        # moving (0/1)
        last = (step - 1) << MEMORY_SHIFT  # memory of a plate in the sand on the last step
        for j in range(k):
            previous = remembered(memory[out_plate[j]], last)
            state = previous if previous >= 0 else (MOVING if speed[j] > v_reg else RESTING)
            states[j] = state
            visited[j] = 1 << state
            set_coefficients(j, state, speed[j], across[j], inv_reg, v_reg, coef_along,
                              coef_across, coef_moving)
        frictional = friction[0].shape[0] > 0
        if frictional:
            friction_start(friction, qvel, v_reg, last)
        w_moving, k_rank, k_iso = space.w_moving, space.k_rank, space.k_iso
        dirty = space.dirty  # slots whose accumulators must be summed again
        dirty[:slots] = True
        blocks, products, force_terms = space.blocks, space.products, space.force_terms
        chain_work = space.chain_work
        system, rhs, factored, solution = space.system, space.rhs, space.factored, space.solution
        iterations = 0
        frozen = 0  # plates, joints, rows and cones frozen this step
        converged = False
        while iterations < MAX_ITERATIONS and not converged:
            iterations += 1
            for s in range(slots):  # (a slot's terms change with its plates' sets only)
                if dirty[s]:
                    accumulate_slot(first[s], first[s + 1], h, u, arm, coef_along, coef_across,
                                     coef_moving, w_moving[s], k_rank[6 * s:6 * s + 6], k_iso[s])
                    resting_block(k_rank[6 * s:6 * s + 6], k_iso[s], blocks[6 * s:6 * s + 6])
                    _slot_terms(blocks[6 * s:6 * s + 6], w_moving[s], rows[6 * s:6 * s + 6],
                                chain[s, :chain_count[s]], chain_work, products[nv * s:nv * s + nv],
                                force_terms[s])
                    dirty[s] = False
            # (Mh - dt J^T K J) qvel+ = Mh qvel + dt (tau_free + J^T W_moving), slot by slot
            # over the dofs its Jacobian reaches (its kinematic chain) only.
            copy_into(mass, momentum, system, rhs)
            for s in range(slots):
                _add_slot(products[nv * s:nv * s + nv], force_terms[s], chain[s, :chain_count[s]],
                          timestep, system, rhs)
            if frictional:
                friction_terms(friction, qvel, v_reg, timestep, system, rhs)
            if ROWS and two_sided:
                add_matrix(space.constraint_matrix, system)
            if ROWS and constrained:
                constraint_terms(constraints, system, rhs)
            if CONES and cones:
                cone_terms(constraints, system, rhs)
            checked_solve(system, rhs, dof_parentid, factored, solution)
            for j in range(k):
                solved[j] = states[j]
            # the cones' Newton step first, the others keeping their sets; then the sets
            cone_pass = False
            if CONES and cones:
                cones_off = cone_errors(constraints, qvel, solution, timestep)
                cone_pass = cones_off > 0 and cone_steps < CONE_ITERATIONS
                if cone_pass:
                    cone_steps += 1
                    cone_step(constraints, point, solution, system, rhs, timestep)
                else:
                    for i in range(nv):
                        point[i] = solution[i]
                    cone_settled(constraints, timestep)
            converged = not cone_pass
            if frictional and not cone_pass:
                changed, cycles = friction_sets(friction, solution, v_reg)
                frozen += cycles
                converged = changed == 0
            if ROWS and constrained and not cone_pass:
                changed, cycles = constraint_sets(constraints, qvel, solution, timestep)
                frozen += cycles
                converged &= changed == 0
            for s in range(slots):  # xi+ = J qvel+, over each chain's dofs
                top = chain[s, 0] + 1 if chain_count[s] > 0 else 0  # its leaf has the highest
                for r in range(6 * s, 6 * s + 6):
                    acc = 0.0
                    for i in range(top):  # (zero beyond the chain: a prefix vectorises)
                        acc += rows[r, i] * solution[i]
                    xi_new[r] = acc
            if cone_pass:
                continue
            for s in range(slots):  # the set each plate's end speed along d asks for
                x0, x1, x2 = xi_new[6 * s], xi_new[6 * s + 1], xi_new[6 * s + 2]
                x3, x4, x5 = xi_new[6 * s + 3], xi_new[6 * s + 4], xi_new[6 * s + 5]
                j0, j1 = first[s], first[s + 1]
                d0, d1, d2 = u[0, j0:j1], u[1, j0:j1], u[2, j0:j1]
                d3, d4, d5 = u[3, j0:j1], u[4, j0:j1], u[5, j0:j1]
                wanted_s, states_s = wanted[j0:j1], states[j0:j1]
                changes = 0
                for j in range(j1 - j0):  # (vectorises)
                    value = (d0[j] * x0 + d1[j] * x1 + d2[j] * x2 + d3[j] * x3 + d4[j] * x4
                             + d5[j] * x5)
                    want = OFF if value < 0.0 else (MOVING if value >= v_reg else RESTING)
                    wanted_s[j] = want
                    changes += (want != states_s[j]) & (states_s[j] != FROZEN)
                if changes == 0:
                    continue
                for j in range(j0, j1):
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
                    set_coefficients(j, new, speed[j], across[j], inv_reg, v_reg, coef_along,
                                      coef_across, coef_moving)
                dirty[s] = True
                converged = False
        # The wrench the last solve assumed: moving plates' G plus every plate's linear response.
        for j in range(k):
            states[j] = solved[j]
        for s in range(slots):
            if dirty[s]:  # back to the coefficients of the last solve
                for j in range(first[s], first[s + 1]):
                    set_coefficients(j, solved[j], speed[j], across[j], inv_reg, v_reg,
                                      coef_along, coef_across, coef_moving)
                accumulate_slot(first[s], first[s + 1], h, u, arm, coef_along, coef_across,
                                 coef_moving, w_moving[s], k_rank[6 * s:6 * s + 6], k_iso[s])
                resting_block(k_rank[6 * s:6 * s + 6], k_iso[s], blocks[6 * s:6 * s + 6])
            block = blocks[6 * s:6 * s + 6]
            for a in range(6):
                acc = w_moving[s, a]
                for b in range(6):
                    acc += block[a, b] * xi_new[6 * s + b]
                wrench[s, a] = acc
        for j in range(k):
            memory[out_plate[j]] = (step << MEMORY_SHIFT) | states[j]
        if frictional:
            friction_finish(friction, qvel, v_reg, solution, step)
        handed_back = False
        if ROWS and constrained:
            handed_back = constraint_forces(constraints, qvel, solution, timestep) + cones_off > 0
            if CONES and cones:
                cone_reports(constraints)
        iterations = iterations if converged and frozen == 0 else -iterations
        counters[SOLVES] += abs(iterations)
        counters[UNSETTLED] += iterations < 0
        if handed_back:
            counters[HANDED_BACK] += 1
            counters[HANDED_BACK_AT] = step
            if not after_hand_back:
                held = float_vector(arrays, ids.held_constraint)
                for i in range(held.shape[0]):
                    held[i] = qfrc_constraint[i]
        for f in range(friction_dofs.shape[0]):  # (mj_step2 adds qfrc_passive as it stands)
            qfrc_passive[friction_dofs[f]] += friction_torque[f]
        if ROWS and not handed_back:
            add_row_forces(constraint_jac, constraint_columns, constraint_counts,
                           constraint_rows, taken, qfrc_passive)
    # one call site for any slot count (a literal 0 at a second one compiled it twice)
    scatter_wrenches(slots, slot_body, wrench, body_ids, body_wrenches, xfrc_applied, xipos,
                     wrench_sum)



def _bound(template, name, constants):
    """A copy of the function `template` named `name`, whose globals `constants` (a dict)
    override: numba prunes the branches on module constants before it types a function,
    so a kernel bound to ROWS = False neither types nor compiles the rows' kernels."""
    function = types.FunctionType(template.__code__, dict(globals(), **constants), name)
    function.__qualname__, function.__doc__ = name, template.__doc__
    return function


def _step_kernel(parts):
    """The implicit step compiled for `parts` (one of `kernel_names.STEP_PARTS`): only what
    it solves compiles (docs/speed.md)."""
    constants = {'ROWS': parts != 'plain', 'CONES': parts == 'cones'}
    return njit(cache=True, error_model='numpy', fastmath=True)(
        _bound(_implicit_step, f'implicit_step_{parts}', constants))


implicit_step_plain = _step_kernel('plain')
implicit_step_rows = _step_kernel('rows')
implicit_step_cones = _step_kernel('cones')
_FRICTION = 'Tuple((int64[::1], float64[::1], int64[::1], int8[:, ::1], float64[::1]))'
_ROWS = ('Tuple((float64[:, ::1], int64[:, ::1], int64[::1], float64[:, ::1], int8[:, ::1], '
         'int64))')
#: Kernels the compiled steps call, the least of `kernel_names.STEP_PARTS` whose step calls
#: them, and the argument types (numba's text) the steps call them with
#: (`background_kernels`), in the order a step's compile reaches them.
_CALLED = (
    (prepare_solve, 'plain', '(int64, int64[::1], int64[::1], float64[:, ::1], '
     'float64[:, ::1], float64[:, ::1], int32[::1], int32[::1], int32[::1], int32[::1], '
     'int32[::1], float64[::1], float64[::1], float64[::1], float64[::1], float64[::1], '
     'float64[:, ::1], int64[:, ::1], int64[::1])'),
    (implicit_damping, 'plain', '(boolean, boolean, float64[::1], int32[::1], int32[:, ::1], '
     'float64[:, ::1], int32[::1], int32[::1], int32[::1], int32[::1], float64[:, ::1], '
     'int32[::1], float64[:, ::1], uint8[::1], float64[:, ::1], float64[::1], float64[::1], '
     'int32[::1], float64[::1], float64[::1])'),
    (implicit_mass, 'plain', '(float64[:, ::1], float64[::1], float64)'),
    (constraint_start, 'rows', f'({_ROWS}, float64[::1], float64, float64[:, ::1], '
     'float64[::1])'),
    (cone_start, 'cones', f'({_ROWS}, float64)'),
    (translational_inverse_masses, 'plain', '(float64[:, ::1], int32[::1], float64[:, ::1], '
     'int64, float64[:, ::1], float64[:, ::1], float64[::1])'),
    (friction_start, 'plain', f'({_FRICTION}, float64[::1], float64, int64)'),
    (accumulate_slot, 'plain', '(int64, int64, float64[:, ::1], float64[:, ::1], '
     'float64[:, ::1], float64[::1], float64[::1], float64[::1], float64[::1], '
     'float64[:, ::1], float64[::1])'),
    (friction_terms, 'plain', f'({_FRICTION}, float64[::1], float64, float64, '
     'float64[:, ::1], float64[::1])'),
    (constraint_terms, 'rows', f'({_ROWS}, float64[:, ::1], float64[::1])'),
    (cone_terms, 'cones', f'({_ROWS}, float64[:, ::1], float64[::1])'),
    (checked_solve, 'plain', '(float64[:, ::1], float64[::1], int32[::1], float64[:, ::1], '
     'float64[::1])'),
    (cone_errors, 'cones', f'({_ROWS}, float64[::1], float64[::1], float64)'),
    (cone_step, 'cones', f'({_ROWS}, float64[::1], float64[::1], float64[:, ::1], '
     'float64[::1], float64)'),
    (cone_settled, 'cones', f'({_ROWS}, float64)'),
    (friction_sets, 'plain', f'({_FRICTION}, float64[::1], float64)'),
    (constraint_sets, 'rows', f'({_ROWS}, float64[::1], float64[::1], float64)'),
    (friction_finish, 'plain', f'({_FRICTION}, float64[::1], float64, float64[::1], int64)'),
    (constraint_forces, 'rows', f'({_ROWS}, float64[::1], float64[::1], float64)'),
    (cone_reports, 'cones', f'({_ROWS},)'),
    (add_row_forces, 'rows', '(float64[:, ::1], int64[:, ::1], int64[::1], float64[:, ::1], '
     'int64, float64[::1])'),
    (scatter_wrenches, 'plain', '(int64, int64[::1], float64[:, ::1], int64[::1], '
     'float64[:, ::1], float64[:, ::1], float64[:, ::1], float64[:, ::1])'))


def background_kernels(parts):
    """[(kernel, signature)]: the kernels that the step solving `parts` (one of
    `kernel_names.STEP_PARTS`) calls, with the argument types it calls them with, for a cold
    start to compile in a second process (`kernel_cache.BackgroundCompile`) while this one
    compiles the step: in the reverse of the order the step's compile reaches them, so that
    the two meet in the middle (this process then loads the rest from the cache, and the
    second compiles nothing twice but the kernel they meet at: on two cores each does about
    half; the engine has the second compile the gather kernel after them, while this one
    compiles the step's own code)."""
    from ..kernel_names import STEP_PARTS  # (here: the names are compiled into no kernel)
    level = STEP_PARTS.index(parts)
    return [(kernel, signature) for kernel, least, signature in reversed(_CALLED)
            if STEP_PARTS.index(least) <= level]


forget_stale(globals())  # (kernel_cache: drops kernels compiled from older sources)
