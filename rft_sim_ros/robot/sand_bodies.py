"""Which bodies of a robot touch the sand, and which legs they form, without hand work.

Sand bodies are given as MuJoCo body names, glob patterns (`'*_calf'`, `'*foot*'`, matched
with fnmatch, case-sensitive) or `auto`, alone or beside names and globs (`[auto, crate]`:
auto's picks for the robot, and the crate):

auto picks, in the initial pose, one body per kinematic branch: the branches are the
subtrees that hang by a joint from the base body's rigid group (the base and the bodies
welded to it, e.g. a URDF `base` link fixed to the trunk), plus that group itself, and a
branch is split where two or more limbs that reach the ground hang by joints from a body
that does not (a humanoid's legs hang from a pelvis below its waist joint: two branches,
where a foot's toes are one, and a shin's welded lower link stays with it); in each, the
body whose collision geoms (contype or conaffinity nonzero) reach lowest (lowest point of
the geoms' bounding boxes, world z) is that branch's candidate. The ground band: within
AUTO_TOLERANCE of the robot's height (base origin above the lowest collision point of all)
from the lowest point of all. The candidates kept are those in it: the feet of a standing
robot, not a head or a tail held higher. Besides them, every body that touches the ground
(its lowest point within AUTO_CONTACT of the robot's height of the lowest point of all) is
picked: the links of a snake lying in the sand, which hang from each other in one branch,
or toes flat beside their foot.

Legs (for the per-leg wrenches): unless the scene gives them, each branch that holds sand
bodies is one leg (split where two or more limbs that hold sand bodies hang by joints from
a body that is not one), named after the branch's first body (the body that hangs from the
base's group or from the fork; the base's own name for the group), its sand bodies listed
from the base outwards, so the last one (the deepest in the tree) is the leg's reference
point.

Other bodies (`other_bodies`): every moving body with collision geoms that the sand bodies
leave out (a shin, the trunk, a head, an arm, a loose crate) carries plates too, at a coarser
density (rft.other_bodies_density_per_mm2, OTHER_BODIES_DENSITY_PER_MM2 by default), so that
nothing passes through the sand: a robot that falls lies on it. They are not legs: a leg is
still a branch that holds sand bodies, and an other body in such a branch (a shin, a thigh
above its foot) adds its wrench to that leg's (the sand's whole push on the leg), its point
still the sand body's; an other body in no leg's branch (the trunk, an arm) is in no leg's
wrench (`legs_from_tree`). Their plates cost a bounding-sphere test a step while above the
sand. With the key null only the sand bodies carry plates, and free-floating trees that hold
none (another robot, a loose crate) are named at start-up (`unheld_free_trees`): the sand
does not hold them.
"""
import fnmatch
import re

import mujoco
import numpy as np

from ..sand.geoms import SAND_SURFACE_BIT, is_collision_geom

#: The sand-body pattern that asks for `auto_sand_bodies`.
AUTO = 'auto'
#: auto keeps branches whose lowest point is within this fraction of the robot's height of
#: the lowest point of all.
AUTO_TOLERANCE = 0.25
#: auto also keeps every body whose lowest point is within this fraction of the robot's
#: height of the lowest point of all (it touches the ground).
AUTO_CONTACT = 0.01
#: Plates per mm^2 on the other bodies (rft.other_bodies_density_per_mm2): one plate per
#: 10 cm^2, triangles about 5 cm on a side. On its side a fallen robot's trunk and limbs bear
#: its weight at a sinkage of millimetres (zeta A z = m g: 30 kg on 0.1 m^2 of zeta 3.75
#: N/cm^3 sinks 0.8 mm), and a 5 cm facet on a 5 cm radius limb lies 6 mm inside its arc, so
#: its lowest point stays within a centimetre or so of the surface; a small body gets the
#: coarsest tessellation of its geoms (`sand.geoms.body_plates`).
OTHER_BODIES_DENSITY_PER_MM2 = 0.001


def collision_geoms(model, body):
    """Ids of the collision geoms of body `body`."""
    start, count = model.body_geomadr[body], model.body_geomnum[body]
    return [g for g in range(start, start + count) if start >= 0 and is_collision_geom(model, g)]


def geom_lowest_z(model, data, geom):
    """World z (m) of the lowest point of geom `geom`'s bounding box in the current pose."""
    return float(geom_lowest_point(model, data, geom)[2])


