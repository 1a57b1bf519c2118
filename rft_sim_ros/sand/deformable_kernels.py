"""The compiled kernels of deformable sand (`deformable`, whose docstring states the rules):
the plates' footprint marks (`touch_cell`, `mark_cell`, inlined into the gather kernel),
rules 2-4 for the footprints of a step (`settle`) and the avalanche (`avalanche`).
Heights in m, grid indices [iy, ix] as `deformable.DeformableSand.grid`."""
from numba import njit

from ..kernel_cache import forget_stale
from .deformable_codes import (COUNT, DIRTY, EPOCH, HEAD, MAX_VISITS, NEAR, OUTSIDE, QUEUED,
                               SETTLED, UNSETTLED)
from .surface import BLOCK


@njit(cache=True, inline='always')
def touch_cell(footprints, step, u, v, z):
    """`mark_cell` for a plate at node coordinates (u, v), anywhere: on the bed's far edges
    (u = nx - 1, v = ny - 1) in their last cell; outside the bed it is only counted
    (state[OUTSIDE])."""
    ny, nx = footprints[0].shape
    if u < 0.0 or v < 0.0 or u > nx - 1 or v > ny - 1:
        footprints[3][OUTSIDE] += 1
        return
    mark_cell(footprints, step, min(int(u), nx - 2), min(int(v), ny - 2), z)


@njit(cache=True, inline='always')
def mark_cell(footprints, step, i, j, z):
    """Rule 1 for a plate at height z (m) in the cell of lower-left node (i, j), at `step`:
    the cell's four nodes marked as under a plate at z. A cell is marked once a step, and
    again only for a lower z (its step and lowest z in cell_stamp, cell_low), so each node
    ends the step with the lowest z of the plates in its cells, and nodes join `pending` in
    the order their cells were first touched. footprints: (stamp, lowest, pending, state,
    cell_stamp, cell_low) (`DeformableSand.kernel_arrays`)."""
    stamp, lowest, pending, state, cell_stamp, cell_low = footprints
    if cell_stamp[j, i] == step and z >= cell_low[j, i]:
        return
    cell_stamp[j, i], cell_low[j, i] = step, z
    nx = stamp.shape[1]
    _mark_node(stamp, lowest, pending, state, nx, step, i, j, z)
    _mark_node(stamp, lowest, pending, state, nx, step, i + 1, j, z)
    _mark_node(stamp, lowest, pending, state, nx, step, i, j + 1, z)
    _mark_node(stamp, lowest, pending, state, nx, step, i + 1, j + 1, z)


@njit(cache=True, inline='always')
def _mark_node(stamp, lowest, pending, state, nx, step, i, j, z):
    if stamp[j, i] < 0:
        pending[state[COUNT]] = j * nx + i
        state[COUNT] += 1
        lowest[j, i] = z
    elif z < lowest[j, i]:
        lowest[j, i] = z
    stamp[j, i] = step


