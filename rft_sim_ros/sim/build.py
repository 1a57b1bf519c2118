"""Building a simulation from a scene, stage by stage: the robot's description, its MuJoCo
model (the scenario's edits, the sand bodies' visuals, the joint interfaces), the sand's
surface and the ground it replaces, the initial pose, the sand bodies and their plates,
the deformable bed, the sand engine, and the robot's legs. `Simulation.__init__`
(sim/simulation.py) calls these in that order and then steps what they built.

Each stage takes what the stages before it made and the scene (`SceneConfig`), and appends
what it decided for the user to `notices` (a list of lines shown at start-up). Bad input is
a SceneError naming the scene key (`scene.locator`) or the scene.
"""
from collections import namedtuple

import mujoco
import numpy as np

from ..rft.force_law import DynamicTerm
from ..robot.description import DescriptionError, load_description
from ..robot.joints import add_joint_interfaces, movable_joints, position_servos
from ..robot.pose import (DEFAULT_KEYFRAMES, initial_keyframe, keyframe_label, parse_spawn,
                          set_initial_pose)
from ..robot.sand_bodies import (AUTO, free_root_joint, keep_sand_visuals, legs_from_tree,
                                 other_bodies, resolve_sand_bodies)
from ..sand.deformable import DeformableSand
from ..sand.engine import LowVelocity, SandEngine, can_collide
from ..sand.geoms import body_plates
from ..sand.paper_loop import PaperLoopEngine
from ..sand.surface import (CHECKED_SLOPE_DEG, Surface, hfield_geom, hfield_label,
                            surface_from_settings)
from ..sand.zeta_map import zeta_map_from_settings
from ..scenes.config import SceneError
from ..scenes.scenarios import failure_line, rows_expected, scenario_files
from .caveats import first_few

#: A plane whose upward normal is within this angle of +z is a floor (steeper: a wall).
FLOOR_TILT_DEG = 45.0

#: The compiled model and what compiling it decided: the initial keyframe (id or None), the
#: joints' interfaces (`robot.joints.add_joint_interfaces`) and the sand bodies' patterns
#: (auto resolved to names where visual geoms carry plates).
CompiledModel = namedtuple('CompiledModel', 'model keyframe joint_plan patterns')

#: The legs (`legs_of`): {leg: sand bodies}, the leg names, each leg's point (its last
#: body's id), the engine's body index of every (leg, sand body) pair (rows) and the
#: (legs, rows) 0/1 matrix that sums the rows of each leg.
Legs = namedtuple('Legs', 'legs names feet rows membership foot_rows')


def in_scenario(scene, scenario, call, *args):
    """call(*args) at start-up; an exception that the scenario's code raised is a SceneError
    naming its file and line (the run does not start)."""
    try:
        return call(*args)
    except SceneError:
        raise
    except Exception as error:
        line = failure_line(error, scenario_files(type(scenario)))
        if line is None:
            raise
        raise SceneError(f'scene {scene.name}: the scenario raised at {line}') from None


def read_description(scene, notices):
    """The robot's description (robot/description.py) and its initial joint positions: the
    ros2_control initial values of the description, then the scene's."""
    robot = scene.robot or {}
    try:
        description = load_description(
            scene.model_path, package_paths=robot.get('package_paths'),
            xacro_args=robot.get('xacro_args'), base=robot.get('base'),
            log=notices.append)  # (what reading the description changed)
    except DescriptionError as error:
        raise SceneError(f'scene {scene.name}: {error}') from None
    return description, {**(description.initial_positions or {}), **scene.initial_positions}