def geom_lowest_point(model, data, geom):
    """World (3,) position (m) of the lowest corner of geom `geom`'s bounding box in the
    current pose (a level face: one of its corners)."""
    rotation = data.geom_xmat[geom].reshape(3, 3)
    center, half = model.geom_aabb[geom, :3], model.geom_aabb[geom, 3:]
    corner = center - np.where(rotation[2] >= 0.0, half, -half)  # z falls towards it
    return data.geom_xpos[geom] + rotation @ corner


def geom_footprint(model, data, geom):
    """World (x0, x1, y0, y1) (m): the horizontal extent of geom `geom`'s bounding box in the
    current pose."""
    rotation = data.geom_xmat[geom].reshape(3, 3)[:2]
    center, half = model.geom_aabb[geom, :3], model.geom_aabb[geom, 3:]
    middle, reach = data.geom_xpos[geom, :2] + rotation @ center, np.abs(rotation) @ half
    return middle[0] - reach[0], middle[0] + reach[0], middle[1] - reach[1], middle[1] + reach[1]


def _name(model, body):
    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body) or f'body{body}'


def branches(model, base, ground=frozenset()):
    """{first body of the branch: [bodies of the branch]}: the base's rigid group (the base
    and the bodies welded to it without a joint, e.g. a URDF `base` link fixed to the trunk)
    is one branch, keyed by the base; each subtree hanging from that group by a joint is
    another, keyed by its first body, and so is each limb hanging from a fork: a body not in
    `ground` (body ids) from which two or more subtrees holding bodies of `ground` hang by
    joints (welded parts, like a shin's lower link beside its foot, stay with their parent).
    Bodies in tree order (a parent before its children)."""
    rigid = model.body_weldid[base]
    parents = model.body_parentid
    holds = np.zeros(model.nbody, dtype=bool)  # its subtree has a body of `ground`
    jointed = model.body_jntnum > 0  # hangs from its parent by a joint
    held_limbs = np.zeros(model.nbody, dtype=int)  # jointed children that hold some
    for body in range(model.nbody - 1, base, -1):  # children after their parents
        holds[body] |= body in ground
        if holds[body]:
            holds[parents[body]] = True
            held_limbs[parents[body]] += jointed[body]
    out = {base: [base]}
    root_of = {base: base}
    for body in range(base + 1, model.nbody):
        parent = int(parents[body])
        if parent not in root_of:
            continue  # not below the base
        fork = (holds[body] and jointed[body] and held_limbs[parent] >= 2
                and parent not in ground)
        if root_of[parent] == base and model.body_weldid[body] == rigid and not fork:
            root_of[body] = base  # welded to the base: part of its group
        elif root_of[parent] == base or fork:
            root_of[body] = body  # hangs from the base's group by a joint, or from a fork
            out[body] = []
        else:
            root_of[body] = root_of[parent]
        out[root_of[body]].append(body)
    return out


def auto_sand_bodies(model, data, base):
    """Body ids `auto` picks (module docstring), in the current pose (after mj_kinematics)."""
    lowest = {}  # body: the lowest point of its collision geoms, for bodies below the base
    for bodies in branches(model, base).values():
        for b in bodies:
            if collision_geoms(model, b):
                lowest[b] = min(geom_lowest_z(model, data, g) for g in collision_geoms(model, b))
    if not lowest:
        raise ValueError(f'sand bodies auto: the robot has no collision geoms under '
                         f'{_name(model, base)!r} (contype/conaffinity 0 everywhere); name the '
                         'sand bodies instead')
    bottom = min(lowest.values())
    height = max(data.xpos[base, 2] - bottom, 0.0)
    band = bottom + AUTO_TOLERANCE * height
    ground = frozenset(b for b, z in lowest.items() if z <= band)
    picked = {b for b, z in lowest.items() if z <= bottom + AUTO_CONTACT * height}
    for bodies in branches(model, base, ground).values():
        candidates = [(lowest[b], b) for b in bodies if b in lowest]
        if candidates and min(candidates)[0] <= band:
            picked.add(min(candidates)[1])
    return sorted(picked)


def other_bodies(model, sand_bodies):
    """Names of the moving bodies (not welded to the world) with collision geoms that are not
    in `sand_bodies` (names), in model order: those that carry plates at the other bodies'
    density (module docstring)."""
    chosen = set(sand_bodies)
    return [_name(model, b) for b in range(1, model.nbody)
            if model.body_weldid[b] != 0 and collision_geoms(model, b)
            and _name(model, b) not in chosen]


