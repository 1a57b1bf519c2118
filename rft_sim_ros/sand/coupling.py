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

Joint friction (MJCF frictionloss F, N m or N) is solved in the same iteration, as the
regularised Coulomb law with the same v_reg: a joint whose end speed is below v_reg sticks
(a damper F / v_reg: at most F), otherwise it slips (F against its motion). The engine takes
it over from MuJoCo, whose friction constraint, acting after the sand's solve, would undo
the end velocities the solve chose and keep a standing robot jittering between sets. So
are MuJoCo's equality, limit and contact constraints, as the rows MuJoCo itself makes for
them (`constraint_rows`), in the same active-set iteration (`active_set`; joint friction's
law: `joint_friction`); a step whose rows do not settle leaves them to MuJoCo's solve.
"""
import types
from collections import namedtuple

import numpy as np
from numba import njit

from ..kernel_cache import forget_stale
from ..rft.kernel import (AREA, DIRECTION, LAW_ROWS, NORMAL, NORMAL_SPEED, SCALE,
                           leading_forces)
from ..rft.force_law import TANGENTIAL  # the leading rule, with the body's speed scale
from .active_set import FROZEN, MEMORY_SHIFT, SOLVED, STATE, VISITED, remembered
from .array_table import (byte_vector, float_matrix, float_vector, int8_matrix, int8_vector,
                          int32_matrix, int32_vector, int_matrix, int_vector)
from .constraint_rows import (ROW_FORCE, add_matrix, constraint_forces, constraint_sets,
                              constraint_start, constraint_terms)
from .deformable import OUTSIDE, mark_cell, settle, touch_cell
from .elliptic_cones import (CONE_ITERATIONS, cone_errors, cone_reports, cone_settled, cone_start,
                             cone_step, cone_terms)
from .joint_friction import friction_finish, friction_sets, friction_start, friction_terms
from .surface import FLAT, GRID, SLOPE
from .surface_kernels import (base_height, bed_range, cell_height, grid_range, inside_grid,
                              map_factor, node_height, plane_top, surface_range,
                              tile_plane, window_range)

MOVING, RESTING, OFF = 1, 0, 2  # a >= 1, 0 <= a < 1, a < 0 (and FROZEN: anti-cycling)

#: Solves per step at most (the active set settles in one or two almost always).
MAX_ITERATIONS = 16

#: Rows of the implicit law's per-plate work space (`implicit_wrenches`), plates along the
#: second axis: |G|, across damper c (N s/m), the set coefficients.
MAGNITUDE, ACROSS, COEF_ALONG, COEF_ACROSS, COEF_MOVING = 0, 1, 2, 3, 4
WORK_ROWS = 5
#: Rows of its per-plate flags (int8): those of `active_set` (final set, sets visited,
#: solved), then the set the last solve asks for.
WANTED = 3
FLAG_ROWS = 4


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


#: Rows of the gathered-plate table after the law's (`kernel.NORMAL` ... `kernel.DIRECTION`):
MOMENT = LAW_ROWS      # r x d, m (3 rows): rows DIRECTION .. MOMENT + 2 are u = [d; r x d]
LEVER = LAW_ROWS + 3   # lever arm r from the body's COM, m, world (3 rows)
SPEED = LAW_ROWS + 6   # |v|, m/s
PLATE_ROWS = LAW_ROWS + 7

#: The engine's settings, one float64 vector in both tables, by index: sand surface height
#: (m, world z; a slope's at the world origin), zeta (N/m^3), reciprocal normalisers 1/a4 and
#: 1/b4, lambda x rho of the dynamic term (kg/m^3), whether trailing plates are gathered too
#: (1/0), and the implicit law's rest speed v_reg (m/s), joint damping and actuator velocity
#: gains (1/0) implicit; then the surface (`surface.SurfaceData`; its kind is the gather
#: kernel's, `gather_kernel`): the slope's gradient dh/dx, dh/dy, the grid's node [0, 0]
#: (x, y) m and 1/spacing (1/m); the zeta map: whether there is one (1/0), its cell
#: [0, 0] corner (x, y) m and 1/cell (1/m); and, for deformable sand, its base beyond the
#: bed: the base's kind code, and a grid base's node [0, 0] (x, y) m and 1/spacing (1/m)
#: (a plane or slope base: SURFACE, SLOPE_X, SLOPE_Y, which the bed's grid does not use),
#: the height difference of axis neighbours at the angle of repose (m; `settle`), and a
#: rigid grid's tile step (nodes) of its bounding planes (`surface.tile_planes`; 0:
#: none).
(SURFACE, ZETA, INV_A4, INV_B4, DYNAMIC, TRAILING, REST_SPEED, DAMPER, ACTUATORS,
 SLOPE_X, SLOPE_Y, GRID_X0, GRID_Y0, GRID_INV_DX, GRID_INV_DY,
 ZETA_MAP, MAP_X0, MAP_Y0, MAP_INV_DX, MAP_INV_DY,
 BASE_KIND, BASE_X0, BASE_Y0, BASE_INV_DX, BASE_INV_DY, DEFORM_RISE,
 TILE_STEP) = range(27)
SETTING_COUNT = 27
#: Its counters, one int64 vector in both tables, by index: steps taken (gathers), plates
#: gathered at the last step, of those leading, slots, implicit solves so far, steps so
#: far in which a plate was frozen or the sets had not settled, MuJoCo's constraint rows
#: the engine took this step (`take_constraint_rows`), steps so far whose rows were handed
#: back to MuJoCo's solve (`implicit_wrenches`), and the last of them (its STEPS count).
(STEPS, GATHERED, LEADING, SLOTS, SOLVES, UNSETTLED, CONSTRAINT_ROWS, HANDED_BACK,
 HANDED_BACK_AT) = range(9)
COUNTER_COUNT = 9

#: The arrays of the gather kernels (`_gather_plates`), in the order of their `ArrayTable`;
#: GATHER holds each field's row of the table. The engine builds the table from a
#: GatherArrays by name, so the order lives here only.
GatherArrays = namedtuple('GatherArrays', [
    # the engine's settings and counters, plates and clusters
    'settings', 'counters', 'body_ids', 'radii', 'body_cluster_start', 'cluster_plate_start',
    'cluster_center', 'cluster_radius', 'positions', 'normals', 'areas',
    # the surface's grid, block maximum and minimum (`surface.SurfaceData`), a rigid grid's
    # tile planes (`surface.tile_planes`) and window maximum and minimum
    # (`surface.window_extremes`); zeta map factors; deformable sand's base grid, block
    # maximum and minimum (beyond the bed; a grid base)
    'surface_grid', 'surface_block_max', 'surface_block_min', 'surface_tiles',
    'surface_window_max', 'surface_window_min', 'zeta_factors',
    'base_grid', 'base_block_max', 'base_block_min',
    # deformable sand's footprint marks and settling (`DeformableSand.kernel_arrays`)
    'deform_stamp', 'deform_lowest', 'deform_pending', 'deform_state', 'deform_cell_stamp',
    'deform_cell_low', 'deform_committed', 'deform_amount', 'deform_queue', 'deform_in_queue',
    'deform_dirty', 'deform_dirty_list', 'deform_changed', 'deform_distance', 'deform_reached',
    # mjData, mjModel
    'xpos', 'xmat', 'xipos', 'cvel', 'subtree_com', 'body_rootid',
    # outputs
    'out_plate', 'out_slot', 'slot_body', 'slot_start', 'table', 'force'])
GATHER = GatherArrays(*range(len(GatherArrays._fields)))

#: The implicit solve's work space, allocated once by the engine (`solve_space`), so that a
#: step allocates nothing: per slot (S <= sand bodies) its kinematic chain (dofs) and their
#: count, its translational inverse effective mass, accumulators (w_moving, k_rank: S 6x6
#: blocks stacked, k_iso) and a flag to sum them again; per dof the momentum Mh qvel +
#: dt tau_free, the system and its right-hand side, a factored copy and the solution, the
#: tree factor of Mh and its solve for the 3S translational Jacobian rows; per slot its
#: twist response (`_resting_block`, S 6x6 blocks stacked) and its terms of the system
#: (`_slot_terms`: S nv x nv blocks stacked, of which its chain's corner is used; S rows of
#: nv); `_slot_terms`' rows; and the two-sided constraint rows' part of the system (nv x nv).
SolveSpace = namedtuple('SolveSpace', [
    'chain', 'chain_count', 'inverse_mass', 'w_moving', 'k_rank', 'k_iso', 'dirty',
    'momentum', 'system', 'rhs', 'factored', 'solution', 'factor', 'translational', 'blocks',
    'products', 'force_terms', 'chain_work', 'constraint_matrix'])


def solve_space(nv, bodies):
    """A SolveSpace for a model with nv dofs and `bodies` sand bodies."""
    return SolveSpace(
        chain=np.zeros((bodies, nv), dtype=np.int64), chain_count=np.zeros(bodies, np.int64),
        inverse_mass=np.zeros(bodies), w_moving=np.zeros((bodies, 6)),
        k_rank=np.zeros((6 * bodies, 6)), k_iso=np.zeros((bodies, 10)),
        dirty=np.zeros(bodies, dtype=np.int8), momentum=np.zeros(nv),
        system=np.zeros((nv, nv)), rhs=np.zeros(nv), factored=np.zeros((nv, nv)),
        solution=np.zeros(nv), factor=np.zeros((nv, nv)), translational=np.zeros((nv, 3 * bodies)),
        blocks=np.zeros((6 * bodies, 6)), products=np.zeros((nv * bodies, nv)),
        force_terms=np.zeros((bodies, nv)), chain_work=np.zeros((12, nv)),
        constraint_matrix=np.zeros((nv, nv)))


#: The arrays of `implicit_step`, likewise (IMPLICIT: their rows), ending with a SolveSpace.
ImplicitArrays = namedtuple('ImplicitArrays', [
    # the engine's settings and counters, the gathered plates (`_gather_plates`)
    'settings', 'counters', 'slot_body', 'slot_start', 'out_plate', 'table', 'force',
    # the sand bodies, mjModel, mjData
    'body_ids', 'body_rootid', 'body_dofnum', 'body_dofadr', 'body_parentid', 'dof_parentid',
    'xipos', 'subtree_com', 'cdof', 'qvel', 'qfrc_passive', 'qfrc_actuator', 'qfrc_applied',
    'qfrc_constraint', 'qfrc_bias',
    # the constraint force of the rows left to MuJoCo held over a step whose rows were handed
    # back (`implicit_step`), and the end velocities the cones are linearised at
    # (`implicit_wrenches`)
    'held_constraint', 'cone_point',
    # joint friction the engine solves (`implicit_wrenches`' friction)
    'friction_dofs', 'friction_force', 'friction_memory', 'friction_flags',
    'friction_torque',
    # MuJoCo's constraint rows the engine solves (`take_constraint_rows`): Jacobian rows,
    # their nonzero columns and counts, their columns ROW_D ... and their sets' flags
    'constraint_jac', 'constraint_columns', 'constraint_counts', 'constraint_rows',
    'constraint_flags',
    # implicit_damping's model and data arrays
    'dof_damping', 'trntype', 'trnid', 'gear', 'jnt_type', 'jnt_dofadr', 'dyntype',
    'gaintype', 'gainprm', 'biastype', 'biasprm', 'forcelimited', 'forcerange', 'ctrl', 'act',
    'actadr', 'actuator_force',
    # work space and results
    'damping', 'mass', 'jac', 'memory', 'work', 'flags', 'xi_new',
    'wrench', 'body_wrenches', 'xfrc_applied', 'wrench_sum', *SolveSpace._fields])
IMPLICIT = ImplicitArrays(*range(len(ImplicitArrays._fields)))


#: The kind of surface (surface.FLAT, SLOPE or GRID) and whether it is deformable sand, of a
#: gather kernel: `_gather_plates` reads them as globals, which each kernel binds to its own
#: constants (`_gather_kernel`). None here: `_gather_plates` itself is never run.
KIND = DEFORM = None


def _gather_plates(arrays):
    """Find the plates in the sand and their RFT force for the current direction of motion:
    one step (counted in the STEPS counter); on deformable sand, then rules 2-4 for the
    footprints the bodies left in this step (`deformable.settle`). KIND (surface.FLAT, SLOPE
    or GRID) and DEFORM (deformable sand: a GRID) are constants each gather kernel binds
    (`_gather_kernel`), so that each kind of surface runs a plate loop of its own.

    arrays: the table of an `ArrayTable` of `GatherArrays`; settings SURFACE ... TRAILING.

    Bodies whose bounding sphere (radius `radii`, about the body origin), and then clusters
    whose bounding sphere, lies above the surface (above its highest point within the
    sphere's radius, horizontally) are skipped without touching their plates. A plate's
    depth is the surface height at its (x, y) minus its z (vertical, world axes): a
    horizontal plane (FLAT) keeps the original arithmetic, bit for bit, and so
    does a grid level under the cluster (its lowest node there == its highest: every
    bilinear height there is that level exactly; where the blocks are level under the body's
    whole sphere, its clusters are not bounded one by one); elsewhere on a grid only plates
    below the highest node under the cluster read the grid (a body a cell inside the grid
    all round without clamping: `inside_grid`, in a plate loop of its own: `_grid_cluster`).
    The nodes under a cluster are bounded on a rigid grid by the window from the first node
    of the cluster's square (`window_range`), on deformable sand by its blocks; or, on a
    rigid grid near a plane around the body (its tile's raised plane, `tile_plane`; a level
    tile has none), the plates below that plane's highest point over the cluster read the
    grid, the body itself bounded by that plane's highest point over its square instead of
    the blocks. On deformable sand
    (DEFORM) the plates below the surface mark their footprint cells
    (`deformable.mark_cell`), and the footprints the bodies left are settled after the
    plates are gathered (`gather_deformable`); beyond the bed its base (plane, slope or
    grid: `_deformable_base`) gives the depth, and bounds the bodies and clusters that reach
    out there, and a plate there marks nothing.
    positions, normals: (N, 3) body-frame plate positions l and normals n_l (separate, so
    that the depth test reads positions only). A plate below the surface first has
    n . v = n_l . (V + W x l) with the body-frame velocity V of the body origin and angular
    velocity W (9 multiply-adds), so only leading plates (n . v > TANGENTIAL x the body's
    speed scale), or all plates below the surface with TRAILING, are transformed to the
    world. Where a rigid grid is read (not level under the cluster), that motion test comes
    before the depth, being cheaper than a bilinear look-up: a trailing plate is dropped
    without one (the plates gathered are the same).
    With a zeta map (ZETA_MAP), a plate's zeta is multiplied by the map's factor at its (x, y).
    For each, column k of `table` (rows: kernel's NORMAL ... DIRECTION, then MOMENT, LEVER,
    SPEED; a trailing plate has SCALE and AREA 0, so it feels no force), out_plate[k] (plate
    index), out_slot[k] (slot) and the RFT force force[:3, k] (N, world). Counts the plates
    written, of those leading, and the slots S (counters GATHERED, LEADING, SLOTS);
    slot_body[s] is the slot's sand-body index, and its plates are columns slot_start[s] ..
    slot_start[s+1]-1.
    """
    a = GATHER
    settings, counters = float_vector(arrays, a.settings), int_vector(arrays, a.counters)
    surface_height, zeta_si = settings[SURFACE], settings[ZETA]
    include_trailing = settings[TRAILING] != 0.0
    flat, slope = KIND == FLAT, KIND == SLOPE
    gx, gy = settings[SLOPE_X], settings[SLOPE_Y]
    g_norm = np.sqrt(gx * gx + gy * gy)
    gx0, gy0 = settings[GRID_X0], settings[GRID_Y0]
    g_idx, g_idy = settings[GRID_INV_DX], settings[GRID_INV_DY]
    grid = float_matrix(arrays, a.surface_grid)
    block_max = float_matrix(arrays, a.surface_block_max)
    block_min = float_matrix(arrays, a.surface_block_min)
    tiles, tile_step = float_matrix(arrays, a.surface_tiles), np.int64(settings[TILE_STEP])
    window_max = float_matrix(arrays, a.surface_window_max)
    window_min = float_matrix(arrays, a.surface_window_min)
    zeta_map = settings[ZETA_MAP] != 0.0
    factors = float_matrix(arrays, a.zeta_factors)
    mx0, my0 = settings[MAP_X0], settings[MAP_Y0]
    m_idx, m_idy = settings[MAP_INV_DX], settings[MAP_INV_DY]
    deform_state = int_vector(arrays, a.deform_state)
    footprints = (int_matrix(arrays, a.deform_stamp), float_matrix(arrays, a.deform_lowest),
                  int_vector(arrays, a.deform_pending), deform_state,
                  int_matrix(arrays, a.deform_cell_stamp), float_matrix(arrays, a.deform_cell_low))
    bed_u, bed_v = grid.shape[1] - 1.0, grid.shape[0] - 1.0  # deformable sand: the bed's
    # last node coordinates; beyond them its base (`_deformable_base`)
    step = counters[STEPS]
    body_ids, radii = int_vector(arrays, a.body_ids), float_vector(arrays, a.radii)
    body_cluster_start = int_vector(arrays, a.body_cluster_start)
    cluster_plate_start = int_vector(arrays, a.cluster_plate_start)
    cluster_center = float_matrix(arrays, a.cluster_center)
    cluster_radius = float_vector(arrays, a.cluster_radius)
    positions, normals = float_matrix(arrays, a.positions), float_matrix(arrays, a.normals)
    areas = float_vector(arrays, a.areas)
    xpos, xmat = float_matrix(arrays, a.xpos), float_matrix(arrays, a.xmat)
    xipos, cvel = float_matrix(arrays, a.xipos), float_matrix(arrays, a.cvel)
    subtree_com = float_matrix(arrays, a.subtree_com)
    body_rootid = int32_vector(arrays, a.body_rootid)
    out_plate, out_slot = int_vector(arrays, a.out_plate), int_vector(arrays, a.out_slot)
    slot_body, slot_start = int_vector(arrays, a.slot_body), int_vector(arrays, a.slot_start)
    table = float_matrix(arrays, a.table)
    force = float_matrix(arrays, a.force)
    law = (zeta_si, areas, zeta_map, factors, mx0, my0, m_idx, m_idy, out_plate)
    k = np.int64(0)  # (typed, not Literal[int](0): that compiled the calls below twice)
    px = py = 0.0  # a plate's world x, y (m), as the depth on a grid needs them
    leading_count = 0
    slots = 0
    for i in range(body_ids.shape[0]):
        b = body_ids[i]
        # a grid reaching a cell beyond the body's sphere all round: its plates are looked
        # up unclamped; on deformable sand, otherwise they may lie beyond the bed (its base)
        inside = KIND == GRID and inside_grid(grid, gx0, gy0, g_idx, g_idy, xpos[b, 0],
                                              xpos[b, 1], radii[i])
        off_bed = DEFORM and not inside
        # a rigid grid near a plane (not level) around the body: that plane bounds it over the
        # body's square (its tile's: `tile_plane`), without reading the blocks there
        planar, p_a, p_gx, p_gy = False, 0.0, 0.0, 0.0
        if KIND == GRID and not DEFORM and inside and tile_step > 0:
            planar, p_a, p_gx, p_gy = tile_plane(tiles, tile_step, grid.shape[1], gx0, gy0,
                                                 g_idx, g_idy, xpos[b, 0], xpos[b, 1], radii[i])
        if planar:
            body_low = -np.inf  # (not level: the grid is read)
            body_top = plane_top(p_a, p_gx, p_gy, xpos[b, 0], xpos[b, 1], radii[i])
        elif DEFORM:
            body_low, body_top = bed_range(grid, block_max, block_min, gx0, gy0, g_idx, g_idy,
                                           xpos[b, 0], xpos[b, 1], radii[i],
                                           _deformable_base(arrays))
        else:
            body_low, body_top = surface_range(KIND, surface_height, gx, gy, g_norm, grid,
                                               block_max, block_min, gx0, gy0, g_idx, g_idy,
                                               xpos[b, 0], xpos[b, 1], radii[i])
        if xpos[b, 2] - radii[i] >= body_top:
            continue
        top = body_top
        first = k
        root = body_rootid[b]
        ox, oy, oz = xpos[b, 0], xpos[b, 1], xpos[b, 2]
        r00, r01, r02 = xmat[b, 0], xmat[b, 1], xmat[b, 2]
        r10, r11, r12 = xmat[b, 3], xmat[b, 4], xmat[b, 5]
        r20, r21, r22 = xmat[b, 6], xmat[b, 7], xmat[b, 8]
        # cvel = [omega; velocity of the point at the root's subtree com], world
        wx, wy, wz = cvel[b, 0], cvel[b, 1], cvel[b, 2]
        cx, cy, cz = subtree_com[root, 0], subtree_com[root, 1], subtree_com[root, 2]
        vcx, vcy, vcz = cvel[b, 3], cvel[b, 4], cvel[b, 5]
        comx, comy, comz = xipos[b, 0], xipos[b, 1], xipos[b, 2]
        rotation = (r00, r01, r02, r10, r11, r12, r20, r21, r22)
        motion = (cx, cy, cz, vcx, vcy, vcz, wx, wy, wz, comx, comy, comz)
        vx0 = vcx + wy * (oz - cz) - wz * (oy - cy)  # velocity of the body origin
        vy0 = vcy + wz * (ox - cx) - wx * (oz - cz)
        vz0 = vcz + wx * (oy - cy) - wy * (ox - cx)
        body_v = (r00 * vx0 + r10 * vy0 + r20 * vz0, r01 * vx0 + r11 * vy0 + r21 * vz0,
                  r02 * vx0 + r12 * vy0 + r22 * vz0)
        body_w = (r00 * wx + r10 * wy + r20 * wz, r01 * wx + r11 * wy + r21 * wz,
                  r02 * wx + r12 * wy + r22 * wz)
        tangential = TANGENTIAL * (np.sqrt(vx0 * vx0 + vy0 * vy0 + vz0 * vz0)
                                   + radii[i] * np.sqrt(wx * wx + wy * wy + wz * wz))
        # a slope's depth is linear in the body-frame position: surface_height minus
        # (z - gx x - gy y) = s_0 + s . l
        s_0 = oz - gx * ox - gy * oy
        s_x, s_y = r20 - gx * r00 - gy * r10, r21 - gx * r01 - gy * r11
        s_z = r22 - gx * r02 - gy * r12
        for c in range(body_cluster_start[i], body_cluster_start[i + 1]):
            ccx, ccy, ccz = cluster_center[c, 0], cluster_center[c, 1], cluster_center[c, 2]
            # the surface under the cluster: level at `level`, or (lookup) a grid to read
            level, lookup = surface_height, False
            if slope:
                if (s_0 + s_x * ccx + s_y * ccy + s_z * ccz - cluster_radius[c]
                        >= surface_height + cluster_radius[c] * g_norm):
                    continue
            else:
                bottom = oz + r20 * ccx + r21 * ccy + r22 * ccz - cluster_radius[c]
                if flat or body_low == body_top:  # level under the body: under the cluster
                    level = body_top
                else:
                    if bottom >= body_top:  # (above the body's bound: nothing to read)
                        continue
                    wx_c = ox + r00 * ccx + r01 * ccy + r02 * ccz  # the cluster's centre
                    wy_c = oy + r10 * ccx + r11 * ccy + r12 * ccz
                    if planar:  # the body's tile plane, at its highest over the cluster
                        top = plane_top(p_a, p_gx, p_gy, wx_c, wy_c, cluster_radius[c])
                        low = -np.inf  # (not level: the grid is read)
                    elif not DEFORM:  # a rigid grid: the window over the cluster
                        low, top = window_range(window_max, window_min, gx0, gy0, g_idx,
                                                g_idy, wx_c, wy_c, cluster_radius[c])
                    elif off_bed:  # (deformable sand, a body reaching beyond the bed)
                        low, top = bed_range(grid, block_max, block_min, gx0, gy0, g_idx,
                                             g_idy, wx_c, wy_c, cluster_radius[c],
                                             _deformable_base(arrays))
                    else:
                        low, top = grid_range(grid, block_max, block_min, gx0, gy0, g_idx,
                                              g_idy, wx_c, wy_c, cluster_radius[c])
                    level, lookup = top, low != top
                if bottom >= top:
                    continue
            j0 = cluster_plate_start[c]
            j1 = cluster_plate_start[c + 1]
            cluster, cluster_normals = positions[j0:j1], normals[j0:j1]  # (no wraparound)
            if KIND == GRID and lookup and inside:  # (the grids' common case)
                k, leading_count = _grid_cluster(
                    DEFORM, j0, cluster, cluster_normals, (ox, oy, oz), rotation, top,
                    (body_v, body_w, tangential, include_trailing), (grid, gx0, gy0, g_idx,
                    g_idy), (footprints, step), motion, law, table, out_slot, slots, k,
                    leading_count)
                continue
            plain = not (slope or lookup or DEFORM)  # a plane, or a rigid grid level here
            # a rigid grid read here: the motion test (cheaper than a look-up) comes first
            motion_first = KIND == GRID and lookup and not DEFORM
            for i_c in range(cluster.shape[0]):
                lx, ly, lz = cluster[i_c, 0], cluster[i_c, 1], cluster[i_c, 2]
                pz = oz + r20 * lx + r21 * ly + r22 * lz
                n_v = 0.0
                if motion_first:
                    if pz >= top:  # above the highest node under the cluster
                        continue
                    n_v = _normal_speed(cluster_normals, i_c, body_v, body_w, lx, ly, lz)
                    if not (n_v > tangential or include_trailing):
                        continue
                if plain:
                    depth = level - pz
                elif slope:
                    depth = surface_height - (s_0 + s_x * lx + s_y * ly + s_z * lz)
                elif lookup and pz >= top:  # above the highest node under the cluster
                    continue
                else:  # a grid, at the plate's node coordinates (u, v)
                    px = ox + r00 * lx + r01 * ly + r02 * lz
                    py = oy + r10 * lx + r11 * ly + r12 * lz
                    u, v = (px - gx0) * g_idx, (py - gy0) * g_idy
                    if inside:  # (level here: a grid read is `_grid_cluster`'s)
                        depth = level - pz
                        if DEFORM and depth > 0.0:
                            mark_cell(footprints, step, int(u), int(v), pz)
                    elif off_bed and (u < 0.0 or v < 0.0 or u > bed_u or v > bed_v):
                        # beyond the bed: its base, where a plate leaves no footprint
                        depth = (base_height(_deformable_base(arrays), px, py) if lookup
                                 else level) - pz
                        deform_state[OUTSIDE] += depth > 0.0
                    else:
                        depth = (node_height(grid, u, v) if lookup else level) - pz
                        if DEFORM and depth > 0.0:
                            touch_cell(footprints, step, u, v, pz)
                if depth <= 0.0:
                    continue
                if not motion_first:
                    n_v = _normal_speed(cluster_normals, i_c, body_v, body_w, lx, ly, lz)
                leading = n_v > tangential
                if not (leading or include_trailing):
                    continue
                if plain or slope:  # (a grid's: above)
                    px = ox + r00 * lx + r01 * ly + r02 * lz
                    py = oy + r10 * lx + r11 * ly + r12 * lz
                _write_plate(table, k, cluster_normals, i_c, rotation, motion, law, px, py, pz,
                             n_v, depth, j0 + i_c, leading)
                out_slot[k] = slots
                leading_count += leading
                k += 1
        if k > first:
            slot_body[slots] = i
            slot_start[slots] = first
            slots += 1
    slot_start[slots] = k
    _directions(k, table)
    leading_forces(k, table, settings[INV_A4], settings[INV_B4], settings[DYNAMIC], force[0],
                   force[1], force[2])
    counters[STEPS] += 1
    counters[GATHERED], counters[LEADING], counters[SLOTS] = k, leading_count, slots
    if DEFORM:  # rules 2-4 for the footprints the bodies left in this step
        settle(float_matrix(arrays, a.surface_grid), float_matrix(arrays, a.surface_block_max),
               float_matrix(arrays, a.surface_block_min), int_matrix(arrays, a.deform_stamp),
               float_matrix(arrays, a.deform_lowest), int_vector(arrays, a.deform_pending),
               int_vector(arrays, a.deform_state), int_vector(arrays, a.deform_committed),
               float_vector(arrays, a.deform_amount), int_vector(arrays, a.deform_queue),
               int8_matrix(arrays, a.deform_in_queue), int8_matrix(arrays, a.deform_dirty),
               int_vector(arrays, a.deform_dirty_list), int_matrix(arrays, a.deform_changed),
               int32_matrix(arrays, a.deform_distance), int_vector(arrays, a.deform_reached),
               int_vector(arrays, a.counters)[STEPS] - 1,
               float_vector(arrays, a.settings)[DEFORM_RISE])


@njit(inline='always')
def _grid_cluster(deform, j0, cluster, cluster_normals, origin, rotation, top, test, surface,
                  marks, motion, law, table, out_slot, slots, k, leading_count):
    """The plates of one cluster (plate j0 its first) of a body a cell inside a grid that is
    read under the cluster (`_gather_plates`' common case on grids, with the loop's other
    cases left out): plates below `top` (m), on a rigid grid leading ones first (the motion
    test before the look-up), on deformable sand (`deform`) marking their footprint cells.
    origin, rotation: the body's pose; test: (body_v, body_w, tangential, include_trailing);
    surface: (grid, x0, y0, 1/dx, 1/dy); marks: (footprints, step). Returns k and
    leading_count, advanced."""
    ox, oy, oz = origin
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = rotation
    body_v, body_w, tangential, include_trailing = test
    grid, gx0, gy0, g_idx, g_idy = surface
    footprints, step = marks
    for i_c in range(cluster.shape[0]):
        lx, ly, lz = cluster[i_c, 0], cluster[i_c, 1], cluster[i_c, 2]
        pz = oz + r20 * lx + r21 * ly + r22 * lz
        if pz >= top:  # above the highest node under the cluster
            continue
        n_v = 0.0
        if not deform:  # the motion test first: it is cheaper than a look-up
            n_v = _normal_speed(cluster_normals, i_c, body_v, body_w, lx, ly, lz)
            if not (n_v > tangential or include_trailing):
                continue
        px = ox + r00 * lx + r01 * ly + r02 * lz
        py = oy + r10 * lx + r11 * ly + r12 * lz
        u, v = (px - gx0) * g_idx, (py - gy0) * g_idy
        i_u, i_v = int(u), int(v)  # (1 <= u <= nx - 2, likewise v)
        depth = cell_height(grid, i_u, i_v, u - i_u, v - i_v) - pz
        if depth <= 0.0:
            continue
        if deform:  # a trailing plate in the sand leaves a footprint too
            mark_cell(footprints, step, i_u, i_v, pz)
            n_v = _normal_speed(cluster_normals, i_c, body_v, body_w, lx, ly, lz)
        leading = n_v > tangential
        if not (leading or include_trailing):
            continue
        _write_plate(table, k, cluster_normals, i_c, rotation, motion, law, px, py, pz,
                     n_v, depth, j0 + i_c, leading)
        out_slot[k] = slots
        leading_count += leading
        k += 1
    return k, leading_count


@njit(inline='always')
def _write_plate(table, k, normals, i, rotation, motion, law, px, py, pz, n_v, depth, j,
                 leading):
    """Column k of the gathered table for plate j (i of `normals`, body frame) in the sand at
    world (px, py, pz), depth `depth` (m), normal speed n_v (`_gather_plates`)."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = rotation
    cx, cy, cz, vcx, vcy, vcz, wx, wy, wz, comx, comy, comz = motion
    zeta_si, areas, zeta_map, factors, mx0, my0, m_idx, m_idy, out_plate = law
    mx, my, mz = normals[i, 0], normals[i, 1], normals[i, 2]
    rx, ry, rz = px - cx, py - cy, pz - cz
    table[DIRECTION, k] = vcx + wy * rz - wz * ry  # v, made d by _directions
    table[DIRECTION + 1, k] = vcy + wz * rx - wx * rz
    table[DIRECTION + 2, k] = vcz + wx * ry - wy * rx
    table[LEVER, k], table[LEVER + 1, k] = px - comx, py - comy
    table[LEVER + 2, k] = pz - comz
    table[NORMAL, k] = r00 * mx + r01 * my + r02 * mz
    table[NORMAL + 1, k] = r10 * mx + r11 * my + r12 * mz
    table[NORMAL + 2, k] = r20 * mx + r21 * my + r22 * mz
    table[NORMAL_SPEED, k] = n_v
    scale = zeta_si * depth * areas[j]
    if zeta_map:
        scale *= map_factor(factors, mx0, my0, m_idx, m_idy, px, py)
    table[SCALE, k] = scale if leading else 0.0
    table[AREA, k] = areas[j] if leading else 0.0
    out_plate[k] = j


@njit(inline='always')
def _deformable_base(arrays):
    """Deformable sand's base beyond the bed (`surface_kernels.base_height`), from the gather
    table's settings (BASE_KIND; SURFACE, SLOPE_X, SLOPE_Y; BASE_X0 ...) and base arrays."""
    a = GATHER
    settings = float_vector(arrays, a.settings)
    gx, gy = settings[SLOPE_X], settings[SLOPE_Y]
    return (np.int64(settings[BASE_KIND]), settings[SURFACE], gx, gy, np.sqrt(gx * gx + gy * gy),
            float_matrix(arrays, a.base_grid), float_matrix(arrays, a.base_block_max),
            float_matrix(arrays, a.base_block_min), settings[BASE_X0], settings[BASE_Y0],
            settings[BASE_INV_DX], settings[BASE_INV_DY])


@njit(inline='always')
def _normal_speed(normals, i, body_v, body_w, lx, ly, lz):
    """n . v of plate i at body-frame position l = (lx, ly, lz) with body-frame normal
    normals[i], for the body-frame velocity V of the body origin and angular velocity W:
    n . (V + W x l), m/s."""
    mx, my, mz = normals[i, 0], normals[i, 1], normals[i, 2]
    return (mx * (body_v[0] + body_w[1] * lz - body_w[2] * ly)
            + my * (body_v[1] + body_w[2] * lx - body_w[0] * lz)
            + mz * (body_v[2] + body_w[0] * ly - body_w[1] * lx))


def _gather_kernel(name, kind, deform, doc):
    """The compiled `_gather_plates` of a surface of kind `kind` (deformable sand where
    `deform`), named `name`, documented by `doc`: the same code with its globals KIND and
    DEFORM bound to these constants. numba prunes the branches of the other surfaces before
    it types the code (its dead-branch pruning sees module constants, not argument values),
    so each kernel compiles its own surface's loop only: gather_plane took 9 s CPU to compile
    this way on an AMD EPYC VM, against 50 s as an inline='always' function called with
    constant arguments (numba's inliner copies a callee's whole scope once per block of it)
    and 37 s as a function compiled for literal arguments (no pruning); docs/speed.md."""
    function = types.FunctionType(_gather_plates.__code__,
                                  dict(globals(), KIND=kind, DEFORM=deform), name)
    function.__qualname__, function.__doc__ = name, doc
    return njit(cache=True, error_model='numpy', fastmath={'contract'})(function)


def gather_kernel(kind, deformable=False):
    """The compiled gather of a surface of kind `kind` (surface.FLAT, SLOPE, GRID), or of
    deformable sand (a GRID). Each compiles, or loads from numba's cache, at its first use
    only, so a scene pays for the kernel of its own surface."""
    if deformable:
        return gather_deformable
    return {FLAT: gather_plane, SLOPE: gather_slope, GRID: gather_grid}[kind]


@njit(cache=True, error_model='numpy', fastmath=True)
def _directions(k, table):
    """Rows DIRECTION, MOMENT and SPEED of the plate table from the plates' world velocity
    v (in rows DIRECTION, replaced) and lever arm r (rows LEVER): d = v/|v| (0 at rest),
    r x d, |v|. One vectorised pass."""
    for j in range(k):
        vx, vy, vz = table[DIRECTION, j], table[DIRECTION + 1, j], table[DIRECTION + 2, j]
        rx, ry, rz = table[LEVER, j], table[LEVER + 1, j], table[LEVER + 2, j]
        speed = np.sqrt(vx * vx + vy * vy + vz * vz)
        inv = 1.0 / speed if speed > 0.0 else 0.0
        dx, dy, dz = vx * inv, vy * inv, vz * inv
        table[DIRECTION, j], table[DIRECTION + 1, j], table[DIRECTION + 2, j] = dx, dy, dz
        table[MOMENT, j] = ry * dz - rz * dy
        table[MOMENT + 1, j] = rz * dx - rx * dz
        table[MOMENT + 2, j] = rx * dy - ry * dx
        table[SPEED, j] = speed


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
    MuJoCo's of the step before (`implicit_step`; mj_step2 computes this step's after the
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


@njit(cache=True, error_model='numpy', fastmath=True)
def _tree_factor(matrix, dof_parentid, factor):
    """L^T D L factor of an SPD joint-space matrix with the sparsity of MuJoCo's inertia (entry
    (i, j) nonzero only if one of dofs i, j is an ancestor of the other, as mj_fullM gives):
    MuJoCo's own factorisation (mj_factorM), eliminating from the leaves, which fills nothing
    in. Writes factor (nv, nv): D on the diagonal, the unit lower-triangular L below it
    (nonzero only at (dof, ancestor dof)), zero above. Rows are updated whole (zeros off the
    pattern stay zero), so the updates vectorise."""
    n = matrix.shape[0]
    for i in range(n):
        for j in range(n):
            factor[i, j] = matrix[i, j] if j <= i else 0.0
    for k in range(n - 1, -1, -1):
        inv = 1.0 / factor[k, k]
        row_k = factor[k]
        i = dof_parentid[k]
        while i >= 0:
            scale = row_k[i] * inv
            target, source = factor[i, :i + 1], row_k[:i + 1]
            for j in range(i + 1):
                target[j] -= source[j] * scale
            row_k[i] = scale
            i = dof_parentid[i]


@njit(cache=True, error_model='numpy', fastmath=True)
def _translational_inverse_masses(mass_h, dof_parentid, jac, slots, factor, work, out):
    """out[s] = sum over the 3 translational rows J_r of slot s of J_r Mh^-1 J_r^T
    (1/kg) = |D^-1/2 L^-T J_r^T|^2 with Mh = L^T D L (`_tree_factor`, into factor (nv, nv)),
    all 3S rows solved at once in work (nv, >= 3S) (their index innermost, so the loops
    vectorise)."""
    n, count = mass_h.shape[0], 3 * slots
    _tree_factor(mass_h, dof_parentid, factor)
    for s in range(slots):
        for a in range(3):
            for i in range(n):
                work[i, 3 * s + a] = jac[6 * s + a, i]
    for i in range(n - 1, -1, -1):  # L^T z = J^T, from the leaves
        row = work[i]
        j = dof_parentid[i]
        while j >= 0:
            f = factor[i, j]
            target = work[j]
            for r in range(count):
                target[r] -= f * row[r]
            j = dof_parentid[j]
    out[:slots] = 0.0
    for i in range(n):  # |D^-1/2 z|^2, each dof's 1/D once
        inv = 1.0 / factor[i, i]
        row = work[i]
        for s in range(slots):
            x, y, z = row[3 * s], row[3 * s + 1], row[3 * s + 2]
            out[s] += (x * x + y * y + z * z) * inv


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
        pivot_row = matrix[col]
        for row in range(col + 1, n):
            factor = matrix[row, col] * inv
            if factor != 0.0:  # whole rows (left of col: never read again), so it vectorises
                target = matrix[row]
                for c in range(n):
                    target[c] -= factor * pivot_row[c]
                rhs[row] -= factor * rhs[col]
    for row in range(n - 1, -1, -1):
        acc = rhs[row]
        for c in range(row + 1, n):
            acc -= matrix[row, c] * rhs[c]
        rhs[row] = acc / matrix[row, row]
    return rhs


#: Smallest pivot of the unpivoted `_tree_solve`, relative to the largest entry of its row.
PIVOT = 1e-9
#: Largest componentwise backward error max_i |A x - b|_i / (|A| |x| + |b|)_i accepted from
#: `_tree_solve` (a backward-stable solve gives about 1e-15).
BACKWARD_ERROR = 1e-10


@njit(cache=True, error_model='numpy', fastmath=True)
def _tree_solve(matrix, rhs, dof_parentid):
    """Solve matrix x = rhs for a square matrix with the sparsity of MuJoCo's inertia (entry
    (i, j) nonzero only if one of dofs i, j is an ancestor of the other), by elimination from
    the leaves, without pivoting: eliminating dof k touches only the rows of its ancestors,
    at the columns of its ancestors, so nothing fills in. Overwrites both; returns True with
    x in rhs, or False (both left partly eliminated) at a pivot below PIVOT times the largest
    entry of its row, where the elimination would need pivoting. It can still lose accuracy
    to growth: `_checked_solve` verifies its result. (Decided before any division: under
    fastmath the compiler may assume no inf or NaN arises, so they cannot be tested after.)"""
    n = rhs.shape[0]
    for k in range(n - 1, -1, -1):
        row = matrix[k]
        largest = 0.0
        for j in range(n):
            largest = max(largest, abs(row[j]))
        if not abs(row[k]) > PIVOT * largest:
            return False
        inv = 1.0 / row[k]
        row_k = row[:k]
        i = dof_parentid[k]
        while i >= 0:
            scale = matrix[i, k] * inv
            target = matrix[i, :k]
            for j in range(k):  # whole prefix (zeros off the ancestors stay zero): vectorises
                target[j] -= scale * row_k[j]
            rhs[i] -= scale * rhs[k]
            i = dof_parentid[i]
    for k in range(n):  # row k now holds its diagonal and its ancestors' columns only
        acc = rhs[k]
        row = matrix[k, :k]
        for j in range(k):
            acc -= row[j] * rhs[j]
        rhs[k] = acc / matrix[k, k]
    return True


@njit(cache=True, inline='always')
def _copy(matrix, vector, matrix_out, vector_out):
    """matrix_out[:, :] = matrix and vector_out[:] = vector (same shapes), element by element:
    numpy's slice assignment compiles a shape check whose error message formatting took a
    quarter of the kernels' compile time."""
    for i in range(vector.shape[0]):
        vector_out[i] = vector[i]
        for j in range(matrix.shape[1]):
            matrix_out[i, j] = matrix[i, j]


@njit(cache=True, error_model='numpy')
def _checked_solve(matrix, rhs, dof_parentid, factored, solution):
    """x of matrix x = rhs (matrix: tree sparsity as in `_tree_solve`; left unchanged) into
    `solution` (factored: (n, n) work space): `_tree_solve`, kept if it met no small pivot
    and its componentwise backward error is at most BACKWARD_ERROR, else the dense partially
    pivoted `_solve`. Returns solution."""
    _copy(matrix, rhs, factored, solution)
    accurate = _tree_solve(factored, solution, dof_parentid)
    if accurate:
        for i in range(rhs.shape[0]):
            residual, scale = -rhs[i], abs(rhs[i])
            for j in range(rhs.shape[0]):
                residual += matrix[i, j] * solution[j]
                scale += abs(matrix[i, j] * solution[j])
            accurate &= abs(residual) <= BACKWARD_ERROR * scale
    if not accurate:
        _copy(matrix, rhs, factored, solution)
        _solve(factored, solution)
    return solution


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
def _set_coefficients(j, state, speed, across, inv_reg, v_reg, coef_along, coef_across,
                      coef_moving):
    """Plate j's accumulator coefficients for its set: along factor (`_along_factor`),
    across damper (0 once off) and moving (1 or 0)."""
    coef_along[j] = _along_factor(state, speed, inv_reg, v_reg)
    coef_across[j] = 0.0 if state == OFF else across
    coef_moving[j] = 1.0 if state == MOVING else 0.0


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
def implicit_plate_forces(k, out_slot, table, force, work, flags, xi_new, v_reg, out):
    """Per-plate forces (N, world, on the body; out[:, :k]) that an implicit step applied,
    from the plates' final sets and across dampers (rows STATE of `flags`, ACROSS of `work`,
    left by `implicit_wrenches`) and the end-of-step twists xi_new: G - c w_perp if moving,
    a G - c w_perp if resting (frozen: with |v| in place of v_reg in a), 0 if off (module
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
def _accumulate_slot(j0, j1, h, u, arm, coef_along, coef_across, coef_moving, w_moving,
                     k_rank, k_iso):
    """A slot's accumulators from its plates j0..j1-1 (h, u (6, K), arm (3, K), per-plate set
    coefficients, as in `implicit_wrenches`): w_moving = sum m h, k_rank = sum (a h + c u) u^T
    and the 10 moments of c (c, c r, c r r^T). Each pass keeps its sums in registers."""
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


@njit(cache=True, error_model='numpy', fastmath=True)
def implicit_wrenches(k, slots, slot_start, out_plate, table, force, v_reg, jac, space, mass_h,
                      dof_parentid, qvel, timestep, step, memory, work, flags, xi_new, wrench,
                      friction, constraints, point):
    """Sand wrenches over the coming step by the implicit law of the module docstring.

    jac: (>= 6S+1, nv) the 6S slot Jacobian rows, then tau_free, every generalised force
    except the sand's (`prepare_solve`); space: a SolveSpace, whose chain,
    chain_count hold the dofs each slot's rows reach (`prepare_solve`), the rest work space.
    mass_h: Mh = M + dt D, the matrix MuJoCo's
    step solves with (`implicit_mass`); dof_parentid: mjModel's. With each plate moving
    (force G), resting (linear in v+) or off, the end-of-step joint velocities solve
        (Mh - dt J^T K J) qvel+ = Mh qvel + dt (tau_free + J^T W_moving),   xi+ = J qvel+,
    K the plates' linear response, W_moving the moving plates' G; plates then change set
    until the solution is consistent (an active-set iteration; moving and off are
    neighbours of resting only, so a plate passes through resting between them).
    Each plate starts from its set of the previous step if it was in the sand then
    (`memory`, indexed by plate, updated here: step << MEMORY_SHIFT | its final set; -1 for
    never) and not frozen, otherwise
    as moving when faster than v_reg; so a step usually needs one solve. Plates: columns
    :k of the gathered table and force, slot by slot from slot_start (`_gather_plates`;
    force (6, >= k): this fills rows 3..5 with r x G, so that it holds h); work
    (WORK_ROWS, >= k) and flags (FLAG_ROWS, >= k) are work space, of which rows STATE (final
    sets) and ACROSS (across dampers, N s/m) are results. Writes xi_new[:6S] (end-of-step
    twists) and wrench[:S] ([force; torque about COM], N, N m).
    friction: (dofs, force, memory, flags, torque) of the J joints with friction: their dof
    indices, friction F (N m or N), memory (as the plates'), flags ((3, J) int8 work space:
    rows STATE, VISITED, SOLVED) and the friction torque the step applies (written, N m or
    N). Each joint is in a set (`joint_friction`: sticking, a damper -F qvel+ / v_reg in the
    system; slipping, a constant -F or +F) chosen by its end speed like a plate's, starting
    from its last set.
    constraints: (jac, columns, counts, rows, flags, n): the n rows of MuJoCo's constraints
    the engine solves this step (`take_constraint_rows`: Jacobian rows, their nonzero
    columns, ROW_D ...) and their flags ((3, >= n) int8 work space: STATE, VISITED, SOLVED).
    Each row is MuJoCo's soft constraint f = D (aref - J (qvel+ - qvel) / dt) (N or N m):
    a two-sided row (an equality) is in every solve; a one-sided row (a limit, a contact's
    pyramid edge) starts active (pushing, in the system) where its reference acceleration
    pushes (aref > 0: the force it would have if nothing else acted), and changes set as its
    force at the solve's end velocities asks. An elliptic cone's rows (`elliptic_cones`) are
    in every solve, linearised at `point` ((nv,) work space: the end velocities they are
    linearised at); after a solve where some cone's force is off MuJoCo's, the next solve is
    its Newton step (`cone_step`) with every other element keeping its set. Their forces
    are written to rows[:, ROW_FORCE].
    A plate that would return to a set it already had this step is frozen for the rest of
    the step (the law is not monotone where RFT's lift makes G d^T non-symmetric, and plain
    active-set iterations can cycle): its along response becomes the secant
    (d.w / max(|v|, v_reg)) G through its current speed - the resting response for a plate
    at rest, about G for a plate that keeps its speed, less as it slows - linear and
    opposing the plate's motion (RFT's G always opposes d). The wrench is exactly what the
    last solve assumed. Returns the number of solves, negative if some plate was frozen or
    the sets had not settled within MAX_ITERATIONS, and whether the constraint rows are
    handed back to MuJoCo: where the rows' forces are not MuJoCo's at the last solve's end
    velocities (a row or cone frozen, or the iteration ended first:
    `constraint_rows.constraint_forces`), the step applies none of them and MuJoCo's own
    solve in mj_step2 solves them, exactly, with the sand's wrenches as this solve left them
    (the engine restores their rows, `constraint_rows.return_constraint_rows`). A joint that
    would return to a set is frozen likewise (a damper F / max(|qvel|, v_reg) through its
    speed at the step's start).

    Each plate enters its slot's accumulators with coefficients set by its set: moving ->
    wrench h = [G; r x G]; resting -> along response h u^T / v_reg (u = [d; r x d]); all but
    off -> across damper -c (I - d d^T), i.e. c u u^T minus c P^T P (kept as the 10 moments
    c, c r, c r r^T). After a solve, only the slots with plates that changed set are summed
    again, and only their terms of the system (J^T block J, J^T w_moving) recomputed; every
    slot's are then added to Mh in the same order as in the first solve.
    """
    n6 = 6 * slots
    nv = qvel.shape[0]
    inv_reg = 1.0 / v_reg
    chain, chain_count = space.chain, space.chain_count
    momentum = space.momentum  # Mh qvel + dt tau_free
    for r in range(nv):
        acc = timestep * jac[n6, r]
        for c in range(nv):
            acc += mass_h[r, c] * qvel[c]
        momentum[r] = acc
    constrained = constraints[5] > 0
    two_sided = cones = 0
    if constrained:
        two_sided = constraint_start(constraints, qvel, timestep, space.constraint_matrix,
                                     momentum)
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
    _translational_inverse_masses(mass_h, dof_parentid, jac, slots, space.factor,
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
        _set_coefficients(j, state, speed[j], across[j], inv_reg, v_reg, coef_along,
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
                _accumulate_slot(first[s], first[s + 1], h, u, arm, coef_along, coef_across,
                                 coef_moving, w_moving[s], k_rank[6 * s:6 * s + 6], k_iso[s])
                _resting_block(k_rank[6 * s:6 * s + 6], k_iso[s], blocks[6 * s:6 * s + 6])
                _slot_terms(blocks[6 * s:6 * s + 6], w_moving[s], jac[6 * s:6 * s + 6],
                            chain[s, :chain_count[s]], chain_work, products[nv * s:nv * s + nv],
                            force_terms[s])
                dirty[s] = False
        # (Mh - dt J^T K J) qvel+ = Mh qvel + dt (tau_free + J^T W_moving), slot by slot
        # over the dofs its Jacobian reaches (its kinematic chain) only.
        _copy(mass_h, momentum, system, rhs)
        for s in range(slots):
            _add_slot(products[nv * s:nv * s + nv], force_terms[s], chain[s, :chain_count[s]],
                      timestep, system, rhs)
        if frictional:
            friction_terms(friction, qvel, v_reg, timestep, system, rhs)
        if two_sided:
            add_matrix(space.constraint_matrix, system)
        if constrained:
            constraint_terms(constraints, system, rhs)
        if cones:
            cone_terms(constraints, system, rhs)
        _checked_solve(system, rhs, dof_parentid, factored, solution)
        for j in range(k):
            solved[j] = states[j]
        # the cones' Newton step first, the others keeping their sets; then the sets
        cone_pass = False
        if cones:
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
        if constrained and not cone_pass:
            changed, cycles = constraint_sets(constraints, qvel, solution, timestep)
            frozen += cycles
            converged &= changed == 0
        for s in range(slots):  # xi+ = J qvel+, over each chain's dofs
            top = chain[s, 0] + 1 if chain_count[s] > 0 else 0  # its leaf has the highest
            for r in range(6 * s, 6 * s + 6):
                acc = 0.0
                for i in range(top):  # (zero beyond the chain: a prefix vectorises)
                    acc += jac[r, i] * solution[i]
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
                _set_coefficients(j, new, speed[j], across[j], inv_reg, v_reg, coef_along,
                                  coef_across, coef_moving)
            dirty[s] = True
            converged = False
    # The wrench the last solve assumed: moving plates' G plus every plate's linear response.
    for j in range(k):
        states[j] = solved[j]
    for s in range(slots):
        if dirty[s]:  # back to the coefficients of the last solve
            for j in range(first[s], first[s + 1]):
                _set_coefficients(j, solved[j], speed[j], across[j], inv_reg, v_reg,
                                  coef_along, coef_across, coef_moving)
            _accumulate_slot(first[s], first[s + 1], h, u, arm, coef_along, coef_across,
                             coef_moving, w_moving[s], k_rank[6 * s:6 * s + 6], k_iso[s])
            _resting_block(k_rank[6 * s:6 * s + 6], k_iso[s], blocks[6 * s:6 * s + 6])
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
    if constrained:
        handed_back = constraint_forces(constraints, qvel, solution, timestep) + cones_off > 0
        if cones:
            cone_reports(constraints)
    return (iterations if converged and frozen == 0 else -iterations), handed_back


@njit(cache=True, error_model='numpy')
def implicit_step(timestep, arrays):
    """One step's implicit sand wrenches over the plates the step's gather kernel left, in
    one call: `prepare_solve` (into jac, (>= 6S+1, nv) work space), `implicit_damping`,
    `implicit_mass` (mass: the dense M of this state, made Mh in place), `implicit_wrenches`
    over the gathered plates, the frictional joints and the constraint rows taken this step
    (`take_constraint_rows`, counter CONSTRAINT_ROWS; when there are any), then
    `scatter_wrenches` into xfrc_applied (zero wrenches when no plate is in the sand); the
    joints' friction and the rows' forces (J^T f) are added to qfrc_passive, which mj_step2
    applies. Arguments as in those functions (timestep: s); arrays: the table of an
    `ArrayTable` of `ImplicitArrays`, settings REST_SPEED, DAMPER, ACTUATORS. Adds the solves
    to the SOLVES counter, counts the step in UNSETTLED where it did not settle and in
    HANDED_BACK where its rows are handed back to MuJoCo (then none of their forces is
    added). The constraint force of the constraints left to MuJoCo is taken as mjData's
    qfrc_constraint of the step before (`prepare_solve`), except after a step whose rows were
    handed back, whose qfrc_constraint holds theirs too: then as the one that step took
    (held_constraint)."""
    a = IMPLICIT
    settings, counters = float_vector(arrays, a.settings), int_vector(arrays, a.counters)
    k, slots, step = counters[GATHERED], counters[SLOTS], counters[STEPS]
    v_reg = settings[REST_SPEED]
    slot_body, slot_start = int_vector(arrays, a.slot_body), int_vector(arrays, a.slot_start)
    out_plate = int_vector(arrays, a.out_plate)
    table, force = float_matrix(arrays, a.table), float_matrix(arrays, a.force)
    body_ids, body_rootid = int_vector(arrays, a.body_ids), int32_vector(arrays, a.body_rootid)
    body_dofnum = int32_vector(arrays, a.body_dofnum)
    body_dofadr = int32_vector(arrays, a.body_dofadr)
    body_parentid = int32_vector(arrays, a.body_parentid)
    dof_parentid = int32_vector(arrays, a.dof_parentid)
    xipos, subtree_com = float_matrix(arrays, a.xipos), float_matrix(arrays, a.subtree_com)
    cdof, qvel = float_matrix(arrays, a.cdof), float_vector(arrays, a.qvel)
    qfrc_passive = float_vector(arrays, a.qfrc_passive)
    qfrc_actuator = float_vector(arrays, a.qfrc_actuator)
    qfrc_applied = float_vector(arrays, a.qfrc_applied)
    qfrc_constraint = float_vector(arrays, a.qfrc_constraint)
    after_hand_back = counters[HANDED_BACK_AT] > 0 and counters[HANDED_BACK_AT] == step - 1
    lagged = float_vector(arrays, a.held_constraint) if after_hand_back else qfrc_constraint
    friction = (int_vector(arrays, a.friction_dofs), float_vector(arrays, a.friction_force),
                int_vector(arrays, a.friction_memory), int8_matrix(arrays, a.friction_flags),
                float_vector(arrays, a.friction_torque))
    qfrc_bias = float_vector(arrays, a.qfrc_bias)
    dof_damping, trntype = float_vector(arrays, a.dof_damping), int32_vector(arrays, a.trntype)
    trnid, gear = int32_matrix(arrays, a.trnid), float_matrix(arrays, a.gear)
    jnt_type, jnt_dofadr = int32_vector(arrays, a.jnt_type), int32_vector(arrays, a.jnt_dofadr)
    dyntype, gaintype = int32_vector(arrays, a.dyntype), int32_vector(arrays, a.gaintype)
    gainprm, biastype = float_matrix(arrays, a.gainprm), int32_vector(arrays, a.biastype)
    biasprm, forcelimited = float_matrix(arrays, a.biasprm), byte_vector(arrays, a.forcelimited)
    forcerange, ctrl = float_matrix(arrays, a.forcerange), float_vector(arrays, a.ctrl)
    act, actadr = float_vector(arrays, a.act), int32_vector(arrays, a.actadr)
    actuator_force = float_vector(arrays, a.actuator_force)
    damping, mass = float_vector(arrays, a.damping), float_matrix(arrays, a.mass)
    jac, memory = float_matrix(arrays, a.jac), int_vector(arrays, a.memory)
    work = float_matrix(arrays, a.work)
    flags, xi_new = int8_matrix(arrays, a.flags), float_vector(arrays, a.xi_new)
    wrench, body_wrenches = float_matrix(arrays, a.wrench), float_matrix(arrays, a.body_wrenches)
    xfrc_applied = float_matrix(arrays, a.xfrc_applied)
    wrench_sum = float_matrix(arrays, a.wrench_sum)
    space = SolveSpace(
        int_matrix(arrays, a.chain), int_vector(arrays, a.chain_count),
        float_vector(arrays, a.inverse_mass), float_matrix(arrays, a.w_moving),
        float_matrix(arrays, a.k_rank), float_matrix(arrays, a.k_iso),
        int8_vector(arrays, a.dirty), float_vector(arrays, a.momentum),
        float_matrix(arrays, a.system), float_vector(arrays, a.rhs),
        float_matrix(arrays, a.factored), float_vector(arrays, a.solution),
        float_matrix(arrays, a.factor), float_matrix(arrays, a.translational),
        float_matrix(arrays, a.blocks), float_matrix(arrays, a.products),
        float_matrix(arrays, a.force_terms), float_matrix(arrays, a.chain_work),
        float_matrix(arrays, a.constraint_matrix))
    constraint_jac, constraint_rows = (float_matrix(arrays, a.constraint_jac),
                                       float_matrix(arrays, a.constraint_rows))
    constraint_columns = int_matrix(arrays, a.constraint_columns)
    constraint_counts = int_vector(arrays, a.constraint_counts)
    taken = counters[CONSTRAINT_ROWS]
    constraints = (constraint_jac, constraint_columns, constraint_counts, constraint_rows,
                   int8_matrix(arrays, a.constraint_flags), taken)
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
        point = float_vector(arrays, a.cone_point) if taken > 0 else qvel  # (unused: none)
        iterations, handed_back = implicit_wrenches(
            k, slots, slot_start, out_plate, table, force, v_reg, rows, space, mass,
            dof_parentid, qvel, timestep, step, memory, work, flags, xi_new, wrench, friction,
            constraints, point)
        counters[SOLVES] += abs(iterations)
        counters[UNSETTLED] += iterations < 0
        if handed_back:
            counters[HANDED_BACK] += 1
            counters[HANDED_BACK_AT] = step
            if not after_hand_back:
                held = float_vector(arrays, a.held_constraint)
                for i in range(held.shape[0]):
                    held[i] = qfrc_constraint[i]
        for f in range(friction_dofs.shape[0]):  # (mj_step2 adds qfrc_passive as it stands)
            qfrc_passive[friction_dofs[f]] += friction_torque[f]
        for r in range(0 if handed_back else taken):
            force_r = constraint_rows[r, ROW_FORCE]
            for c in constraint_columns[r, :constraint_counts[r]]:
                qfrc_passive[c] += constraint_jac[r, c] * force_r
    # one call site for any slot count (a literal 0 at a second one compiled it twice)
    scatter_wrenches(slots, slot_body, wrench, body_ids, body_wrenches, xfrc_applied, xipos,
                     wrench_sum)


@njit(cache=True, error_model='numpy')
def smoothed_wrenches(k, slots, out_plate, out_slot, table, force, alpha, step,
                      ema_force, ema_step, applied, wrench):
    """Explicit RFT with the paper's per-plate exponential moving average (RFT-SiM eq. 6):
    F_s = alpha F + (1 - alpha) F_s(previous step) for a plate that was in the sand on the
    previous step, F_s = F otherwise (its history is dropped when it leaves the sand).
    alpha = 1 applies the raw RFT force. Plates: columns :k of the gathered table and force
    (`_gather_plates`). Writes applied[:, :k] = F_s (N, world, on the body).
    ema_force (N, 3), ema_step (N,) hold each plate's last smoothed force and the step index
    it was computed at. Writes wrench[:S] as in `implicit_wrenches`.
    """
    wrench[:slots, :] = 0.0
    for j in range(k):
        p = out_plate[j]
        for a in range(3):
            applied[a, j] = force[a, j]
            if ema_step[p] == step - 1:
                applied[a, j] = alpha * force[a, j] + (1.0 - alpha) * ema_force[p, a]
            ema_force[p, a] = applied[a, j]
        ema_step[p] = step
        fx, fy, fz = applied[0, j], applied[1, j], applied[2, j]
        rx, ry, rz = table[LEVER, j], table[LEVER + 1, j], table[LEVER + 2, j]
        s = out_slot[j]
        wrench[s, 0] += fx
        wrench[s, 1] += fy
        wrench[s, 2] += fz
        wrench[s, 3] += ry * fz - rz * fy
        wrench[s, 4] += rz * fx - rx * fz
        wrench[s, 5] += rx * fy - ry * fx


# The gather kernels, bound once every function their code calls is defined (`_gather_kernel`
# copies the module's globals).
gather_plane = _gather_kernel('gather_plane', FLAT, False,
                              '`_gather_plates` on a horizontal plane.')
gather_slope = _gather_kernel('gather_slope', SLOPE, False,
                              '`_gather_plates` on an inclined plane.')
gather_grid = _gather_kernel('gather_grid', GRID, False,
                             '`_gather_plates` on a rigid height grid.')
gather_deformable = _gather_kernel(
    'gather_deformable', GRID, True,
    '`_gather_plates` on deformable sand (a height grid the plates mark), then rules 2-4 for '
    'the footprints the bodies left in this step (`deformable.settle`): one call.')

forget_stale(globals())  # (kernel_cache: drops kernels compiled from older sources)