@njit(cache=True)
def settle(grid, block_max, block_min, stamp, lowest, pending, state, committed, amount, queue,
           in_queue, dirty, dirty_list, changed, distance, reached, step, rise):
    """Rules 2-4 (module docstring) for the nodes that were pending before `step`; `rise`:
    see `avalanche`; `changed`: see `_refresh_dirty`; distance, reached: see
    `_free_distances`."""
    ny, nx = grid.shape
    count = state[COUNT]
    kept = 0
    n_committed = 0
    for p in range(count):
        index = pending[p]
        j, i = index // nx, index % nx
        if stamp[j, i] == step:
            pending[kept] = index
            kept += 1
            continue
        stamp[j, i] = -2  # committed in this step (not a rim node)
        committed[n_committed] = index
        amount[n_committed] = max(grid[j, i] - lowest[j, i], 0.0)
        grid[j, i] -= amount[n_committed]
        n_committed += 1
    state[COUNT] = kept
    searched, found = False, 0  # `_free_distances` run yet; the nodes it set
    for c in range(n_committed):
        if amount[c] <= 0.0:
            continue
        j, i = committed[c] // nx, committed[c] % nx
        ring, free = 0, 0
        while free == 0 and ring < NEAR:
            ring += 1
            free = _ring_free(stamp, i, j, ring)
        if free == 0:  # inside a wide footprint: every committed node's distance at once
            if not searched:
                found = _free_distances(stamp, pending, kept, committed, n_committed,
                                        distance, reached)
                searched = True
            ring = distance[j, i]
            free = _ring_free(stamp, i, j, ring) if ring > 0 else 0
        if free == 0:  # no free node on the bed: the node keeps its sand
            grid[j, i] += amount[c]
        else:
            _deposit(grid, stamp, queue, in_queue, state, dirty, dirty_list, i, j, ring, free,
                     amount[c])
    for t in range(found):  # (back to none found, for the next step that needs them)
        distance[reached[t] // nx, reached[t] % nx] = -1
    for c in range(n_committed):
        j, i = committed[c] // nx, committed[c] % nx
        stamp[j, i] = -1
        _enqueue(queue, in_queue, state, nx, i, j)  # free again: its slopes are checked
        _mark_dirty(dirty, dirty_list, state, i, j)
    if state[QUEUED]:
        avalanche(grid, stamp, queue, in_queue, state, dirty, dirty_list, rise, MAX_VISITS)
        state[UNSETTLED] += state[QUEUED] > 0
    _refresh_dirty(grid, block_max, block_min, dirty, dirty_list, changed, state)


@njit(cache=True, inline='always')
def _enqueue(queue, in_queue, state, nx, i, j):
    """Add node (i, j) to the avalanche's queue, unless it is in it."""
    if in_queue[j, i]:
        return
    in_queue[j, i] = 1
    size = queue.shape[0]
    queue[(state[HEAD] + state[QUEUED]) % size] = j * nx + i
    state[QUEUED] += 1


@njit(cache=True, inline='always')
def _mark_dirty(dirty, dirty_list, state, i, j):
    """Note the blocks holding node (i, j) for `_refresh_dirty`."""
    nby, nbx = dirty.shape
    for bj in range(max((j - 1) // BLOCK, 0), min(j // BLOCK, nby - 1) + 1):
        for bi in range(max((i - 1) // BLOCK, 0), min(i // BLOCK, nbx - 1) + 1):
            if not dirty[bj, bi]:
                dirty[bj, bi] = 1
                dirty_list[state[DIRTY]] = bj * nbx + bi
                state[DIRTY] += 1


@njit(cache=True)
def _refresh_dirty(grid, block_max, block_min, dirty, dirty_list, changed, state):
    """Recompute the maxima and minima of the blocks `_mark_dirty` noted, and stamp them
    in `changed` with a new change epoch (state[EPOCH]) where there are any."""
    ny, nx = grid.shape
    nbx = dirty.shape[1]
    state[EPOCH] += state[DIRTY] > 0
    for d in range(state[DIRTY]):
        bj, bi = dirty_list[d] // nbx, dirty_list[d] % nbx
        low, high = 1e300, -1e300
        for j in range(bj * BLOCK, min((bj + 1) * BLOCK, ny - 1) + 1):
            for i in range(bi * BLOCK, min((bi + 1) * BLOCK, nx - 1) + 1):
                low, high = min(low, grid[j, i]), max(high, grid[j, i])
        block_max[bj, bi], block_min[bj, bi] = high, low
        changed[bj, bi] = state[EPOCH]
        dirty[bj, bi] = 0
    state[DIRTY] = 0


@njit(cache=True, inline='always')
def _ring_free(stamp, i, j, r):
    """The free nodes (neither pending nor just committed) on the ring at Chebyshev distance
    r >= 1 around node (i, j), clipped to the bed."""
    ny, nx = stamp.shape
    free = 0
    for jj in range(max(j - r, 0), min(j + r, ny - 1) + 1):
        step = 1 if abs(jj - j) == r else 2 * r  # (its top and bottom rows, else two nodes)
        for ii in range(i - r, i + r + 1, step):
            if 0 <= ii < nx and stamp[jj, ii] == -1:
                free += 1
    return free


@njit(cache=True)
def _deposit(grid, stamp, queue, in_queue, state, dirty, dirty_list, i, j, r, free,
             volume_height):
    """Rule 3: spread `volume_height` (m of one node) evenly over the `free` free nodes of
    the ring at Chebyshev distance r around (i, j) (`_ring_free`), queued for the avalanche."""
    ny, nx = grid.shape
    share = volume_height / free
    given = 0.0
    for jj in range(max(j - r, 0), min(j + r, ny - 1) + 1):
        step = 1 if abs(jj - j) == r else 2 * r
        for ii in range(i - r, i + r + 1, step):
            if 0 <= ii < nx and stamp[jj, ii] == -1:
                free -= 1
                part = volume_height - given if free == 0 else share
                grid[jj, ii] += part
                given += part
                _enqueue(queue, in_queue, state, nx, ii, jj)
                _mark_dirty(dirty, dirty_list, state, ii, jj)


@njit(cache=True)
def _free_distances(stamp, pending, kept, committed, n_committed, distance, reached):
    """The Chebyshev distance of every node under a body (the `kept` pending and
    `n_committed` committed nodes) to the nearest free node, into `distance` (nodes; -1
    where no free node is reachable), by one breadth-first pass from the free nodes beside
    them through them (a shortest way from a node to its nearest free node passes only
    nodes under bodies, else one of those would be nearer). Returns the count of nodes it
    set, listed in `reached` (flat indices), for setting them back to -1 after use."""
    ny, nx = stamp.shape
    tail = 0
    for source in range(kept + n_committed):
        index = pending[source] if source < kept else committed[source - kept]
        j, i = index // nx, index % nx
        for jj in range(max(j - 1, 0), min(j + 1, ny - 1) + 1):
            for ii in range(max(i - 1, 0), min(i + 1, nx - 1) + 1):
                if stamp[jj, ii] == -1 and distance[jj, ii] < 0:
                    distance[jj, ii] = 0
                    reached[tail] = jj * nx + ii
                    tail += 1
    head = 0
    while head < tail:
        index = reached[head]
        head += 1
        j, i = index // nx, index % nx
        for jj in range(max(j - 1, 0), min(j + 1, ny - 1) + 1):
            for ii in range(max(i - 1, 0), min(i + 1, nx - 1) + 1):
                if stamp[jj, ii] != -1 and distance[jj, ii] < 0:
                    distance[jj, ii] = distance[j, i] + 1
                    reached[tail] = jj * nx + ii
                    tail += 1
    return tail


@njit(cache=True)
def avalanche(grid, stamp, queue, in_queue, state, dirty, dirty_list, rise, visits):
    """Rule 4 over the queued nodes (up to `visits` of them): `rise` (m) is the largest
    height difference allowed between axis neighbours (tan(repose) x cell; x sqrt 2 between
    diagonal ones). A visited node that is not pending brings each free neighbour that is
    too far above or below it to the limit (half the excess each way) and queues it, and is
    queued again itself when it moved sand. Returns the visits made."""
    ny, nx = grid.shape
    size = queue.shape[0]
    done = 0
    while state[QUEUED] > 0 and done < visits:
        index = queue[state[HEAD]]
        state[HEAD] = (state[HEAD] + 1) % size
        state[QUEUED] -= 1
        j, i = index // nx, index % nx
        in_queue[j, i] = 0
        done += 1
        if stamp[j, i] >= 0:
            continue
        moved = False
        for jj in range(max(j - 1, 0), min(j + 1, ny - 1) + 1):
            for ii in range(max(i - 1, 0), min(i + 1, nx - 1) + 1):
                if (ii == i and jj == j) or stamp[jj, ii] >= 0:
                    continue
                limit = rise * (1.4142135623730951 if ii != i and jj != j else 1.0)
                diff = grid[j, i] - grid[jj, ii]
                excess = abs(diff) - limit
                if excess <= SETTLED * rise:
                    continue
                transfer = 0.5 * excess if diff > 0 else -0.5 * excess
                grid[j, i] -= transfer
                grid[jj, ii] += transfer
                moved = True
                _enqueue(queue, in_queue, state, nx, ii, jj)
                _mark_dirty(dirty, dirty_list, state, ii, jj)
        if moved:
            _enqueue(queue, in_queue, state, nx, i, j)
            _mark_dirty(dirty, dirty_list, state, i, j)
    return done


forget_stale(globals())  # (kernel_cache: drops kernels compiled from older sources)