def compile_model(scene, scenario, spec, initial_positions, notices):
    """The CompiledModel of the description's `spec`, edited by the scenario, the sand
    bodies' visual geoms kept where they carry plates, every other visual discarded, and
    the joints' command interfaces added; the scene's timestep and initial keyframe."""
    in_scenario(scene, scenario, scenario.edit_model, spec)
    visual = scene.plate_geoms == 'visual'
    patterns = scene.sand_bodies
    if visual and AUTO in patterns:  # auto's bodies' visuals are marked before compiling
        patterns = (_auto_sand_bodies(scene, spec, initial_positions)
                    + [p for p in patterns if p != AUTO])
    keep_sand_visuals(spec, patterns, visual)
    spec.compiler.discardvisual = True  # headless: visual-only geoms and meshes not needed
    try:
        joint_plan = add_joint_interfaces(spec, scene.servos)
    except ValueError as error:
        raise SceneError(f'scene {scene.name}: {error}') from None
    if joint_plan.switched_off:
        names = joint_plan.switched_off
        notices.append(f'servos passive: the model\'s actuator{"s" * (len(names) > 1)} '
                       f'{first_few(names)} switched off (no force), so the joints they drove '
                       'move freely')
    if joint_plan.replaced:
        names = joint_plan.replaced
        notices.append(f'servos: the model\'s actuator{"s" * (len(names) > 1)} '
                       f'{first_few(names)} of another kind than position or motor switched '
                       'off (no force): the servos asked for drive their joints instead')
    if joint_plan.other_driven:
        names = joint_plan.other_driven
        notices.append(
            f'joint{"s" * (len(names) > 1)} {first_few(names)}: driven by the model\'s own '
            'actuators of another kind than position or motor (velocity, a muscle, ...), '
            'whose controls stay 0 (a velocity actuator holds its joint still); commands '
            'leave them out. servos: {NAME: {kp: ..., kd: ...}} switches those actuators off '
            'and gives the joint position, velocity and effort commands')
    if joint_plan.unactuated:
        names = joint_plan.unactuated
        notices.append(
            f'joint{"s" * (len(names) > 1)} {", ".join(names)}: no actuator in the model, '
            f'so {"they stay" if len(names) > 1 else "it stays"} passive as written '
            '(spring, damping, limits) and commands leave them out; servos: {NAME: {kp: '
            '..., kd: ...}} gives one a servo')
    try:
        model = spec.compile()
    except Exception as error:
        raise SceneError(f'scene {scene.name}: model does not compile: {error}') from None
    model.opt.timestep = scene.timestep
    keyframe = initial_keyframe(model, scene.keyframe)
    if keyframe is not None and scene.keyframe is None:
        names = [model.key(k).name or f'#{k}' for k in range(model.nkey)]
        notices.append(
            f"initial pose: the model's keyframe {keyframe_label(keyframe)} (by "
            f'default the first of {", ".join(DEFAULT_KEYFRAMES)} it has, else its first '
            f'keyframe; it has {", ".join(names)}): robot.keyframe or --keyframe NAME '
            "picks another, '' the model's qpos0")
    return CompiledModel(model, keyframe, joint_plan, patterns)


def _auto_sand_bodies(scene, spec, initial_positions):
    """The body names auto picks, found on a compiled copy of `spec` (visual geoms
    discarded) in the initial pose; [AUTO] where that copy fails, so that the model's own
    compile and pose report the error."""
    try:
        probe = spec.copy()
        probe.compiler.discardvisual = True
        model = probe.compile()
        data = mujoco.MjData(model)
        set_initial_pose(model, data, initial_keyframe(model, scene.keyframe),
                         initial_positions)
        mujoco.mj_kinematics(model, data)
        return resolve_sand_bodies(model, data, [AUTO], base_id(scene, model))
    except (ValueError, KeyError):
        return [AUTO]


def sand_surface(scene, model, given, notices):
    """The sand's surface and zeta map: `given` (a Surface made in Python; the scene's
    sand.surface must then be the plane), else the scene's sand.surface; its notices said."""
    try:
        if given is None:
            surface = surface_from_settings(scene.surface, scene.surface_height, model)
        elif not isinstance(given, Surface) or isinstance(given, DeformableSand):
            raise ValueError(f'surface must be a rft_sim_ros.sand.surface.Surface (a Plane, '
                             f'Slope or HeightGrid), got {type(given).__name__}'
                             + ('; deformable sand is the scene\'s sand.deformable, laid over '
                                'the surface given' if isinstance(given, DeformableSand) else ''))
        elif scene.surface.get('type', 'plane') != 'plane':
            raise ValueError('a surface given in Python replaces the scene\'s sand.surface, '
                             f'which is a {scene.surface["type"]} here: leave it out')
        else:
            surface = given
        notices.extend(surface.notices)
        zeta_map = zeta_map_from_settings(scene.zeta_map)
    except ValueError as error:
        raise SceneError(f'scene {scene.name}: {error}') from None
    return surface, zeta_map


