"""Joint friction (MJCF frictionloss F, N m or N) in the sand's implicit solve
(`implicit_solve._implicit_step`): the regularised Coulomb law with the sand's rest speed
v_reg. A joint whose end-of-step speed is below v_reg sticks (a damper F / v_reg, so at most
F), otherwise it slips (F against its motion); a joint that would return to a set it had in
the step is frozen (`active_set`), a damper F / max(|qvel|, v_reg) through its speed at the
step's start. The engine takes the friction over from MuJoCo, whose friction constraint,
acting after the sand's solve, undid the end velocities the solve chose and kept a robot
with joint friction standing in sand jittering between the sets.

The joints of a step: `friction` = (dofs, force, memory, flags, torque): their dof indices,
friction F, memory of their last step's set (step << MEMORY_SHIFT | set; -1 for never),
flags (`active_set`'s rows) and the friction torque the step applies (written).
"""
from numba import njit

from ..kernel_cache import forget_stale
from .active_set import MEMORY_SHIFT, SOLVED, STATE, VISITED, next_set, remembered

#: A frictional joint's sets: |end speed| < v_reg, end speed >= v_reg, <= -v_reg (and FROZEN).
STICK, SLIP_UP, SLIP_DOWN = 0, 1, 2


@njit(cache=True)
def friction_start(friction, qvel, v_reg, last):
    """The implicit step's (`implicit_solve._implicit_step`) frictional joints in their first
    sets: the last step's (their memory, `last`: that step << MEMORY_SHIFT) unless frozen
    then, else their speed's."""
    dofs, memory, flags = friction[0], friction[2], friction[3]
    for f in range(dofs.shape[0]):
        previous = remembered(memory[f], last)
        state = previous if previous >= 0 else _friction_set(qvel[dofs[f]], v_reg)
        flags[STATE, f] = state
        flags[VISITED, f] = 1 << state


@njit(cache=True)
def friction_terms(friction, qvel, v_reg, timestep, system, rhs):
    """The frictional joints' terms of the implicit system: a sticking or frozen joint's
    damper on the diagonal, a slipping joint's constant force in the right-hand side."""
    dofs, forces, flags = friction[0], friction[1], friction[3]
    for f in range(dofs.shape[0]):
        i, force, state = dofs[f], forces[f], flags[STATE, f]
        if state == SLIP_UP or state == SLIP_DOWN:
            rhs[i] += timestep * force * (-1.0 if state == SLIP_UP else 1.0)
        else:
            system[i, i] += timestep * _friction_damper(state, force, qvel[i], v_reg)


@njit(cache=True)
def friction_sets(friction, solution, v_reg):
    """After a solve: each frictional joint's set as solved (row SOLVED), then the set its
    end speed asks for (a return to a set it had this step: FROZEN). Returns the joints that
    changed set and of those the ones frozen."""
    dofs, flags = friction[0], friction[3]
    changed = frozen = 0
    for f in range(dofs.shape[0]):
        moved, cycle = next_set(flags, f, _friction_set(solution[dofs[f]], v_reg))
        changed += moved
        frozen += cycle
    return changed, frozen


@njit(cache=True)
def friction_finish(friction, qvel, v_reg, solution, step):
    """The friction torque the last solve assumed (friction's torque, N m or N) and each
    joint's memory of its set in this step."""
    dofs, forces, memory, flags, torque = friction
    for f in range(dofs.shape[0]):
        i, force, state = dofs[f], forces[f], flags[SOLVED, f]
        if state == SLIP_UP or state == SLIP_DOWN:
            torque[f] = force * (-1.0 if state == SLIP_UP else 1.0)
        else:
            torque[f] = -_friction_damper(state, force, qvel[i], v_reg) * solution[i]
        memory[f] = (step << MEMORY_SHIFT) | state


@njit(cache=True, inline='always')
def _friction_set(speed, v_reg):
    """The set a frictional joint's (end) speed asks for: STICK below v_reg, else SLIP_UP or
    SLIP_DOWN with its sign."""
    return SLIP_UP if speed >= v_reg else (SLIP_DOWN if speed <= -v_reg else STICK)


@njit(cache=True, inline='always')
def _friction_damper(state, force, speed, v_reg):
    """Damper (N m s/rad or N s/m) of a sticking (F / v_reg) or frozen (F / max(|speed|,
    v_reg), the secant through its speed at the step's start) joint of friction F."""
    return force / (v_reg if state == STICK else max(abs(speed), v_reg))


forget_stale(globals())  # (kernel_cache: drops kernels compiled from older sources)
