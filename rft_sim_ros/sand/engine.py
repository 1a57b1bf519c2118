"""SandEngine: RFT sand forces on the bodies of a MuJoCo model, applied every step.

Each step: `mj_step1` computes positions and velocities; the engine finds the plates in the
sand, computes their RFT forces from that same state (no one-step lag), treats them at low
velocity (implicit by default, see `implicit_law`), sums them per body into a wrench about the
body's centre of mass and writes all of them at once into `mjData.xfrc_applied`; `mj_step2`
integrates. The engine owns the xfrc_applied rows of its sand bodies.

Only the bodies a scene names carry plates; a body whose plates are all above the surface is
skipped after one bounding-sphere test, so cost grows with plates in the sand.
"""
import contextlib
import resource
import time
from dataclasses import dataclass

import mujoco
import numpy as np

from .. import kernel_names, prebuilt
from ..kernel_cache import BackgroundCompile, is_cached, last_cold_start, load, record_cold_start
from ..kernel_names import (EXPLICIT, PLATE_FORCES, ROWS, STEP_PARTS, STEPS, TABLE_SIGNATURE,
                            function)
from ..rft.coefficients import normalisation as find_normalisation
from ..rft.plates import Plates
from ..units import validated_zeta, zeta_to_si
from . import layout
from .array_table import ArrayTable
from .clusters import cluster_plates
from .deformable import no_bed_arrays
from .surface import GRID, Plane, tile_planes, window_extremes, window_span
from .surface_codes import KINDS

LOW_VELOCITY_METHODS = ('implicit', 'ema', 'none')

#: Constraint rows an engine has room for at first (`SandEngine._take_constraint_rows` grows
#: it for a step with more: a few contacts' pyramid edges, equalities, limits).
CONSTRAINT_ROOM = 16


def engine_kernels(method='implicit', surface_kind='plane', deformable=False, parts='rows'):
    """The names (`kernel_names`) of the compiled kernels an engine with low-velocity
    `method` ('implicit'; any other: the explicit methods' kernels) on a surface of
    `surface_kind` ('plane', 'slope', 'grid': `surface_codes.KINDS`; deformable or not) runs; with
    the implicit method, its step solving `parts` (`kernel_names.STEP_PARTS`, `step_parts`)."""
    gathering = kernel_names.gather(surface_kind, deformable)
    if method != 'implicit':
        return (gathering, *EXPLICIT)
    rows = () if parts == 'plain' else ROWS
    return (gathering, STEPS[parts], PLATE_FORCES, *rows)


def ready(name):
    """Whether kernel `name` (`kernel_names`) runs without compiling: prebuilt
    (`prebuilt.has`) or held, current, in numba's on-disk cache (`kernel_cache.is_cached`,
    which imports the kernel's module and numba)."""
    return prebuilt.has(name) or is_cached(prebuilt.dispatcher(name))


def kernels_cached(method='implicit', surface_kind='plane', deformable=False, parts='rows'):
    """Whether the `engine_kernels` of these arguments are all `ready`, so that building
    such an engine compiles nothing (otherwise it compiles them: a first run after install,
    or after an upgrade)."""
    return all(ready(kernel)
               for kernel in engine_kernels(method, surface_kind, deformable, parts))


def step_parts(model, rows_expected=False):
    """Which compiled implicit step (`kernel_names.STEP_PARTS`) an engine of MuJoCo
    `model` loads: 'plain' where the model cannot make a constraint row (no equality, no
    limited joint or tendon, no tendon friction and no rigid contact: `can_collide`) and rows
    are not `rows_expected`; 'cones' where it can and its contacts use elliptic cones; 'rows'
    otherwise. (A step that takes rows the loaded step does not solve loads the one that
    does: `_take_constraint_rows`.)"""
    tendons = model.ntendon and (model.tendon_limited.any() or model.tendon_frictionloss.any())
    rows = bool(rows_expected or model.neq or tendons or model.jnt_limited.any()
                or can_collide(model))
    if not rows:
        return 'plain'
    return 'cones' if model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC else 'rows'


def can_collide(model):
    """Whether MuJoCo could ever make a rigid contact in `model`: an explicit <pair>, a flex,
    or two geoms of bodies that are not welded together whose contype and conaffinity bits
    let them collide (parent-child filtering and distance left out: a conservative
    answer)."""
    if model.npair or model.nflex:
        return True
    contype, conaffinity = model.geom_contype, model.geom_conaffinity
    live = np.flatnonzero((contype != 0) | (conaffinity != 0))
    if len(live) < 2:
        return False
    kinds, affinities = contype[live], conaffinity[live]
    bodies = model.body_weldid[model.geom_bodyid[live]]  # (MuJoCo skips geoms of one weld)
    pairs = ((kinds[:, None] & affinities[None, :]) != 0) | (
        (affinities[:, None] & kinds[None, :]) != 0)
    return bool((pairs & (bodies[:, None] != bodies[None, :])).any())