def world_ground(model, geom_type):
    """Ids of the geoms of `geom_type` (mjtGeom) fixed to the world (their body welded to
    it) that can collide with a geom of a moving body (contype/conaffinity bits)."""
    moving = model.body_weldid[model.geom_bodyid] != 0
    contype = np.bitwise_or.reduce(model.geom_contype[moving], initial=0)
    conaffinity = np.bitwise_or.reduce(model.geom_conaffinity[moving], initial=0)
    return [int(g) for g in np.flatnonzero((model.geom_type == geom_type) & ~moving)
            if model.geom_contype[g] & conaffinity or model.geom_conaffinity[g] & contype]


def floor_planes(model):
    """Ids of the floor planes of a model: planes of its `world_ground`, facing up (within
    FLOOR_TILT_DEG of +z; a wall is not a floor)."""
    planes = world_ground(model, mujoco.mjtGeom.mjGEOM_PLANE)
    if not planes:
        return []
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)  # the poses of geoms fixed to the world
    up = data.geom_xmat[planes, 8]  # z of each plane's normal (its local z axis)
    return [g for g, z in zip(planes, up) if z >= np.cos(np.radians(FLOOR_TILT_DEG))]


def ground_to_sand(scene, model, notices):
    """Switch off the rigid collisions of the model's ground that the sand replaces: the
    hfield geom that is the sand's surface, and the floor planes (`floor_planes`, said in a
    notice) unless sand.keep_floor. The model's other hfields stay rigid ground, said in a
    notice with the keys that make one of them the sand's surface. A model left with nothing
    to collide skips MuJoCo's (empty) collision pass."""
    ground = [] if scene.keep_floor else floor_planes(model)
    if ground:
        names = ', '.join(model.geom(g).name or f'#{g}' for g in ground)
        notices.append(f'floor plane {names}: rigid collisions switched off, the sand '
                       'carries the robot (sand.keep_floor: true keeps it)')
    kind = scene.surface.get('type', 'plane')
    if kind == 'hfield':
        ground.append(hfield_geom(model, scene.surface.get('geom')))
    rigid = [g for g in world_ground(model, mujoco.mjtGeom.mjGEOM_HFIELD) if g not in ground]
    if rigid:
        labels = [hfield_label(model, g) for g in rigid]
        notices.append(
            f'hfield geom{"s" * (len(labels) > 1)} {", ".join(labels)}: rigid ground where '
            f"the robot meets it, not sand (the sand's surface is the {kind}); --set "
            f'sand.surface.type=hfield --set sand.surface.geom={labels[0]} makes it the '
            "sand's surface")
    model.geom_contype[ground] = model.geom_conaffinity[ground] = 0
    if not can_collide(model):
        model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT


def initial_pose(scene, model, data, keyframe, positions):
    """The keyframe and initial joint positions of the scene (robot/pose.py) set in `data`,
    its kinematics computed; joints outside their range start at its nearest end. Returns
    those (`robot.pose.set_initial_pose`)."""
    try:
        moved = set_initial_pose(model, data, keyframe, positions)
    except ValueError as error:
        key = 'robot.keyframe' if 'keyframe' in str(error) else 'robot.initial_positions'
        raise scene.locator.error(key, str(error)) from None
    mujoco.mj_kinematics(model, data)
    return moved


def say_moved_into_ranges(moved, notices):
    """The start-up notice of the joints `initial_pose` moved into their ranges."""
    if moved:
        name, value, low, high = moved[0]
        notices.append(
            f'joint{"s" if len(moved) > 1 else ""} {", ".join(m[0] for m in moved)} '
            f'started outside {"their ranges" if len(moved) > 1 else "its range"} '
            f'({name} at {value:.4g}, range {low:.4g} .. {high:.4g}): each starts at its '
            "range's nearest end, which its servo holds (robot.initial_positions or "
            'robot.keyframe give another start)')


def base_id(scene, model):
    """Id of the body /odom follows in `model`: the scene's base_body, else the first body
    under the world (named or not)."""
    if not scene.base_body:
        return min(1, model.nbody - 1)
    try:
        return model.body(scene.base_body).id
    except KeyError:
        raise scene.locator.error('base_body', f'{scene.base_body!r} is not a '
                                  f'body of {scene.model_path.name}') from None


