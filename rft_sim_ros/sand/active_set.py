"""The bookkeeping the implicit solve's active-set iteration shares across its elements
(plates, frictional joints, MuJoCo's constraint rows; `implicit_solve._implicit_step`): each
element is in one of a few sets (its law's linear pieces, by a small code), a solve asks
each for a set, and an element that would return to a set it already had in the step is
frozen (FROZEN) for the rest of it, which ends the cycles a non-monotone law can make.
Each kind of element keeps int8 flags with rows STATE (its set), VISITED (a bit per set had
this step) and SOLVED (the set the last solve used)."""
from numba import njit

#: The set code of a frozen element (every kind's own codes are below it).
FROZEN = 3
#: Rows of an element's flags.
STATE, VISITED, SOLVED = 0, 1, 2
#: An element's memory of its set in its last step (plates in the sand, frictional joints) is
#: one int64: step << MEMORY_SHIFT | set.
MEMORY_SHIFT = 2


@njit(cache=True, inline='always')
def next_set(flags, e, new):
    """Element e (a frictional joint, a constraint row) after a solve: its set as solved kept
    in SOLVED, then the set `new` its solution asks for, unless frozen; a return to a set it
    had this step (a cycle) freezes it. Returns (moved, cycle), each 0 or 1."""
    old = flags[STATE, e]
    flags[SOLVED, e] = old
    if old == FROZEN or new == old:
        return 0, 0
    cycle = (flags[VISITED, e] >> new) & 1
    new = FROZEN if cycle else new
    flags[STATE, e] = new
    flags[VISITED, e] |= 1 << new
    return 1, cycle


@njit(cache=True, inline='always')
def remembered(memory, last):
    """The set an element had in the step before by its memory (`MEMORY_SHIFT`; last: that
    step << MEMORY_SHIFT), or -1 where it was not in that step or was frozen in it."""
    previous = memory - last
    return previous if (previous >= 0) & (previous < FROZEN) else -1