def _uncached_key(kernels):
    """The function names of those of `kernels` (names, `kernel_names`) that are neither
    prebuilt nor cached, as one text (what a cold start's record is kept under); '' when
    none is missing."""
    return ' '.join(sorted(function(name) for name in kernels if not ready(name)))


def cold_start_estimate(method='implicit', surface_kind='plane', deformable=False,
                        parts='rows'):
    """Wall seconds the last start that compiled what the cache now lacks of the
    `engine_kernels` of these arguments took with this cache (measured on this machine by
    `SandEngine._load_kernels`, kept by `kernel_cache.record_cold_start`); None when no start
    compiled just those here (e.g. a first run after install) or none are missing."""
    key = _uncached_key(engine_kernels(method, surface_kind, deformable, parts))
    record = last_cold_start(prebuilt.dispatcher(STEPS['plain']), key) if key else None
    return None if record is None else record['wall_s']


def _cpu_seconds():
    """CPU seconds of this process and its waited-for children (the background compile)."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def full_inertia_call(model, data, out):
    """(function, args) that write the dense joint-space inertia M (nv x nv) into `out`:
    mj_fullM, whose signature changed in MuJoCo 4."""
    if int(mujoco.__version__.split('.')[0]) >= 4:
        return mujoco.mj_fullM, (model, data, out)
    return mujoco.mj_fullM, (model, out, data.qM)


@dataclass(frozen=True)
class LowVelocity:
    """How RFT is treated where the direction of motion is ill-defined (|v| -> 0).

    method: 'implicit' (default): the sand may stop a plate within a step but not reverse
            it, and holds a plate at rest; `rest_speed` (m/s) is the regularisation speed
            below which the law is a stiff damper solved implicitly (a loaded body at rest
            creeps at most at about rest_speed x load / capacity).
            'ema': the RFT-SiM paper's exponential moving average of each plate force with
            factor `ema_alpha` (0.1 in the paper's text, 0.5 in its code), explicit.
            'none': raw explicit RFT.
    """
    method: str = 'implicit'
    rest_speed: float = 1e-5
    ema_alpha: float = 0.1

    def __post_init__(self):
        if self.method not in LOW_VELOCITY_METHODS:
            raise ValueError(f'low_velocity.method must be one of {LOW_VELOCITY_METHODS}, '
                             f'got {self.method!r}')
        if not self.rest_speed > 0:
            raise ValueError(f'low_velocity.rest_speed must be > 0 m/s, got {self.rest_speed}')
        if not 0 < self.ema_alpha <= 1:
            raise ValueError(f'low_velocity.ema_alpha must be in (0, 1], got {self.ema_alpha}')
        for name in ('rest_speed', 'ema_alpha'):  # (numbers, as the kernels take them: floats)
            object.__setattr__(self, name, float(getattr(self, name)))


class SandEngine:
    """RFT sand under a MuJoCo model.

    model, data: the MuJoCo model and its data (integrator Euler, implicit or implicitfast).
    body_plates: {body name: Plates in that body's frame (xpos/xmat), m}.
    zeta: N/cm^3 (multiplied by `zeta_map`'s factor where it has one: a ZetaMap or None).
    surface_height: z of the horizontal sand surface, m; or `surface`: any `surface.Surface`
    (slope, height grid), fixed for the engine's life (`engine.surface`: its heights where
    plates meet it, `height(x, y)`): a rigid grid's heights are read-only, as the bounds
    the engine derives from them once are (another surface: another engine); deformable
    sand changes its own grid, bounds included.
    normalisation: 'treers' or 'rft_sim'. dynamic: DynamicTerm or None.
    With the implicit law the engine takes over the model's joint friction (MJCF
    frictionloss): `joint_friction` {dof: F (N m or N)} is solved with the sand
    (`implicit_solve._implicit_step`), and model.dof_frictionloss is zeroed there, so that
    MuJoCo's friction constraint does not act a second time after the solve; and MuJoCo's
    equality, limit and contact constraints (pyramidal and elliptic cones): each step the
    rows MuJoCo made for them in mj_step1 are taken into the solve (`constraint_rows`),
    their Jacobian zeroed in mjData, so that mj_step2's solve adds no force of theirs but
    reports the solve's in efc_force; their generalised force is in qfrc_passive, not
    qfrc_constraint. A step whose rows the solve cannot settle hands them back to MuJoCo's
    solve (restored in mjData; `handed_back_steps`).
    """

    def __init__(self, model, data, body_plates, zeta, surface_height=0.0,
                 normalisation='treers', dynamic=None, low_velocity=LowVelocity(),
                 surface=None, zeta_map=None, rows_expected=False):
        if model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4:
            raise ValueError('the RFT engine needs the Euler, implicit or implicitfast '
                             'integrator (RK4 cannot be split into mj_step1/mj_step2)')
        self.model, self.data = model, data
        self.body_names = tuple(body_plates)
        self.body_ids = np.array([model.body(name).id for name in self.body_names],
                                 dtype=np.int64)
        plates = [body_plates[name] for name in self.body_names]
        self._cluster(plates)
        norm = find_normalisation(normalisation)
        self.dynamic = dynamic
        self.low_velocity = low_velocity
        self._implicit_method = low_velocity.method == 'implicit'
        # the kernels' settings and counters (layout.SURFACE ..., layout.STEPS ...)
        self._settings = np.zeros(layout.SETTING_COUNT)
        self._counters = np.zeros(layout.COUNTER_COUNT, dtype=np.int64)
        self.surface = Plane(surface_height) if surface is None else surface
        self.deformable = not self.surface.rigid
        self._set_surface(self.surface)
        self._surface_kind = KINDS[self.surface.data.kind]  # ('plane', 'slope', 'grid')
        self._gathering = kernel_names.gather(self._surface_kind, self.deformable)
        self._gather = prebuilt.kernel(self._gathering)
        # per-plate forces of an implicit step, where asked for (`active_plates`)
        self._plate_forces = prebuilt.kernel(PLATE_FORCES)
        # the kernels of the explicit methods, and of MuJoCo's constraint rows where the
        # engine calls them (`_row_kernels`)
        self._smoothed_wrenches, self._scatter_wrenches = (
            (None, None) if self._implicit_method else map(prebuilt.kernel, EXPLICIT))
        self._rows_kernels = None  # (`_row_kernels`)
        self.zeta_map = zeta_map
        self._zeta_factors = (np.ones((1, 1)) if zeta_map is None
                              else np.ascontiguousarray(zeta_map.factors, dtype=float))
        if zeta_map is not None:
            self._settings[layout.ZETA_MAP] = 1.0
            self._settings[layout.MAP_X0], self._settings[layout.MAP_Y0] = zeta_map.origin
            self._settings[layout.MAP_INV_DX] = 1.0 / zeta_map.cell
            self._settings[layout.MAP_INV_DY] = 1.0 / zeta_map.cell
        self._settings[layout.INV_A4] = 1.0 / norm.a4
        self._settings[layout.INV_B4] = 1.0 / norm.b4
        self._settings[layout.DYNAMIC] = 0.0 if dynamic is None else (dynamic.lam
                                                                         * dynamic.density)
        # the paper's EMA keeps a history for plates in the sand that trail, too
        self._settings[layout.TRAILING] = low_velocity.method == 'ema'
        self._settings[layout.REST_SPEED] = low_velocity.rest_speed
        self.zeta = zeta

        n, nb = len(self.areas), len(self.body_names)
        # the plates in the sand this step, one per column (the gather kernel)
        self._plate = np.zeros(n, dtype=np.int64)
        self._slot = np.zeros(n, dtype=np.int64)
        self._table = np.zeros((layout.PLATE_ROWS, n))
        self._force = np.zeros((6, n))  # G, then r x G (implicit_solve._implicit_step)
        self._applied = np.zeros((3, n))
        self._work = np.zeros((layout.WORK_ROWS, n))
        self._flags = np.zeros((layout.FLAG_ROWS, n), dtype=np.int8)
        # each plate's last step in the sand and its set then (implicit_solve._implicit_step)
        self._plate_memory = np.full(n, -1, dtype=np.int64)
        self._take_friction(model)
        self._take_constraints(model)
        self._parts = None
        self._solve_at_least(step_parts(model, rows_expected))
        self._xi = np.zeros(6 * nb)
        self._slot_body = np.zeros(nb, dtype=np.int64)
        self._slot_start = np.zeros(nb + 1, dtype=np.int64)  # slot s: plates [start s, s+1)
        self._slot_wrench = np.zeros((nb, 6))
        self._jac = np.zeros((6 * nb + 1, model.nv))  # slot Jacobians and tau_free
        self._ema_force = np.zeros((n, 3))
        self._ema_step = np.full(n, -2, dtype=np.int64)
        self.body_wrenches = np.zeros((nb, 6))
        # per sand body, summed over the steps since `mean_wrenches` last restarted the mean:
        # [force; torque about the world origin] (mujoco_terms.scatter_wrenches)
        self._wrench_sum = np.zeros((nb, 6))
        self._sum_since = 0  # the STEPS counter when the sum restarted
        self._views()
        self._load_kernels()

    def _set_surface(self, surface):
        """Write the surface's `surface.SurfaceData` into the kernels' settings and keep its
        arrays; deformable sand's is its bed's, and its base's (read beyond the bed) goes
        in too: a plane or slope as SURFACE, SLOPE_X, SLOPE_Y, a grid as the BASE_ settings
        and arrays. A rigid grid gets its bounding planes over tiles of TILE_STEP nodes,
        enough for the largest sand body's square (`surface.tile_planes`), and its extremes
        over windows enough for the largest cluster's square (`surface.window_extremes`)."""
        settings = self._settings
        data = surface.data
        base = surface.base.data if self.deformable else data
        settings[layout.SURFACE] = base.height
        settings[layout.SLOPE_X], settings[layout.SLOPE_Y] = base.gradient
        settings[layout.GRID_X0], settings[layout.GRID_Y0] = data.origin
        settings[layout.GRID_INV_DX] = 1.0 / data.spacing[0]
        settings[layout.GRID_INV_DY] = 1.0 / data.spacing[1]
        settings[layout.BASE_KIND] = base.kind
        settings[layout.BASE_X0], settings[layout.BASE_Y0] = base.origin
        settings[layout.BASE_INV_DX] = 1.0 / base.spacing[0]
        settings[layout.BASE_INV_DY] = 1.0 / base.spacing[1]
        if self.deformable:
            settings[layout.DEFORM_RISE] = surface.rise
        self._surface_grid = data.grid
        self._surface_block_max, self._surface_block_min = data.block_max, data.block_min
        # a rigid grid's bounding planes over tiles that hold any body's square (none where
        # every body's plates lie at its origin: step 0)
        step = int(np.ceil(2 * self.radii.max(initial=0.0) / min(data.spacing)))
        rigid_grid = data.kind == GRID and not self.deformable
        settings[layout.TILE_STEP] = step if rigid_grid else 0
        self._surface_tiles = (tile_planes(data.grid, data.origin, data.spacing, step)
                               if rigid_grid and step > 0 else np.zeros((1, 4)))
        # and its extremes over windows that reach every node a cluster's square touches
        self._surface_windows = (
            window_extremes(data.grid, window_span(self._cluster_radius.max(), data.spacing))
            if rigid_grid else (np.zeros((1, 1)), np.zeros((1, 1))))
        self._base_arrays = dict(base_grid=base.grid, base_block_max=base.block_max,
                                 base_block_min=base.block_min)

    def _cluster(self, plates):
        """Store all plates, body by body and within a body cluster by cluster, with the
        bounding spheres (body frame) used to skip plates above the sand."""
        empty = [name for name, body in zip(self.body_names, plates) if len(body) == 0]
        if empty:
            raise ValueError(f'sand bodies without plates: {", ".join(empty)} (each sand body '
                             'needs at least one)')
        parts, body_clusters, plate_starts, centers, radii = [], [0], [], [], []
        offset = 0
        for body in plates:
            order, starts = cluster_plates(body.centroids)
            ordered = body.subset(order)
            parts.append(ordered)
            for c in range(len(starts) - 1):
                points = ordered.centroids[starts[c]:starts[c + 1]]
                center = 0.5 * (points.min(axis=0) + points.max(axis=0))
                centers.append(center)
                radii.append(np.linalg.norm(points - center, axis=1).max())
                plate_starts.append(offset + starts[c])
            offset += len(ordered)
            body_clusters.append(len(centers))
        plate_starts.append(offset)
        joined = Plates.concatenate(parts)
        # per plate, body frame: position and normal (read by the gather kernel)
        self.local_pos = np.ascontiguousarray(joined.centroids)
        self.local_normal = np.ascontiguousarray(joined.normals)
        self.areas = np.ascontiguousarray(joined.areas)
        counts = np.array([len(p) for p in plates], dtype=np.int64)
        self.plate_start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        self.radii = np.array([np.linalg.norm(p.centroids, axis=1).max() for p in plates])
        self._body_cluster_start = np.array(body_clusters, dtype=np.int64)
        self._cluster_plate_start = np.array(plate_starts, dtype=np.int64)
        self._cluster_center = np.array(centers, dtype=float).reshape(-1, 3)
        self._cluster_radius = np.array(radii, dtype=float)

    def _take_friction(self, model):
        """The joint friction the implicit law solves (`implicit_solve._implicit_step`):
        its dofs, forces, memory and work space; MuJoCo's own friction switched off for
        them."""
        frictional = (np.flatnonzero(model.dof_frictionloss > 0) if self._implicit_method
                      else np.zeros(0, dtype=np.int64))
        self.joint_friction = {int(i): float(model.dof_frictionloss[i]) for i in frictional}
        self._friction_dofs = frictional.astype(np.int64)
        self._friction_force = model.dof_frictionloss[frictional].copy()
        self._friction_memory = np.full(len(frictional), -1, dtype=np.int64)
        self._friction_flags = np.zeros((3, len(frictional)), dtype=np.int8)
        self._friction_torque = np.zeros(len(frictional))
        model.dof_frictionloss[frictional] = 0.0

    def _take_constraints(self, model):
        """Which of MuJoCo's constraint rows the implicit law solves (`constraint_rows`' KEPT,
        TWO_SIDED, ONE_SIDED by mjtConstraint; none with the explicit methods) and room for
        a step's rows, grown when a step has more (`_take_constraint_rows`)."""
        kind = mujoco.mjtConstraint
        self._constraint_kinds = np.full(len(kind.__members__), layout.KEPT,
                                         dtype=np.int64)
        if self._implicit_method:
            self._constraint_kinds[int(kind.mjCNSTR_EQUALITY)] = layout.TWO_SIDED
            for one_sided in (kind.mjCNSTR_LIMIT_JOINT, kind.mjCNSTR_LIMIT_TENDON,
                              kind.mjCNSTR_CONTACT_FRICTIONLESS, kind.mjCNSTR_CONTACT_PYRAMIDAL):
                self._constraint_kinds[int(one_sided)] = layout.ONE_SIDED
            self._constraint_kinds[int(kind.mjCNSTR_CONTACT_ELLIPTIC)] = layout.CONE
        self._sparse = bool(mujoco.mj_isSparse(model))
        self._dense_index = tuple(np.zeros(0, dtype=np.int32) for _ in range(3))
        # contacts' mu, friction, dim, efc_address (read for elliptic cones only)
        self._no_contacts = (np.zeros(0), np.zeros((0, 5)), np.zeros(0, dtype=np.int32),
                             np.zeros(0, dtype=np.int32))
        self._rows_taken = False  # (the last step's: its counter must return to 0)
        self._constraint_room(model.nv, CONSTRAINT_ROOM)
        self._held_constraint = np.zeros(model.nv)  # (`implicit_solve._implicit_step`)
        self._cone_point = np.zeros(model.nv)  # (`implicit_solve._implicit_step`)

    def _constraint_room(self, nv, rows):
        """Room for `rows` constraint rows of nv dofs (`constraint_rows`)."""
        self._constraint_jac = np.zeros((rows, nv))
        self._constraint_columns = np.zeros((rows, nv), dtype=np.int64)
        self._constraint_counts = np.zeros(rows, dtype=np.int64)
        self._constraint_rows = np.zeros((rows, layout.ROW_COLUMNS))
        self._constraint_flags = np.zeros((3, rows), dtype=np.int8)
        self._constraint_efc = np.zeros(rows, dtype=np.int64)  # their rows in mjData's efc

    def _row_kernels(self):
        """The kernels of MuJoCo's constraint rows (`kernel_names.ROWS`: take, report,
        return; prebuilt, or numba's imported where first needed)."""
        if self._rows_kernels is None:
            self._rows_kernels = tuple(map(prebuilt.kernel, ROWS))
        return self._rows_kernels

    def _compile_constraint_rows(self):
        """The constraint rows' kernels (`_row_kernels`) compiled or loaded for mjData's
        arrays, on none of their rows."""
        d = self.data
        take_constraint_rows, report_constraint_forces, return_constraint_rows = (
            self._row_kernels())
        take_constraint_rows(
            self._constraint_kinds, d.efc_type[:0], d.efc_id[:0], d.efc_J[:0], d.efc_D[:0],
            d.efc_aref[:0], d.efc_J_rownnz[:0], d.efc_J_rowadr[:0], d.efc_J_colind[:0],
            self._sparse, *self._no_contacts, self._constraint_jac, self._constraint_columns,
            self._constraint_counts, self._constraint_rows, self._constraint_efc)
        report_constraint_forces(self._constraint_rows, self._constraint_efc, 0, d.efc_aref[:0])
        return_constraint_rows(
            self._constraint_jac, self._constraint_rows, self._constraint_efc, 0, d.efc_J[:0],
            d.efc_aref[:0], d.efc_J_rownnz[:0], d.efc_J_rowadr[:0], d.efc_J_colind[:0],
            self._sparse, self.model.nv)

    def _contacts(self):
        """mjData's contacts' mu, friction, dim and efc_address as the cones' rows read them
        (`constraint_rows.take_constraint_rows`): contiguous copies where the model has
        elliptic cones (as it has now: mjModel's option may change) and there are contacts
        (mjData's are strided views, another kernel signature), else empty."""
        d = self.data
        if not d.ncon or self._options.cone != mujoco.mjtCone.mjCONE_ELLIPTIC:
            return self._no_contacts
        contact = d.contact
        return (np.ascontiguousarray(contact.mu), np.ascontiguousarray(contact.friction),
                np.ascontiguousarray(contact.dim), np.ascontiguousarray(contact.efc_address))

    def _jacobian_index(self):
        """mjData's index arrays of a sparse constraint Jacobian (efc_J_rownnz, efc_J_rowadr,
        efc_J_colind); empty ones for a dense Jacobian, which has none to read (three views
        fewer, ~0.5 us)."""
        d = self.data
        return ((d.efc_J_rownnz, d.efc_J_rowadr, d.efc_J_colind) if self._sparse
                else self._dense_index)

    def _take_constraint_rows(self):
        """This step's rows of the constraints the implicit law solves, taken from mjData
        (made by mj_step1; `constraint_rows.take_constraint_rows`) into the engine's arrays and
        the CONSTRAINT_ROWS counter (and whether there were any, `_rows_taken`); the room
        doubles (at least) when a step needs more. Returns the rows taken."""
        d = self.data
        taken = 0
        if d.nefc:
            index = self._jacobian_index()
            contacts = self._contacts()
            while True:
                taken = self._row_kernels()[0](
                    self._constraint_kinds, d.efc_type, d.efc_id, d.efc_J, d.efc_D,
                    d.efc_aref, *index, self._sparse, *contacts, self._constraint_jac,
                    self._constraint_columns, self._constraint_counts, self._constraint_rows,
                    self._constraint_efc)
                if taken >= 0:
                    break
                self._constraint_room(self.model.nv, max(-taken, 2 * len(self._constraint_rows)))
                self._implicit_arrays = self._implicit_table()
        self._counters[layout.CONSTRAINT_ROWS] = taken
        self._rows_taken = taken > 0
        if taken > 0 and (self._parts == 'plain' or (contacts is not self._no_contacts
                                                      and self._parts == 'rows')):
            self._solve_at_least('rows' if contacts is self._no_contacts else 'cones')
        return taken

    def _solve_at_least(self, parts):
        """Step with the compiled implicit step that solves `parts` (`kernel_names.STEP_PARTS`)
        from now on, where the one loaded solves less: the model made rows that `step_parts`
        did not foresee (its options changed at run time). It loads, or compiles, at its first
        call."""
        if self._parts is None or STEP_PARTS.index(parts) > STEP_PARTS.index(self._parts):
            self._parts = parts
            self._stepping = STEPS[parts]
            self._implicit_step = prebuilt.kernel(self._stepping)

    def _views(self):
        """Record the arrays of the per-step kernels in array tables (`ArrayTable`): numpy views
        of mjModel/mjData and the engine's own arrays, which stay the same objects, at the same
        addresses, for the engine's life."""
        m, d = self.model, self.data
        self._options = m.opt  # a live view: the timestep is read every step
        integrator = m.opt.integrator
        damper = not m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_DAMPER
        if integrator == mujoco.mjtIntegrator.mjINT_EULER:
            damper = damper and not m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_EULERDAMP
        actuators = integrator != mujoco.mjtIntegrator.mjINT_EULER
        self._damping = np.zeros(m.nv)
        self._mass = np.zeros((m.nv, m.nv))
        self._full_inertia, self._full_inertia_args = full_inertia_call(m, d, self._mass)
        self._xipos = d.xipos
        self._xfrc = d.xfrc_applied
        self._settings[layout.DAMPER] = bool(damper)
        self._settings[layout.ACTUATORS] = bool(actuators)
        self._gather_arrays = ArrayTable(*layout.GatherArrays(
            settings=self._settings, counters=self._counters, body_ids=self.body_ids,
            radii=self.radii, body_cluster_start=self._body_cluster_start,
            cluster_plate_start=self._cluster_plate_start, cluster_center=self._cluster_center,
            cluster_radius=self._cluster_radius, positions=self.local_pos,
            normals=self.local_normal, areas=self.areas, surface_grid=self._surface_grid,
            surface_block_max=self._surface_block_max,
            surface_block_min=self._surface_block_min, surface_tiles=self._surface_tiles,
            surface_window_max=self._surface_windows[0],
            surface_window_min=self._surface_windows[1],
            zeta_factors=self._zeta_factors,
            **self._base_arrays,
            **(self.surface.kernel_arrays() if self.deformable else no_bed_arrays()),
            xpos=d.xpos, xmat=d.xmat, xipos=d.xipos, cvel=d.cvel, subtree_com=d.subtree_com,
            body_rootid=m.body_rootid, out_plate=self._plate, out_slot=self._slot,
            slot_body=self._slot_body, slot_start=self._slot_start, table=self._table,
            force=self._force))
        self._solve_space = layout.solve_space(m.nv, len(self.body_ids))
        self._implicit_arrays = self._implicit_table()

    def _implicit_table(self):
        """The ArrayTable of `implicit_solve._implicit_step`'s arrays (`layout.ImplicitArrays`)."""
        m, d = self.model, self.data
        return ArrayTable(*layout.ImplicitArrays(
            settings=self._settings, counters=self._counters, slot_body=self._slot_body,
            slot_start=self._slot_start, out_plate=self._plate, out_slot=self._slot,
            table=self._table,
            force=self._force, body_ids=self.body_ids,
            body_rootid=m.body_rootid, body_dofnum=m.body_dofnum, body_dofadr=m.body_dofadr,
            body_parentid=m.body_parentid, dof_parentid=m.dof_parentid, xipos=d.xipos,
            subtree_com=d.subtree_com, cdof=d.cdof, qvel=d.qvel, qfrc_passive=d.qfrc_passive,
            qfrc_actuator=d.qfrc_actuator, qfrc_applied=d.qfrc_applied,
            qfrc_constraint=d.qfrc_constraint, qfrc_bias=d.qfrc_bias,
            held_constraint=self._held_constraint, cone_point=self._cone_point,
            friction_dofs=self._friction_dofs, friction_force=self._friction_force,
            friction_memory=self._friction_memory, friction_flags=self._friction_flags,
            friction_torque=self._friction_torque, constraint_jac=self._constraint_jac,
            constraint_columns=self._constraint_columns,
            constraint_counts=self._constraint_counts, constraint_rows=self._constraint_rows,
            constraint_flags=self._constraint_flags,
            dof_damping=m.dof_damping, trntype=m.actuator_trntype, trnid=m.actuator_trnid,
            gear=m.actuator_gear, jnt_type=m.jnt_type, jnt_dofadr=m.jnt_dofadr,
            dyntype=m.actuator_dyntype, gaintype=m.actuator_gaintype,
            gainprm=m.actuator_gainprm, biastype=m.actuator_biastype,
            biasprm=m.actuator_biasprm, forcelimited=m.actuator_forcelimited,
            forcerange=m.actuator_forcerange, ctrl=d.ctrl, act=d.act,
            actadr=m.actuator_actadr, actuator_force=d.actuator_force, damping=self._damping,
            mass=self._mass, jac=self._jac, memory=self._plate_memory, work=self._work,
            flags=self._flags, xi_new=self._xi, applied=self._applied, wrench=self._slot_wrench,
            body_wrenches=self.body_wrenches, xfrc_applied=d.xfrc_applied,
            wrench_sum=self._wrench_sum, **self._solve_space._asdict()))

    @property
    def zeta(self):
        """Sand stiffness, N/cm^3. Setting it validates and takes effect on the next step."""
        return self._zeta

    @zeta.setter
    def zeta(self, value):
        self._zeta = validated_zeta(value)
        self._settings[layout.ZETA] = zeta_to_si(self._zeta)

    def zeta_at(self, x, y):
        """The zeta (N/cm^3) that plates meet at world (x, y) (m; arrays broadcast): `zeta`
        times the zeta map's factor there (1 without a map, or outside it)."""
        factor = 1.0 if self.zeta_map is None else self.zeta_map.factor(x, y)
        return self._zeta * factor

    @property
    def plates_active(self):
        """Plates in the sand and leading at the last step."""
        return int(self._counters[layout.LEADING])

    @property
    def solves(self):
        """Implicit solves so far (about one per step with sand contact)."""
        return int(self._counters[layout.SOLVES])

    @property
    def unsettled_steps(self):
        """Steps so far in which a plate was frozen (anti-cycling) or the sets had not
        settled."""
        return int(self._counters[layout.UNSETTLED])

    @property
    def handed_back_steps(self):
        """Steps so far whose constraint rows the implicit solve could not settle and handed
        back to MuJoCo's own solve (`implicit_solve._implicit_step`)."""
        return int(self._counters[layout.HANDED_BACK])

    @property
    def plates_total(self):
        """Number of plates on all sand bodies."""
        return len(self.areas)

    def forget_last_step(self):
        """For a state that does not follow the last step (a reset): the plates' and
        frictional joints' sets in it (the solve's start), the EMA's history, a hand-back's
        held constraint force and the wrenches summed for `mean_wrenches` are forgotten, so
        the next step starts as the first did. The counters keep counting."""
        self._plate_memory[:] = -1
        self._friction_memory[:] = -1
        self._ema_step[:] = -2
        self._counters[layout.HANDED_BACK_AT] = 0
        self._wrench_sum[:] = 0.0
        self._sum_since = self._counters[layout.STEPS]

    def step(self):
        """Advance the model one timestep with sand forces."""
        model, data = self.model, self.data
        mujoco.mj_step1(model, data)
        self.apply()
        mujoco.mj_step2(model, data)

    def apply(self):
        """Compute the sand wrenches from the current state (after mj_step1) and write them
        into xfrc_applied of the sand bodies."""
        if self._implicit_method:
            self._implicit()
        else:
            had_slots = self._counters[layout.SLOTS]
            self._gather(self._gather_arrays.table)
            if self._counters[layout.SLOTS] or had_slots:  # (zeros once the last leave)
                self._explicit()

    @property
    def kernels(self):
        """One line: whether this engine's step calls the prebuilt kernels (its gather, and
        its implicit step or the explicit methods' kernels) or numba's, and why
        (`prebuilt.state`)."""
        stepping = (self._stepping,) if self._implicit_method else EXPLICIT
        return prebuilt.state(self._gathering, *stepping)

    def _explicit(self):
        """Explicit sand wrenches ('ema' or 'none': explicit.smoothed_wrenches) of the plates
        gathered this step, written to xfrc_applied."""
        alpha = self.low_velocity.ema_alpha if self.low_velocity.method == 'ema' else 1.0
        counters = self._counters
        slots = counters[layout.SLOTS]
        self._smoothed_wrenches(counters[layout.GATHERED], slots, self._plate, self._slot,
                                   self._table, self._force, alpha, counters[layout.STEPS],
                                   self._ema_force, self._ema_step, self._applied,
                                   self._slot_wrench)
        self._scatter(slots)

    def _scatter(self, slots):
        """Write the wrenches of the first `slots` slots (zero for the other sand bodies)."""
        self._scatter_wrenches(slots, self._slot_body, self._slot_wrench, self.body_ids,
                                  self.body_wrenches, self._xfrc, self._xipos,
                                  self._wrench_sum)

    def _implicit(self):
        """The plates in the sand and their implicit wrenches, written to xfrc_applied
        (the surface's gather kernel and implicit_solve._implicit_step, after MuJoCo's actuator
        forces and dense inertia of this state)."""
        mujoco.mj_fwdActuation(self.model, self.data)
        self._full_inertia(*self._full_inertia_args)
        self._gather(self._gather_arrays.table)
        # (most steps of most robots have no rows: one attribute read, ~0.1 us, for them)
        taken = self._take_constraint_rows() if self.data.nefc or self._rows_taken else 0
        self._implicit_step(self._options.timestep, self._implicit_arrays.table)
        if taken:
            d, counters = self.data, self._counters
            _, report_constraint_forces, return_constraint_rows = self._row_kernels()
            if counters[layout.HANDED_BACK_AT] == counters[layout.STEPS]:  # MuJoCo's
                return_constraint_rows(
                    self._constraint_jac, self._constraint_rows, self._constraint_efc, taken,
                    d.efc_J, d.efc_aref, *self._jacobian_index(), self._sparse, self.model.nv)
            else:
                report_constraint_forces(self._constraint_rows, self._constraint_efc, taken,
                                         d.efc_aref)

    def _load_kernels(self):
        """Load every compiled kernel the engine runs from numba's cache (or compile it) now,
        as part of start-up, and not at the first step in contact with sand, where it would
        stall a running simulation (a paced ROS node) for up to a few tenths of a second:
        the gather kernel by its signature, the others by a run on no plates (their outputs
        are scratch). Where any of them had to compile, the time that took is recorded in
        the cache (`kernel_cache.record_cold_start`): the next notice that they compile
        quotes it (`cold_start_estimate`)."""
        cold = _uncached_key(engine_kernels(self.low_velocity.method, self._surface_kind,
                                            self.deformable, self._parts))
        wall, cpu = time.perf_counter(), _cpu_seconds()
        self._compile_kernels()
        #: (names of the kernels this engine compiled, wall s it took); ('', 0.0): all cached
        self.compiled = (cold, time.perf_counter() - wall if cold else 0.0)
        if cold:
            record_cold_start(prebuilt.dispatcher(STEPS['plain']), cold, self.compiled[1],
                              _cpu_seconds() - cpu)
        self._counters[:] = 0
        self._wrench_sum[:] = 0.0

    def _compile_kernels(self):
        """`_load_kernels`' loads: with a cold cache (a first run) and the implicit method,
        the gather kernel and a share of the kernels the implicit step calls
        (`implicit_solve.background_kernels`, where the step is to compile: its module is
        imported then) compile in a second process
        (`BackgroundCompile`) while this one compiles the step (which then loads that share
        from the cache): on two cores the start-up is about the longer of the two."""
        if self._implicit_method:
            background = []
            if not ready(self._stepping):  # (a compile: numba's, and the step's module)
                from .implicit_solve import background_kernels
                background = [(kernel, signature) for kernel, signature
                              in background_kernels(self._parts) if not is_cached(kernel)]
            if not ready(self._gathering):
                background.append((prebuilt.dispatcher(self._gathering), TABLE_SIGNATURE))
            with (BackgroundCompile(background) if background
                  else contextlib.nullcontext()) as compiling:
                self._implicit_step(self._options.timestep, self._implicit_arrays.table)
                self._plate_forces(self._implicit_arrays.table)
                if self._parts != 'plain':
                    self._compile_constraint_rows()
                if compiling is not None:
                    compiling.wait()  # (a kernel it did not cache compiles below)
        else:
            self._explicit()
        if not prebuilt.has(self._gathering):
            load(prebuilt.dispatcher(self._gathering), TABLE_SIGNATURE)

    def mean_wrenches(self):
        """(nb, 6) mean of each sand body's wrench over the steps since the last call (what
        a filtered force sensor reports over that window), as [force (N); torque about the
        world origin (N m)], world axes; then restarts the mean. With no step since, the
        wrench of the last step."""
        steps = self._counters[layout.STEPS] - self._sum_since
        if steps > 0:
            mean = self._wrench_sum / steps
        else:
            force = self.body_wrenches[:, :3]
            mean = np.hstack([force, self.body_wrenches[:, 3:]
                              + np.cross(self._xipos[self.body_ids], force)])
        self._wrench_sum[:] = 0.0
        self._sum_since = self._counters[layout.STEPS]
        return mean

    def active_plates(self):
        """Plates in the sand at the last step: (positions (K, 3) m, forces (K, 3) N, areas
        (K,) m^2), world frame; forces after the low-velocity treatment, on the body."""
        k = self._counters[layout.GATHERED]
        if self._implicit_method:
            self._plate_forces(self._implicit_arrays.table)
        com = self._xipos[self.body_ids[self._slot_body[self._slot[:k]]]]
        lever = self._table[layout.LEVER:layout.LEVER + 3, :k].T
        return lever + com, self._applied[:, :k].T.copy(), self.areas[self._plate[:k]]