def deformable_bed(scene, surface, data, base, notices):
    """The sand the robot stands on: the deformable bed (scene key sand.deformable) over
    `surface` where enabled, centred where the scene says, else under the base body in the
    initial pose, its x, y rounded to whole cells; else `surface`. Notices: deformable keys
    set without it, a surface steeper than the slopes checked."""
    given = sorted(set((scene.raw.get('sand') or {}).get('deformable') or {}) - {'enabled'})
    if given and not scene.deformable.get('enabled'):
        notices.append(f'sand.deformable.{", sand.deformable.".join(given)} set, but '
                       'sand.deformable.enabled is false: the sand is rigid and they '
                       'have no effect (sand.deformable.enabled=true makes it '
                       'deformable)')
    if scene.deformable.get('enabled'):
        bed = scene.deformable
        center = bed.get('center')
        if center is None:
            center = bed['cell'] * np.round(data.xpos[base, :2] / bed['cell'])
        try:
            surface = DeformableSand(surface, bed['size'], bed['cell'], bed['repose_deg'],
                                     tuple(float(c) for c in center))
        except ValueError as error:
            raise SceneError(f'scene {scene.name}: {error}') from None
        notices.extend(surface.notices)
    steepest = surface.steepest_deg()
    if steepest > CHECKED_SLOPE_DEG:
        notices.append(
            f'the sand surface is {steepest:.3g} deg steep at its steepest: '
            f'beyond the slopes checked (up to {CHECKED_SLOPE_DEG:g} deg) and near dry '
            "sand's angle of repose (about 30 deg), where real sand fails and flows; the "
            'model knows nothing of that failure (docs/terrain.md, "Stated limit")')
    return surface


def choose_sand_bodies(scene, model, data, patterns, base, notices):
    """(sand bodies, other bodies): the bodies the scene's patterns name (robot/
    sand_bodies.py; auto resolved in the initial pose), and, where the scene gives the other
    bodies plates, every other body. The scene's per-body plate counts must name sand
    bodies."""
    try:
        sand_bodies = tuple(resolve_sand_bodies(model, data, patterns, base))
    except ValueError as error:
        raise scene.locator.error('rft.sand_bodies', str(error)) from None
    if list(scene.sand_bodies) != list(sand_bodies):
        notices.append(f'sand bodies ({", ".join(scene.sand_bodies)}): '
                       f'{", ".join(sand_bodies)}')
    others = ()
    if scene.other_bodies_density_per_mm2 is not None:
        others = tuple(other_bodies(model, sand_bodies))
    for body in scene.plates_by_body:
        if body not in sand_bodies:
            raise scene.locator.error('rft.plates', f'{body!r} is not a sand body '
                                      f'({", ".join(sand_bodies)})')
    return sand_bodies, others


def plates_of(scene, model, sand_bodies, others, notices):
    """({body: Plates}, other bodies with plates): the sand bodies' as the scene asks (a
    count or a density per body; a body whose geoms make more plates than its count even at
    their coarsest is named in a notice), then the other bodies' at
    rft.other_bodies_density_per_mm2 (one whose geoms cannot carry plates, a plane, is left
    out of them and named in a notice)."""
    plates, over = {}, []
    for body in sand_bodies:
        count = scene.plates_by_body.get(body, scene.plates_per_body)
        try:
            plates[body] = body_plates(
                model, model.body(body).id, count=count,
                density_per_mm2=None if count is not None else scene.plate_density_per_mm2)
        except ValueError as error:
            raise scene.locator.error('rft.sand_bodies', str(error)) from None
        if count is not None and len(plates[body].areas) > count:
            over.append(f'{body} {len(plates[body].areas)}')
    if over:
        notices.append(f'plates: {", ".join(over)}, more than asked: their geoms '
                       'tessellate (a mesh decimates) no coarser')
    density, without, asked = scene.other_bodies_density_per_mm2, [], 0
    for body in others:
        try:
            plates[body] = body_plates(model, model.body(body).id, density_per_mm2=density,
                                       outline=True)
        except ValueError as error:
            without.append(f'{body} ({error})')
        else:
            asked += max(1, round(density * plates[body].total_area * 1e6))
    if without:
        notices.append(f'other bodies without plates, which pass through the sand: '
                       f'{first_few(without)}')
    others = tuple(b for b in others if b in plates)
    if others:
        count = sum(len(plates[b].areas) for b in others)
        coarsest = ('' if count <= asked else
                    f', {count - asked} more than {density:g} per mm^2 asks: small bodies '
                    "carry their geoms' coarsest tessellation")
        notices.append(
            f'other bodies: {first_few(list(others))} carry {count} plates '
            f'({density:g} per mm^2{coarsest}; meshes as the convex outline MuJoCo '
            "collides), so that the sand holds them too (those on a leg's branch add to "
            "that leg's wrench; rft.other_bodies_density_per_mm2: null leaves them "
            'without)')
    return plates, others


