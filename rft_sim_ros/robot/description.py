"""`load_description`: a robot file (MJCF .xml, URDF .urdf, xacro .xacro/.urdf.xacro) or a
`robot_description` XML string, as a compilable `mujoco.MjSpec` and its joint data.

The kind is told by the root element (<mujoco> or <robot>), so a URDF saved as .xml works
too; xacro files are expanded first (`xacro_files`). A URDF's root link gets a free joint
named FLOATING_JOINT (`base='floating'`; a root link hung from a `world` link by a
`floating` joint keeps that joint, which MuJoCo makes free) or stays welded to the world
(`base='fixed'`, that joint dropped); `base=None` (the default) does as the URDF says: a
root link hung from a `world` link by a `fixed` joint (an arm on its mount) stays welded,
any other floats. A root link joined only by a fixed joint to the real trunk is fine (it
is a massless body carrying the trunk). MJCF is used as written, except where `base` asks:
'fixed' welds the robot's root (the first body under the world: its free joint removed;
already welded, nothing to do), 'floating' frees it (a free joint FLOATING_JOINT added to
a root without joints; a free root as it is); a root that moves on other joints (slides,
hinges: a planar robot) is refused with the reason, as MuJoCo's importer never guesses. A
visual-only mesh geom (contype and conaffinity 0) whose mesh file is missing is dropped with
the same notice as a URDF's (plain MuJoCo refuses the file); a missing mesh that a colliding
geom uses is refused, naming it.
Notices (dropped visuals, ignored tags, converted meshes, a welded or freed root) are logged
once through `log`.
"""
import logging
from dataclasses import dataclass, field
from pathlib import Path

import mujoco

from .control_block import command_interfaces
from .meshes import MeshError, dropped_visuals_notice
from .packages import PackageResolver
from .urdf import UrdfError, parse_xml, prepare_urdf
from .xacro_files import XacroError, expand_xacro

#: Suffixes of the robot files `load_description` (and `rft-sim run`) take.
ROBOT_SUFFIXES = ('.xml', '.urdf', '.xacro')
#: Name of the free joint a floating-base URDF gets at its root link.
FLOATING_JOINT = 'floating_base'
BASES = ('floating', 'fixed', None)

_LOG = logging.getLogger(__name__)


class DescriptionError(ValueError):
    """A robot description cannot be loaded; one line saying what and where."""


@dataclass
class RobotDescription:
    """A loaded robot. spec: mujoco.MjSpec (compilable); kind: 'mjcf' or 'urdf';
    source_path: the file (None for a string); effort_limits {joint: N m or N};
    velocity_limits {joint: rad/s or m/s}; initial_positions {joint: rad or m} (URDF
    <ros2_control> initial values); command_interfaces {joint: (position, effort, ...)} (URDF
    <ros2_control> command interfaces, `control_block`); notices: one-line remarks already
    logged."""
    spec: mujoco.MjSpec
    kind: str
    source_path: Path = None
    effort_limits: dict = field(default_factory=dict)
    velocity_limits: dict = field(default_factory=dict)
    initial_positions: dict = field(default_factory=dict)
    command_interfaces: dict = field(default_factory=dict)
    notices: list = field(default_factory=list)


def is_robot_file(path):
    """Whether `path` names a robot description by its suffix (.xml, .urdf, .xacro)."""
    return Path(str(path)).suffix.lower() in ROBOT_SUFFIXES


def is_xml_string(source):
    """Whether `source` is XML text rather than a path."""
    return isinstance(source, str) and source.lstrip().startswith('<')


