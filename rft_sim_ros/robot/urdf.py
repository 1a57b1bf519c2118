"""URDF made ready for MuJoCo's URDF importer, and what the joints need read from it.

MuJoCo (MjSpec.from_string) imports URDF links as bodies, joints with their limits
(range; `effort` -> actuatorfrcrange), inertials, and visual/collision geometry (visuals
become non-colliding group-1 geoms). Before that, `prepare_urdf`:

- resolves every mesh reference (package://, file://, relative) to a path;
- drops visuals MuJoCo cannot read (COLLADA and other formats, missing files): visual
  geometry never blocks physics (one notice lists them);
- converts collision meshes in other formats with trimesh (`meshes`), or refuses with the
  file's name;
- removes <ros2_control>, <gazebo> and <transmission> (one notice), after reading joint
  initial values from <ros2_control> (`<param name="initial_value">` of a joint's position
  state or command interface);
- reads each joint's <limit effort velocity> (N m or N; rad/s or m/s);
- replaces an <inertia> no rigid body can have (principal moments not all positive, or
  violating A + B >= C; URDF tools accept them, MuJoCo refuses to compile them, e.g. a
  placeholder with every entry 0.001) by the isotropic one of the same trace: principal
  moments set to their mean, as MuJoCo's balanceinertia does (one notice names the links);
- sets MuJoCo's compiler for URDF: links joined by fixed joints stay bodies of their own
  (fusestatic off, so every link name can be named as a sand body), a link without
  <inertial> is massless as in URDF (inertiafromgeom off), visuals are kept, mesh paths are
  used as given. A <mujoco><compiler .../></mujoco> of the file's own wins over these.
"""
import hashlib
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import numpy as np

from .meshes import converted_stl, dropped_visuals_notice, mujoco_reads

#: Tags of other simulators and of ros2_control that MuJoCo does not use.
IGNORED_TAGS = ('ros2_control', 'gazebo', 'transmission')

#: MuJoCo compiler settings for URDF (see module docstring).
COMPILER_DEFAULTS = {'fusestatic': 'false', 'discardvisual': 'false', 'strippath': 'false',
                     'inertiafromgeom': 'false', 'angle': 'radian'}


class UrdfError(ValueError):
    """The URDF cannot be used; the message says where and why."""


@dataclass
class PreparedUrdf:
    """URDF text MuJoCo imports, in-memory mesh assets {name: bytes}, and joint data."""
    text: str
    assets: dict = field(default_factory=dict)
    effort_limits: dict = field(default_factory=dict)
    velocity_limits: dict = field(default_factory=dict)
    initial_positions: dict = field(default_factory=dict)
    notices: list = field(default_factory=list)


def parse_xml(text, where):
    """The root element of XML `text`; UrdfError with file and line if it is malformed."""
    try:
        return ET.fromstring(text)
    except ET.ParseError as error:
        line, column = error.position
        raise UrdfError(f'{where}: malformed XML at line {line}, column {column + 1}: '
                        f'{str(error).split(":")[0]}') from None


def prepare_urdf(root, where, base_dir, resolver):
    """PreparedUrdf from the <robot> element `root` of description `where` (for messages),
    mesh references resolved against `base_dir` (None: the working directory) through
    `resolver` (packages.PackageResolver)."""
    prepared = PreparedUrdf(text='')
    _read_limits(root, where, prepared)
    _read_initial_values(root, where, prepared)
    ignored = sorted({child.tag for child in root if child.tag in IGNORED_TAGS})
    for child in [child for child in root if child.tag in IGNORED_TAGS]:
        root.remove(child)
    if ignored:
        prepared.notices.append(f'{where}: ignored <{">, <".join(ignored)}> (MuJoCo and the '
                                'sand engine simulate the robot; ros2_control initial values '
                                'and joint limits were read)')
    _prepare_meshes(root, where, base_dir, resolver, prepared)
    balanced = balance_inertias(root)
    if balanced:
        prepared.notices.append(
            f'{where}: link{"s" if len(balanced) > 1 else ""} {", ".join(balanced)}: an '
            'inertia no rigid body has (principal moments not positive, or A + B < C) or a '
            f'principal moment below {LEAST_MOMENT:g} kg m^2 (MuJoCo refuses the first and '
            'moments below 1e-14), replaced by the isotropic one of the same trace, '
            f'{LEAST_MOMENT:g} kg m^2 at least')
    _set_compiler(root)
    prepared.text = ET.tostring(root, encoding='unicode')
    return prepared


def _number(element, name, where):
    text = element.get(name)
    if text is None:
        return None
    try:
        return float(text)
    except ValueError:
        raise UrdfError(f'{where}: {element.tag} {name}={text!r} is not a number') from None


