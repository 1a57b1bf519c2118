"""What start-up tells the user the sand will not do for their model, each as one notice
with the key that changes it: hold bodies the model gives no collision geom, bear the robot
on sand bodies too small for its weight (robot/bearing.py), hold free bodies that have no
sand body (another robot, a loose crate), run MuJoCo's noslip iterations on the constraints
the sand solve takes, resolve footprints finer than the deformable bed's cells, or mark
cells finer than its plates."""
import numpy as np

from ..robot.bearing import bearing
from ..robot.sand_bodies import free_root_joint, geom_lowest_z, unheld_free_trees
from ..sand.geoms import bodies_without_collision
from ..units import zeta_to_si

#: Names a notice lists before "and N more".
SHOWN_NAMES = 5


def first_few(names):
    """'a, b, c and N more': the first SHOWN_NAMES of `names`, and how many are left."""
    more = len(names) - SHOWN_NAMES
    return ', '.join(names[:SHOWN_NAMES]) + (f' and {more} more' if more > 0 else '')


def caveats(model, data, engine, scene, base, sand_count):
    """Notices (str) for a model in its initial pose (`data`, after mj_kinematics) with its
    SandEngine `engine`, its SceneConfig `scene` and its base body id `base`; the engine's
    first `sand_count` bodies are the sand bodies (the others: robot/sand_bodies.py, "Other
    bodies"), which the notices on bearing and on the bed's cells are about."""
    notices = []
    bare = [model.body(b).name or f'body {b}' for b in bodies_without_collision(model)
            if free_root_joint(model, b) is not None]  # (a rig fixed to the world: by design)
    if bare:
        notices.append(f'bodies without a collision geom (the model gives them none, or only '
                       f'visual ones): {first_few(bare)}; should the robot fall onto them they '
                       'pass through the sand, watched by their origins only (give them '
                       'collision geoms, or name those with visual geoms beside the sand '
                       'bodies, rft.sand_bodies: [auto, NAME], for their visual geoms to carry '
                       'plates)')
    if not scene.keep_floor:  # (else the floor holds the robot and any other body)
        notices += _bearing_notice(model, data, engine, scene.zeta, base, sand_count)
        unheld = unheld_free_trees(model, engine.body_ids)
        if unheld:
            notices.append(f'free bodies without a sand body, which the sand does not hold: '
                           f'{first_few(unheld)}; they fall through its surface unless other rigid ground '
                           'holds them (name their bodies in rft.sand_bodies; beside auto: '
                           f'[auto, {unheld[0]}])')
    if engine.deformable:
        notices += (_coarse_bed_notice(engine, sand_count)
                    + _fine_bed_notice(engine, sand_count))
    noslip = int(model.opt.noslip_iterations)
    if noslip and scene.low_velocity['method'] == 'implicit':
        notices.append(f"MuJoCo's noslip iterations ({noslip}) do not act on the constraints "
                       'the sand solve takes (rigid contacts, limits, equalities; '
                       'docs/robots.md); rft.low_velocity.method ema or none leaves them to '
                       'MuJoCo')
    return notices


def _coarse_bed_notice(engine, sand_count):
    """[notice] where the deformable bed's cells are wider than a sand body (its width: the
    middle of its plates' three extents along the body axes, a shin's or a foot's
    thickness, a sole's width): a footprint is whole cells, so such a body displaces the
    sand of cells around it, far more than its own volume; else []."""
    cell = engine.surface.cell
    starts = engine.plate_start[:sand_count + 1]
    narrow = []
    for name, a, b in zip(engine.body_names, starts[:-1], starts[1:]):
        local = engine.local_pos[a:b]
        extent = float(np.median(local.max(axis=0) - local.min(axis=0)))
        if extent < cell:
            narrow.append(f'{name} ({extent * 100:.3g} cm)')
    if not narrow:
        return []
    return [f'sand.deformable.cell {cell:g} m is wider than sand bod'
            f'{"ies" if len(narrow) > 1 else "y"} {first_few(narrow)}: footprints are whole '
            'cells, so their craters and the sand displaced grow with the cell, not with the '
            'body (sand.deformable.cell: a cell well below that width)']


#: A deformable bed's cells narrower than this fraction of its plates' spacing are said.
FINE_CELL_FRACTION = 0.5


def _fine_bed_notice(engine, sand_count):
    """[notice] where the deformable bed's cells are narrower than FINE_CELL_FRACTION of the
    sand bodies' plates' spacing (the median plate's side, the square root of its area): a
    plate marks the cell under its centre, so cells between the plates stay unmarked, and a
    footprint becomes pits with the sand they displaced piled between them, under the foot
    (a hexapod's feet sank 5x deeper at 1 mm cells than at 2 to 20 mm); else []."""
    areas = engine.areas[:engine.plate_start[sand_count]]
    cell, side = engine.surface.cell, float(np.median(np.sqrt(areas)))
    if cell >= FINE_CELL_FRACTION * side:
        return []
    return [f"sand.deformable.cell {cell:g} m is narrower than half the sand bodies' plate "
            f'spacing ({side * 1e3:.3g} mm, the median plate): a plate marks the cell under its '
            'centre, so the cells between plates stay unmarked and a footprint becomes pits '
            'with sand piled between them, under the foot (sand.deformable.cell at least '
            'half the plate spacing, or more plates: rft.plates_per_body)']


def _bearing_notice(model, data, engine, zeta, base, sand_count):
    """[notice] where a free-floating robot bears its weight only with bodies in the sand
    that are not sand bodies (robot/bearing.py), at zeta (N/cm^3); else []."""
    if free_root_joint(model, base) is None:
        return []
    root = model.body_rootid[base]
    starts = engine.plate_start[:sand_count + 1]
    sand_ids = engine.body_ids[:sand_count]
    plates = [(engine.local_normal[a:b], engine.local_pos[a:b], engine.areas[a:b])
              for a, b in zip(starts[:-1], starts[1:])]
    poses = [(data.xpos[b], data.xmat[b].reshape(3, 3)) for b in sand_ids]
    others = [g for g in range(model.ngeom) if model.body_rootid[model.geom_bodyid[g]] == root
              and model.geom_bodyid[g] not in sand_ids]
    others_lowest = min((geom_lowest_z(model, data, g) for g in others), default=float('inf'))
    mass = float(model.body_subtreemass[root])
    found = bearing(mass, model.opt.gravity, zeta_to_si(zeta), poses, plates, others_lowest)
    if not found.sinks:
        return []
    return [f'sand bodies: their {found.area_m2 * 1e4:.3g} cm^2 facing down bear the robot\'s '
            f'{mass:.3g} kg only about {found.depth_m * 100:.3g} cm deep (zeta A z = m g), '
            f'deeper than its other bodies clear them ({found.clearance_m * 100:.3g} cm): those '
            + ('bear the rest on their coarser plates (rft.other_bodies_density_per_mm2)'
               if len(engine.body_ids) > sand_count else
               'pass through its surface, which does not hold them')
            + "; name more sand bodies (rft.sand_bodies; '*' takes every body) or take their "
            'plates from their visual geoms (rft.plate_geoms: visual)']
