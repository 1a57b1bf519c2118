"""`load_description`: a robot file (MJCF .xml, URDF .urdf, xacro .xacro/.urdf.xacro) or a
`robot_description` XML string, as a compilable `mujoco.MjSpec` and its joint data.

The kind is told by the root element (<mujoco> or <robot>), so a URDF saved as .xml works
too; xacro files are expanded first (`xacro_files`). A URDF's root link gets a free joint
named FLOATING_JOINT (`base='floating'`; a root link hung from a `world` link by a
`floating` joint keeps that joint, which MuJoCo makes free) or stays welded to the world
(`base='fixed'`, that joint dropped); `base=None` (the default) does as the URDF says: a
root link hung from a `world` link by a `fixed` joint (an arm on its mount) stays welded,
any other floats. A root link joined only by a fixed joint to the real trunk is fine (it
is a massless body carrying the trunk). MJCF is used as written (`base` applies to URDF
only).
Notices (dropped visuals, ignored tags, converted meshes) are logged once through `log`.
"""
import logging
from dataclasses import dataclass, field
from pathlib import Path

import mujoco

from .control_block import command_interfaces
from .meshes import MeshError
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
    base: 'floating', 'fixed' or None (URDF; module docstring). Raises DescriptionError.
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
            description = _from_mjcf(text, path, where)
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


def _from_mjcf(text, path, where):
    spec = _spec(lambda: (mujoco.MjSpec.from_file(str(path)) if path is not None
                          else mujoco.MjSpec.from_string(text)), where)
    notices = _name_bodies(spec, where)
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