def load_description(source, *, package_paths=None, xacro_args=None, base=None,
                     log=_LOG.warning):
    """RobotDescription of `source`: a path or an XML string (see module docstring).

    package_paths: {package: folder} or ['NAME=DIR', ...] for $(find)/package:// (the
    ament index and ROS_PACKAGE_PATH are searched after them); xacro_args: {name: value};
    base: 'floating', 'fixed' or None (as the file says; module docstring). Raises
    DescriptionError.
    """
    if base not in BASES:
        raise DescriptionError(f"base must be 'floating', 'fixed' or None, got {base!r}")
    try:
        resolver = PackageResolver(package_paths)
    except ValueError as error:
        raise DescriptionError(str(error)) from None
    path, text = None, None
    if is_xml_string(source):
        text, where, base_dir = source, 'robot_description', None
    else:
        path = Path(source).expanduser()
        where, base_dir = str(path), path.parent.resolve()
        if not path.is_file():
            raise DescriptionError(f'robot file {path} not found')
        if not is_robot_file(path):
            raise DescriptionError(f'{path}: a robot file is MJCF (.xml), URDF (.urdf) or '
                                   'xacro (.xacro, .urdf.xacro)')
        try:
            text = (expand_xacro(path, resolver, xacro_args) if path.suffix == '.xacro'
                    else path.read_text())
        except XacroError as error:
            raise DescriptionError(str(error)) from None
    try:
        root = parse_xml(text, where)
        if root.tag == 'robot':
            description = _from_urdf(root, where, base_dir, resolver, base)
        elif root.tag == 'mujoco':
            description = _from_mjcf(text, path, where, base)
        else:
            raise DescriptionError(f'{where}: root element <{root.tag}> is neither <robot> '
                                   '(URDF) nor <mujoco> (MJCF)')
    except (UrdfError, MeshError) as error:
        raise DescriptionError(str(error)) from None
    description.source_path = path
    for notice in description.notices:
        log(notice)
    return description


def _from_urdf(root, where, base_dir, resolver, base):
    if base is None:
        base = 'fixed' if _fixed_to_world(root) else 'floating'
    declared = command_interfaces(root)  # (before prepare_urdf drops the block)
    prepared = prepare_urdf(root, where, base_dir, resolver)
    spec = _spec(lambda: mujoco.MjSpec.from_string(prepared.text, assets=prepared.assets),
                 where)
    roots = [body for body in spec.worldbody.bodies]
    if len(roots) != 1:
        raise DescriptionError(f'{where}: a URDF robot has one root link, found '
                               f'{[b.name for b in roots]}')
    # a root link hung from a `world` link by a `floating` joint has its free joint already
    free = [joint for joint in roots[0].joints if joint.type == mujoco.mjtJoint.mjJNT_FREE]
    if base == 'floating' and not free:
        roots[0].add_freejoint(name=FLOATING_JOINT)
    if base == 'fixed':
        for joint in free:
            spec.delete(joint)
    _check_compiles(spec, where)
    return RobotDescription(spec=spec, kind='urdf', effort_limits=prepared.effort_limits,
                            velocity_limits=prepared.velocity_limits,
                            initial_positions=prepared.initial_positions,
                            command_interfaces=declared, notices=prepared.notices)


def _fixed_to_world(root):
    """Whether URDF <robot> `root` hangs its root link from a `world` link by a fixed
    joint (as an arm's description mounts it)."""
    return any(joint.get('type') == 'fixed' and joint.find('parent') is not None
               and joint.find('parent').get('link') == 'world' for joint in root.iter('joint'))


def _from_mjcf(text, path, where, base):
    spec = _spec(lambda: (mujoco.MjSpec.from_file(str(path)) if path is not None
                          else mujoco.MjSpec.from_string(text)), where)
    notices = _name_bodies(spec, where)
    dropped = _drop_missing_visual_meshes(spec, where, path)
    if dropped:
        notices.append(dropped_visuals_notice(where, dropped))
    if base is not None:
        notices.append(_set_mjcf_base(spec, where, base))
    # effort limits read from the spec, not a compiled model: compiling here would also
    # process every visual mesh (seconds for a vendor model), which the simulation discards
    effort = {}
    for joint in spec.joints:
        limited = joint.actfrclimited == mujoco.mjtLimited.mjLIMITED_TRUE or (
            joint.actfrclimited == mujoco.mjtLimited.mjLIMITED_AUTO
            and spec.compiler.autolimits and any(joint.actfrcrange))
        if limited and joint.name:
            effort[joint.name] = float(max(abs(joint.actfrcrange)))
    return RobotDescription(spec=spec, kind='mjcf', effort_limits=effort, notices=notices)


