"""The package's compiled kernels that a run calls from Python, by name: the dotted path
('package.module.function') of each numba kernel the sand engine and the built-in gaits
call, so that they can choose their kernels and call the prebuilt ones (`prebuilt.kernel`)
without importing the modules that define them, which import numba (0.3 to 0.5 s of a start,
and as much again to load its first kernel; `prebuilt.dispatcher` imports one where a run
needs numba's); and `PREBUILT`, what `rft-sim warmup` builds ahead of time (`prebuild`).
Plain names and numba's text of argument types: nothing here is compiled, and nothing of the
package is imported (the engine and the gaits import this, through `prebuilt` too: it sits
below them)."""
_SAND = 'rft_sim_ros.sand'
_GAITS = 'rft_sim_ros.scenes.gait_kernels'

#: The parts the compiled implicit steps solve, one step each (`sand.implicit_solve`):
#: 'plain' (the sand and joint friction), 'rows' (and MuJoCo's equality, limit and pyramidal
#: contact rows), 'cones' (and elliptic cones' rows); each solves what the ones before it do.
STEP_PARTS = ('plain', 'rows', 'cones')
#: The compiled implicit steps (`implicit_solve._implicit_step`), by the parts they solve.
STEPS = {parts: f'{_SAND}.implicit_solve.implicit_step_{parts}' for parts in STEP_PARTS}
#: numba's text of the argument types of a kernel taking its arrays as one table
#: (`sand.array_table`: its int64 table).
TABLE_SIGNATURE = '(int64[:, ::1],)'
#: numba's text of the compiled steps' argument types (timestep, array table).
STEP_SIGNATURE = '(float64, int64[:, ::1])'
#: The gather kernel of each kind of rigid surface, by its name (`sand.surface_codes.KINDS`),
#: and of deformable sand (`gather._gather_plates`).
GATHERS = {kind: f'{_SAND}.gather.gather_{kind}' for kind in ('plane', 'slope', 'grid')}
GATHER_DEFORMABLE = f'{_SAND}.gather.gather_deformable'
#: The plates' forces of the last implicit step (`implicit_law.implicit_plate_forces`).
PLATE_FORCES = f'{_SAND}.implicit_law.implicit_plate_forces'
#: MuJoCo's constraint rows taken into the implicit solve and given back
#: (`constraint_rows`): take, report, return.
ROWS = tuple(f'{_SAND}.constraint_rows.{name}' for name in (
    'take_constraint_rows', 'report_constraint_forces', 'return_constraint_rows'))
#: The explicit methods' wrenches and their scatter into xfrc_applied.
EXPLICIT = (f'{_SAND}.explicit.smoothed_wrenches', f'{_SAND}.mujoco_terms.scatter_wrenches')
#: A height grid's heights at points (`sand.surface.HeightGrid.height`).
GRID_HEIGHTS = f'{_SAND}.surface_kernels.grid_heights'


#: The built-in gaits' kernels (`scenes.gait_kernels`): the foot path, the lateral legs'
#: inverse kinematics, the tripod's and the trot's targets.
FOOT_PATH, LEG_INVERSE, TRIPOD_TARGETS, TROT_TARGETS = (
    f'{_GAITS}.{name}' for name in ('foot_path', 'leg_inverse', 'tripod_targets', 'trot_targets'))

_F, _I, _B = 'float64', 'int64', 'boolean'  # (numba's text of scalar and array types)
_F1, _F2, _I1, _I2 = 'float64[::1]', 'float64[:, ::1]', 'int64[::1]', 'int64[:, ::1]'
_I32 = 'int32[::1]'

#: The kernels that take their arrays as one table (`sand.array_table`), with numba's text
#: of their argument types.
TABLE_KERNELS = (*((gathering, TABLE_SIGNATURE) for gathering in GATHERS.values()),
                 (GATHER_DEFORMABLE, TABLE_SIGNATURE),
                 *((STEPS[parts], STEP_SIGNATURE) for parts in STEP_PARTS),
                 (PLATE_FORCES, TABLE_SIGNATURE))
#: The other kernels a run calls from Python, with the argument types it calls them with
#: (those of mjData's arrays and the engine's for the constraint rows' and the explicit
#: methods'; a grid's read-only heights; the gaits' own).
CALLED_KERNELS = (
    (ROWS[0], f'({_I1}, {_I32}, {_I32}, {_F1}, {_F1}, {_F1}, {_I32}, {_I32}, {_I32}, {_B}, '
              f'{_F1}, {_F2}, {_I32}, {_I32}, {_F2}, {_I2}, {_I1}, {_F2}, {_I1})'),
    (ROWS[1], f'({_F2}, {_I1}, {_I}, {_F1})'),
    (ROWS[2], f'({_F2}, {_F2}, {_I1}, {_I}, {_F1}, {_F1}, {_I32}, {_I32}, {_I32}, {_B}, {_I})'),
    (EXPLICIT[0], f'({_I}, {_I}, {_I1}, {_I1}, {_F2}, {_F2}, {_F}, {_I}, {_F2}, {_I1}, {_F2}, '
                  f'{_F2})'),
    (EXPLICIT[1], f'({_I}, {_I1}, {_F2}, {_I1}, {_F2}, {_F2}, {_F2}, {_F2})'),
    (GRID_HEIGHTS, f"(Array(float64, 2, 'C', readonly=True), {_F}, {_F}, {_F}, {_F}, {_F1}, "
                   f"{_F1}, {_F1})"),
    (FOOT_PATH, f'({_F1}, {_F}, {_F}, {_F})'),
    (LEG_INVERSE, f'({_F2}, {_F2}, {_F2}, {_F1}, {_F}, {_F}, {_F})'),
    (TRIPOD_TARGETS, f'({_F}, {_F1}, {_F}, {_F}, {_F}, {_F}, {_F2}, {_F2}, {_F1}, {_F}, {_F}, '
                     f'{_F})'),
    (TROT_TARGETS, f'({_F}, {_F1}, {_F}, {_F}, {_F}, {_F}, {_F}, {_F}, {_F}, {_F})'))
#: What `rft-sim warmup` builds ahead of time (`prebuild`): every kernel above, with its
#: argument types, which each call's arguments are checked against (`prebuilt.checked`).
PREBUILT = TABLE_KERNELS + CALLED_KERNELS


def gather(kind, deformable=False):
    """The name of the gather kernel of a surface of kind `kind` ('plane', 'slope', 'grid':
    `sand.surface_codes.KINDS`), or of deformable sand (on a 'grid')."""
    return GATHER_DEFORMABLE if deformable else GATHERS[kind]


def function(name):
    """The function's own name in kernel `name` (what numba's cache and notices call it)."""
    return name.rpartition('.')[2]