def _dynamic_term(config):
    """The scene's rft.dynamic (lambda, density kg/m^3) as a DynamicTerm, or None."""
    if not config:
        return None
    return DynamicTerm(lam=float(config.get('lambda', 1.0)),
                       density=float(config.get('density', 1600.0)))


def sand_engine(scene, model, data, plates, surface, zeta_map):
    """The sand engine over `plates` on `surface` with the scene's rft settings: the exact
    coupling (SandEngine), or the RFT-SiM code's lagged loop (`rft.coupling: paper`)."""
    engine = PaperLoopEngine if scene.coupling == 'paper' else SandEngine
    try:
        return engine(model, data, plates, scene.zeta,
                      surface_height=scene.surface_height, surface=surface,
                      zeta_map=zeta_map, normalisation=scene.normalisation,
                      dynamic=_dynamic_term(scene.dynamic),
                      low_velocity=LowVelocity(**scene.low_velocity),
                      rows_expected=rows_expected(scene))
    except (TypeError, ValueError) as error:
        raise SceneError(f'scene {scene.name}: rft: {error}') from None


def named_joints(model, notices):
    """Ids of the hinge and slide joints that have a name; how many have none is said in a
    notice (they get no interfaces either: `add_joint_interfaces`)."""
    movable = movable_joints(model)
    named = [j for j in movable if model.joint(j).name]
    if len(named) < len(movable):
        notices.append(f'{len(movable) - len(named)} hinge or slide joint(s) without '
                       'a name: no command interfaces, not in /joint_states (name '
                       'them in the model to command them)')
    return named


def legs_of(scene, model, engine, sand_bodies, others, base):
    """The Legs: the scene's, or one per branch of the kinematic tree that holds sand bodies,
    with the other bodies of that branch (robot/sand_bodies.py)."""
    legs = scene.legs
    if legs == 'auto':
        legs = legs_from_tree(model, sand_bodies, base, others)
    for leg, bodies in scene.legs.items() if scene.legs != 'auto' else ():
        for body in bodies:
            if body not in sand_bodies:
                raise scene.locator.error(f'legs.{leg}', f'{body!r} is not a sand body '
                                          f'({", ".join(sand_bodies)})')
    legs = {leg: tuple(bodies) for leg, bodies in legs.items()}
    feet = np.array([model.body(bodies[-1]).id for bodies in legs.values()], dtype=int)
    rows = np.array([engine.body_names.index(b) for bodies in legs.values() for b in bodies],
                    dtype=int)
    leg_of_row = np.repeat(np.arange(len(legs)), [len(bodies) for bodies in legs.values()])
    membership = (leg_of_row == np.arange(len(legs))[:, None]).astype(float)
    foot_rows = np.array([engine.body_names.index(bodies[-1]) for bodies in legs.values()],
                         dtype=int)  # each leg's foot: its last sand body
    return Legs(legs, tuple(legs), feet, rows, membership, foot_rows)


def servo_stiffness(scene, model):
    """The scene's servo_kp (N m/rad or N/m), where given, as every position servo's
    stiffness."""
    if scene.servo_kp is not None:
        for actuator, _ in position_servos(model):
            model.actuator_gainprm[actuator, 0] = scene.servo_kp
            model.actuator_biasprm[actuator, 1] = -scene.servo_kp


def spawn_of(scene, model, base, notices):
    """(kind, height) of the scene's robot.spawn (robot/pose.py); a robot fixed to the world
    (no free joint at its root) starts where the model puts it ('model'), said in a notice
    unless the spawn is the default."""
    try:
        spawn = parse_spawn(scene.spawn, scene.scenario)
    except ValueError as error:
        raise scene.locator.error('robot.spawn', str(error)) from None
    if spawn[0] != 'model' and free_root_joint(model, base) is None:
        if scene.spawn != 'auto':  # (the default: a welded robot starts where it is)
            notices.append(f'robot.spawn {scene.spawn}: body {model.body(base).name} is '
                           'fixed to the world (no free joint at its root), so it starts '
                           'where the model puts it')
        spawn = ('model', None)
    return spawn