def _set_mjcf_base(spec, where, base):
    """Weld ('fixed') or free ('floating') the root of MJCF `spec`: its first body under the
    world (module docstring). Returns the notice saying what was done; raises
    DescriptionError where it cannot be done as the file stands."""
    roots = list(spec.worldbody.bodies)
    if not roots:
        raise DescriptionError(f'{where}: robot.base {base}: the model has no body to '
                               f'{"weld" if base == "fixed" else "free"}')
    root = roots[0]
    free = [j for j in root.joints if j.type == mujoco.mjtJoint.mjJNT_FREE]
    others = [j.name or f'#{i}' for i, j in enumerate(root.joints)
              if j.type != mujoco.mjtJoint.mjJNT_FREE]
    if others:
        raise DescriptionError(
            f'{where}: robot.base {base}: root body {root.name} moves on joints '
            f'{", ".join(others)}, not on one free joint, so it cannot be '
            f'{"welded" if base == "fixed" else "freed"} without changing the model: edit its '
            'joints in the file, or leave robot.base unset (the model as written)')
    if base == 'fixed':
        for joint in free:
            spec.delete(joint)
        return (f'{where}: robot.base fixed: root body {root.name} welded to the world '
                f'({"its free joint removed" if free else "it had no joint"})')
    if not free:
        root.add_freejoint(name=FLOATING_JOINT)
    return (f'{where}: robot.base floating: root body {root.name} '
            f'{"free as written" if free else f"freed (free joint {FLOATING_JOINT} added)"}')


def _drop_missing_visual_meshes(spec, where, path):
    """Drop from MJCF `spec` each mesh whose file is missing, with the visual-only geoms
    (contype and conaffinity 0) that use it; returns '<file> (missing)' for each dropped.
    Raises DescriptionError where a colliding geom uses such a mesh. Mesh files are looked
    for as MuJoCo does: absolute as given, else under the model file's folder (`path`; the
    working directory for a string) joined with the compiler's meshdir."""
    folder = (Path(path).resolve().parent if path is not None else Path.cwd()) / spec.meshdir
    missing = {mesh.name: mesh for mesh in spec.meshes
               if mesh.file and not (folder / mesh.file).is_file()}
    if not missing:
        return []
    users = {}
    for geom in spec.geoms:
        if geom.type == mujoco.mjtGeom.mjGEOM_MESH and geom.meshname in missing:
            users.setdefault(geom.meshname, []).append(geom)
    for name, geoms in users.items():
        colliding = [g for g in geoms if g.contype or g.conaffinity]
        if colliding:
            raise DescriptionError(
                f'{where}: mesh {name}: file {missing[name].file} not found (looked for '
                f'{folder / missing[name].file}), and geom {colliding[0].name or "(unnamed)"} '
                'of a body collides with it: give the file, or drop the geom')
    for geoms in users.values():
        for geom in geoms:
            spec.delete(geom)
    for mesh in missing.values():
        spec.delete(mesh)
    return [f'{mesh.file} (missing)' for mesh in missing.values()]


def _name_bodies(spec, where):
    """Name each body of `spec` that has none body<id> (its compiled id; body<id>_ where that
    name is taken), so that sand bodies, legs and errors can name it. Returns the notices."""
    taken = {body.name for body in spec.bodies}
    named = []
    for i, body in enumerate(spec.bodies):  # (in compiled id order)
        if not body.name:
            name = f'body{i}'
            while name in taken:
                name += '_'
            body.name = name
            taken.add(name)
            named.append(name)
    if not named:
        return []
    return [f'{where}: {len(named)} bod{"ies" if len(named) > 1 else "y"} without a name, '
            f'called by {"their" if len(named) > 1 else "its"} id: '
            f'{", ".join(named[:5])}{" ..." if len(named) > 5 else ""}']


def _spec(parse, where):
    try:
        return parse()
    except Exception as error:  # MuJoCo reports parse errors as plain exceptions
        raise DescriptionError(f'{where}: MuJoCo cannot read it: {_one_line(error)}') from None


def _check_compiles(spec, where):
    try:
        return spec.compile()
    except Exception as error:
        raise DescriptionError(f'{where}: does not compile: {_one_line(error)}') from None


def _one_line(error):
    return ' '.join(str(error).split())