def unheld_free_trees(model, sand_bodies):
    """Names of the root bodies of free-floating trees (a free joint on the root) that have
    collision geoms and no body in `sand_bodies` (ids): the sand does not hold them (another
    robot, a loose crate)."""
    roots = model.body_rootid
    held = {int(roots[b]) for b in sand_bodies}
    colliding = {int(roots[model.geom_bodyid[g]]) for g in range(model.ngeom)
                 if is_collision_geom(model, g)}
    return [_name(model, root) for root in sorted(colliding - held - {0})
            if free_root_joint(model, root) is not None]


def free_root_joint(model, body):
    """Id of the free joint on the root of body `body`'s tree, or None (a tree fixed to the
    world)."""
    joint = model.body_jntadr[model.body_rootid[body]]
    free = joint >= 0 and int(model.jnt_type[joint]) == mujoco.mjtJoint.mjJNT_FREE
    return int(joint) if free else None


def match_bodies(names, patterns, shaped=None):
    """Body names that match `patterns` (names or fnmatch globs): in the patterns' order, a
    glob's matches in model order, of the bodies in `shaped` (names of the bodies with geoms;
    None: all), so that '*' takes the whole robot but not the world or a frame without
    geoms; a name is taken as it is. Raises ValueError naming a pattern that matches
    nothing."""
    chosen = []
    for pattern in patterns:
        glob = any(c in pattern for c in '*?[')
        hits = [n for n in names if fnmatch.fnmatchcase(n, pattern)
                and (shaped is None or not glob or n in shaped)]
        if not hits:
            listed = [n for n in names if n and (shaped is None or not glob or n in shaped)]
            raise ValueError(f'sand body {pattern!r} matches no body of the model'
                             f'{" with geoms" if glob and shaped is not None else ""} '
                             f'(bodies{" with geoms" if glob and shaped is not None else ""}: '
                             f'{", ".join(listed) or "none"})')
        chosen += [n for n in hits if n not in chosen]
    return chosen


def resolve_sand_bodies(model, data, patterns, base):
    """Names of the sand bodies that `patterns` (list of names, globs and `AUTO`) choose:
    auto's picks first, then the others' matches not among them."""
    chosen = [_name(model, b) for b in auto_sand_bodies(model, data, base)] \
        if AUTO in patterns else []
    others = [p for p in patterns if p != AUTO]
    if others:
        names = [_name(model, b) for b in range(model.nbody)]
        shaped = {names[b] for b in range(1, model.nbody) if model.body_geomnum[b] > 0}
        chosen += [n for n in match_bodies(names, others, shaped) if n not in chosen]
    return chosen


def legs_from_tree(model, sand_bodies, base, others=()):
    """{leg name: (body names, base outwards)} by branch (module docstring): each branch
    that holds sand bodies is a leg, its sand bodies and the `others` (names of other
    plated bodies) of the branch in tree order, the last sand body last (the leg's
    point); an other body in no such branch is in no leg."""
    ids = {model.body(name).id: name for name in sand_bodies}
    extra = {model.body(name).id: name for name in others}
    legs = {}
    for first, bodies in branches(model, base, frozenset(ids)).items():
        mine = [ids[b] for b in bodies if b in ids]
        if mine:
            point = mine[-1]
            leg = [ids.get(b) or extra[b] for b in bodies if b in ids or b in extra]
            leg.remove(point)
            legs[_leg_name(_name(model, first))] = (*leg, point)
    unplaced = set(sand_bodies) - {b for leg in legs.values() for b in leg}
    for name in sorted(unplaced):  # sand bodies outside the base's subtree: a leg each
        legs[_leg_name(name)] = (name,)
    return legs


def _leg_name(name):
    """A body name made usable as a leg (ROS topic token): letters, digits, underscores."""
    token = re.sub(r'[^A-Za-z0-9_]', '_', name)
    return token if token[:1].isalpha() else f'leg_{token}'


def keep_sand_visuals(spec, patterns, visual=False):
    """Before compiling with discardvisual: mark the visual geoms (contype = conaffinity = 0)
    of the bodies that `patterns` (names/globs; auto, which only looks at collision geoms,
    is passed over) name as their sand surface (`SAND_SURFACE_BIT`), so that they stay and
    carry the plates (`sand.geoms.body_geoms`): those of a body with no collision geom, or
    with `visual` (rft.plate_geoms: visual) those of every such body."""
    patterns = [p for p in patterns if p != AUTO]
    bodies = [b for b in spec.bodies if b.name and any(
        fnmatch.fnmatchcase(b.name, p) for p in patterns)]
    for body in bodies:
        visuals = [g for g in body.geoms if not (g.contype or g.conaffinity)]
        if visuals and (visual or len(visuals) == len(body.geoms)):
            for geom in visuals:
                geom.conaffinity = SAND_SURFACE_BIT