def _read_limits(root, where, prepared):
    for joint in root.iter('joint'):
        limit = joint.find('limit')
        if limit is None or joint.get('type') in (None, 'fixed', 'floating', 'planar'):
            continue
        name = joint.get('name')
        effort = _number(limit, 'effort', f'{where}: joint {name}')
        velocity = _number(limit, 'velocity', f'{where}: joint {name}')
        if effort is not None and effort > 0:
            prepared.effort_limits[name] = effort
        if velocity is not None and velocity > 0:
            prepared.velocity_limits[name] = velocity


def _read_initial_values(root, where, prepared):
    for control in root.iter('ros2_control'):
        for joint in control.iter('joint'):
            for interface in (*joint.findall('state_interface'),
                              *joint.findall('command_interface')):
                if interface.get('name') != 'position':
                    continue
                for param in interface.findall('param'):
                    if param.get('name') == 'initial_value' and param.text:
                        try:
                            value = float(param.text.strip())
                        except ValueError:
                            raise UrdfError(
                                f'{where}: <ros2_control> joint {joint.get("name")}: '
                                f'initial_value {param.text.strip()!r} is not a number') from None
                        prepared.initial_positions.setdefault(joint.get('name'), value)


def _prepare_meshes(root, where, base_dir, resolver, prepared):
    dropped, converted = [], {}  # converted: {path: asset name}
    for link in root.iter('link'):
        for kind in ('visual', 'collision'):
            for element in link.findall(kind):
                mesh = element.find('geometry/mesh')
                if mesh is None or mesh.get('filename') is None:
                    continue
                uri = mesh.get('filename')
                try:
                    path = resolver.resolve_uri(uri, base_dir)
                except LookupError as error:
                    if kind == 'visual':
                        dropped.append(f'{uri} ({error})')
                        link.remove(element)
                        continue
                    raise UrdfError(f'{where}: link {link.get("name")}: collision mesh {uri}: '
                                    f'{error}') from None
                if kind == 'visual':
                    if not (path.is_file() and mujoco_reads(path)):
                        dropped.append(uri if path.is_file() else f'{uri} (missing)')
                        link.remove(element)
                    else:
                        mesh.set('filename', str(path))
                    continue
                if not path.is_file():
                    raise UrdfError(f'{where}: link {link.get("name")}: collision mesh {uri} '
                                    f'not found (looked for {path})')
                if mujoco_reads(path):
                    mesh.set('filename', str(path))
                    continue
                if path not in converted:
                    data = converted_stl(path)
                    converted[path] = f'{path.stem}-{hashlib.sha1(data).hexdigest()[:12]}.stl'
                    prepared.assets[converted[path]] = data
                mesh.set('filename', converted[path])
    if converted:
        prepared.notices.append(
            f'{where}: converted {len(converted)} collision mesh(es) to STL with trimesh '
            f'(MuJoCo reads STL, OBJ and MSH): {", ".join(str(p) for p in converted)}')
    if dropped:
        prepared.notices.append(dropped_visuals_notice(where, dropped))


#: kg m^2: the least principal moment a replaced inertia gets, above the least MuJoCo takes
#: in a full inertia (mjEPS, 1e-14: user_util.cc); a link's placeholder inertia (Unitree's B2
#: lidar link: 1.7e-27 with 4e-15 kg) is far below it.
LEAST_MOMENT = 1e-12


def balance_inertias(root):
    """Replace, in <robot> `root`, each link's <inertial><inertia> whose principal moments
    are not all above MuJoCo's floor or violate the triangle inequality A + B >= C (MuJoCo's
    tests, user_objects.cc, user_util.cc) by the isotropic inertia of the same trace (its
    principal moments' mean, as MuJoCo's balanceinertia), LEAST_MOMENT at least; an inertia
    of trace <= 0 is left for MuJoCo to name. Returns the names of the links changed."""
    names = []
    keys = ('ixx', 'ixy', 'ixz', 'iyy', 'iyz', 'izz')
    for link in root.iter('link'):
        inertia = link.find('inertial/inertia')
        if inertia is None:
            continue
        try:
            xx, xy, xz, yy, yz, zz = (float(inertia.get(k, 0.0)) for k in keys)
        except ValueError:
            continue  # MuJoCo's importer names a malformed value
        moments = np.linalg.eigvalsh([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
        mean = float(moments.sum()) / 3.0
        if mean > 0 and (moments[0] < LEAST_MOMENT or moments[0] + moments[1] < moments[2]):
            moment = repr(max(mean, LEAST_MOMENT))
            for key in keys:
                inertia.set(key, moment if key in ('ixx', 'iyy', 'izz') else '0')
            names.append(link.get('name'))
    return names


def _set_compiler(root):
    extension = root.find('mujoco')
    if extension is None:
        extension = ET.Element('mujoco')
        root.insert(0, extension)
    compiler = extension.find('compiler')
    if compiler is None:
        compiler = ET.SubElement(extension, 'compiler')
    for name, value in COMPILER_DEFAULTS.items():
        compiler.attrib.setdefault(name, value)
