"""The layout the sand kernels share: the rows of the gathered-plate table, the engine's
settings and counters (one float64 and one int64 vector, by index), the implicit law's
per-plate work rows and flags, the columns of MuJoCo's constraint rows the implicit step
takes, and the named arrays each kernel takes (`GatherArrays`, `ImplicitArrays`,
`SolveSpace`), which the engine (`engine.SandEngine`) allocates once.

Conventions: plates run along the second axis of every per-plate table (column k: the k-th
plate gathered this step); world frame, z up, SI. Nothing here is compiled: the kernels
(`gather`, `implicit_solve`, `explicit`) read these constants as compile-time globals.
"""
from collections import namedtuple

import numpy as np

from ..rft.law_rows import LAW_ROWS

#: Rows of the implicit law's per-plate work space (`implicit_solve._implicit_step`), plates
#: along the second axis: |G|, across damper c (N s/m), the set coefficients.
MAGNITUDE, ACROSS, COEF_ALONG, COEF_ACROSS, COEF_MOVING = 0, 1, 2, 3, 4
WORK_ROWS = 5
#: Rows of its per-plate flags (int8): those of `active_set` (final set, sets visited,
#: solved), then the set the last solve asks for.
WANTED = 3
FLAG_ROWS = 4

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
#: kernel's, `kernel_names.gather`): the slope's gradient dh/dx, dh/dy, the grid's node [0, 0]
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
#: back to MuJoCo's solve (`implicit_solve._implicit_step`), and the last of them (its STEPS count).
(STEPS, GATHERED, LEADING, SLOTS, SOLVES, UNSETTLED, CONSTRAINT_ROWS, HANDED_BACK,
 HANDED_BACK_AT) = range(9)
COUNTER_COUNT = 9

#: The arrays of the gather kernels (`gather._gather_plates`), in the order of their `ArrayTable`;
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
#: twist response (`resting_block`, S 6x6 blocks stacked) and its terms of the system
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


#: The arrays of the implicit step (`implicit_solve._implicit_step`), likewise (IMPLICIT:
#: their rows), ending with a SolveSpace.
ImplicitArrays = namedtuple('ImplicitArrays', [
    # the engine's settings and counters, the gathered plates (`gather._gather_plates`)
    'settings', 'counters', 'slot_body', 'slot_start', 'out_plate', 'out_slot', 'table',
    'force',
    # the sand bodies, mjModel, mjData
    'body_ids', 'body_rootid', 'body_dofnum', 'body_dofadr', 'body_parentid', 'dof_parentid',
    'xipos', 'subtree_com', 'cdof', 'qvel', 'qfrc_passive', 'qfrc_actuator', 'qfrc_applied',
    'qfrc_constraint', 'qfrc_bias',
    # the constraint force of the rows left to MuJoCo held over a step whose rows were handed
    # back, and the end velocities the cones are linearised at (`implicit_solve._implicit_step`)
    'held_constraint', 'cone_point',
    # joint friction the engine solves (`implicit_solve._implicit_step`' friction)
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
    # work space and results (`applied`: per-plate forces, `implicit_law.implicit_plate_forces`)
    'damping', 'mass', 'jac', 'memory', 'work', 'flags', 'xi_new', 'applied',
    'wrench', 'body_wrenches', 'xfrc_applied', 'wrench_sum', *SolveSpace._fields])
IMPLICIT = ImplicitArrays(*range(len(ImplicitArrays._fields)))

#: MuJoCo's constraint rows in the implicit solve (`constraint_rows`, `elliptic_cones`).
#: A one-sided row's sets: pushing (MuJoCo's soft constraint in the system) or not.
INACTIVE, ACTIVE = 0, 1
#: The kinds of MuJoCo's constraint rows (`take_constraint_rows`' kinds, by mjtConstraint):
#: left to MuJoCo, two-sided (equalities), one-sided (limits, frictionless and pyramidal
#: contacts) or a row of an elliptic cone (`elliptic_cones`).
KEPT, TWO_SIDED, ONE_SIDED, CONE = -1, 0, 1, 2
#: Columns of a row: MuJoCo's efc_D and efc_aref, its kind (TWO_SIDED ...), its push (N s or
#: N m s: its term of the system's right-hand side; a row's D (J qvel + dt aref)), the force
#: the step applies along it (N or N m) and the aref that makes MuJoCo report that force
#: (`report_constraint_forces`). A cone's rows also hold (`elliptic_cones`): per row its jar
#: at the last solve's end velocities; its friction coefficient along the row (the contact's
#: mu on its first, normal row, then its `friction` per tangent row); on its first row its
#: row count (condim); per row its start J qvel / dt + aref (jar = J qvel+ / dt - start),
#: the jar its linearisation is made at, a jar a line search tries, the linearisation's
#: force at jar = 0 (N or N m), and from ROW_HESSIAN that row of the linearisation's Hessian
#: H (CONE_ROWS columns): f = ROW_LINEAR - H jar.
(ROW_D, ROW_AREF, ROW_KIND, ROW_PUSH, ROW_FORCE, ROW_REPORT, ROW_JAR, ROW_FRICTION, ROW_DIM,
 ROW_START, ROW_POINT, ROW_TRIAL, ROW_LINEAR) = range(13)
#: Rows of a cone at most (condim 6), and where its Hessian's columns begin.
CONE_ROWS = 6
ROW_HESSIAN = 13
ROW_COLUMNS = ROW_HESSIAN + CONE_ROWS
