"""Scene configuration: one YAML file per scene, validated into a `SceneConfig`.

A scene names the robot or rig model (MJCF, URDF or xacro; `robot:` says how to load it), the bodies that touch sand and how they are discretised, the
sand (surface height, zeta), the timestep and duration (s, or `auto`: as long as the
scenario's own values say, e.g. one rotation at the set speed), the legs to report, and values of
the scene's own (`params`: masses, drop heights, gait...) that its scenario module uses.
Every value can be overridden from the command line or the ROS node (`--set key=value`):
a key is either a name in `params` or a dotted path into the file (e.g. `rft.plates_per_body`).

Units: SI throughout except zeta, in N/cm^3 (the paper's unit).
"""
import copy
import difflib
import functools
from dataclasses import dataclass
from pathlib import Path

import yaml

from .. import resources
from ..robot.description import is_robot_file
from .schema import (BY_PATH, Locator, SceneError, check_scene, load_with_lines, load_yaml,
                     renamed_keys)


#: Settings that replace each other: overriding one removes the other.
_ALTERNATIVES = {'rft.plates_per_body': 'rft.plate_density_per_mm2',
                 'rft.plate_density_per_mm2': 'rft.plates_per_body'}


@dataclass(frozen=True)
class SceneConfig:
    """A validated scene. `raw` keeps the whole (overridden) YAML content. sand_bodies: the
    names, glob patterns or ('auto',) of rft.sand_bodies; legs: {leg: bodies} or 'auto' (both
    resolved on the model by the Simulation). notices: one-line remarks on the scene as
    given (a deprecated key's new name, schema.renamed_keys), for the run's notices."""
    name: str
    description: str
    scenario: str
    model_path: Path
    timestep: float
    duration: float
    zeta: float
    surface_height: float
    keep_floor: bool  # sand.keep_floor: the model's floor planes stay rigid
    surface: dict     # sand.surface.* (sand.surface.surface_from_settings), file resolved
    zeta_map: dict    # sand.zeta_map.* (sand.zeta_map.zeta_map_from_settings) or None
    deformable: dict  # sand.deformable.* (sand.deformable.DeformableSand)
    sand_bodies: tuple
    plate_geoms: str  # rft.plate_geoms: 'collision' or 'visual'
    plates_per_body: int
    plate_density_per_mm2: float
    other_bodies_density_per_mm2: float  # or None: only sand_bodies carry plates
    plates_by_body: dict
    normalisation: str
    coupling: str     # rft.coupling: 'exact' or 'paper' (sand/paper_loop.py)
    low_velocity: dict
    dynamic: dict
    legs: dict
    base_body: str
    publish_rate: float
    control_rate: float
    servo_kp: float
    params: dict
    raw: dict
    values: dict  # every schema key's effective value, by dotted path (schema.check_scene)
    servos: dict  # {joint pattern: {kp, kd, effort} or 'passive'} (robot/joints.py)
    keyframe: str  # or None
    initial_positions: dict  # {joint: rad or m}
    spawn: str  # 'model', 'rest' or 'drop:H' (robot/pose.py)
    locator: Locator  # where each key came from, for errors found later (e.g. body names)
    robot: dict = None  # robot.base, robot.package_paths (absolute), robot.xacro_args
    notices: tuple = ()


def bundled_scenes():
    """{name: path} of the scene YAML files shipped with the package."""
    return dict(_scene_files(resources.config_dir()))


@functools.lru_cache(maxsize=None)
def _scene_files(folder):
    """{name: path} of the scene files in `folder`: read once per process (each is parsed to
    tell scenes from other YAML, ~6 ms a file; load_scene asks on every call)."""
    return {path.stem: path for path in sorted(Path(folder).glob('*.yaml'))
            if _is_scene_file(path)}


def _bundled_scene(name):
    """The path of the bundled scene `name`; raises SceneError naming them all where there
    is none. Only that scene's file is read when it is one (start-up reads no other)."""
    path = resources.config_dir() / f'{name}.yaml'
    if _is_scene_file(path):
        return path
    scenes = bundled_scenes()
    raise SceneError(f'unknown scene {name!r}: not a scene file and not one of the bundled '
                     f'scenes ({", ".join(scenes)})')


def _is_scene_file(path):
    try:
        content = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError):
        return False
    return isinstance(content, dict) and 'scenario' in content


def load_scene(name_or_path, overrides=None, given_by='--set'):
    """Load a bundled scene by name, a scene YAML by path, or a robot file (MJCF, URDF,
    xacro: the scene `robot_scene` makes for it), apply `overrides` ({key: value}, see
    module docstring) and validate it. Raises SceneError; given_by: how the overrides were
    given, as errors name them (`Locator`)."""
    path = Path(name_or_path)
    overrides = overrides or {}
    if is_robot_file(path):
        if not path.is_file():
            raise SceneError(f'robot file {path} not found')
        raw, overrides, notices = renamed_keys(robot_scene(path), overrides, path, {},
                                               given_by)
        raw = apply_overrides(raw, overrides)
        return _validate(raw, path, Locator(path, {}, overrides, given_by), notices)
    if path.suffix in ('.yaml', '.yml') or len(path.parts) > 1:
        if not path.is_file():
            raise SceneError(f'scene file {path} not found')
    else:
        path = _bundled_scene(str(name_or_path))
    try:
        text = path.read_text()
    except OSError as error:
        raise SceneError(f'{path}: cannot read: {error.strerror}') from None
    raw, lines = load_with_lines(text, path)
    if not isinstance(raw, dict):
        raise SceneError(f'{path}: a scene file must hold a mapping')
    _refuse_glued_keys(raw, str(path))
    raw, overrides, notices = renamed_keys(raw, overrides, path, lines, given_by)
    raw = apply_overrides(raw, overrides)
    return _validate(raw, path, Locator(path, lines, overrides, given_by), notices)


#: Model file stems that say nothing about the robot (a MuJoCo Menagerie robot's scene.xml):
#: its folder names it.
GENERIC_STEMS = {'scene', 'model', 'robot', 'main', 'description'}


def robot_file_name(model_path):
    """The name of a bare robot file's scene, and so of its runs' folders: the file's stem
    ('anymal_c' for anymal_c.xml, 'my_robot' for my_robot.urdf.xacro), or its folder's name
    where the stem says nothing (GENERIC_STEMS: 'unitree_go2' for unitree_go2/scene.xml)."""
    path = Path(model_path).resolve()  # (a bare scene.xml: the folder it is in)
    stem = path.name.split('.')[0]
    return path.parent.name if stem in GENERIC_STEMS and path.parent.name else stem


def robot_scene(model_path):
    """The scene of a bare robot file (the mapping a scene YAML would hold): its model, a name
    and a description, and every other key at the schema's default, so that it starts and
    runs as a scene file naming the same robot does: scenario `external` (the robot holds its
    pose and takes commands), paper sand (zeta 3.75 N/cm^3), 1 ms steps, the default plates
    per sand body, the base as the description says (`robot.base`), spawn auto (rest: lowered
    onto the sand and settled; a base fixed to the world starts where the model puts it),
    sand bodies and legs auto unless `rft.sand_bodies` (`rft-sim run --sand-bodies`) names
    them."""
    return {'name': robot_file_name(model_path),
            'description': f'{Path(model_path).name} in sand (external commands)',
            'model': str(Path(model_path).resolve())}


def parse_assignment(text, given_by='--set'):
    """'key=value' -> (key, value), the value read as YAML (numbers, lists, booleans; 1e6
    counts as a number, in lists too: `load_yaml`). given_by: how it was given, as errors
    name it."""
    key, sep, value = text.partition('=')
    if not sep or not key.strip():
        raise SceneError(f'{given_by} expects key=value, got {text!r}')
    try:
        parsed = load_yaml(value)
    except yaml.YAMLError:
        parsed = value
    _refuse_glued_keys(parsed, f'{given_by} {key.strip()}')
    return key.strip(), parsed


def _refuse_glued_keys(value, where):
    """Raise SceneError where a mapping in `value` has a key like 'factor:0.3' without a
    value: YAML reads `{x: 1, factor:0.3}` so, a colon with no space after it being part of
    the key, and the error a validator would give later does not say why."""
    if isinstance(value, dict):
        for name, item in value.items():
            if item is None and isinstance(name, str) and ':' in name.strip(':'):
                key, _, rest = name.partition(':')
                raise SceneError(f'{where}: {name!r} was read as a key without a value: '
                                 f'YAML needs a space after the colon ({key}: {rest})')
            _refuse_glued_keys(item, where)
    elif isinstance(value, list):
        for item in value:
            _refuse_glued_keys(item, where)


def robot_overrides(sand_bodies=None, package_paths=(), xacro_args=()):
    """Scene overrides of the robot options: sand_bodies 'A,B*' or 'auto' -> rft.sand_bodies,
    ['NAME=DIR'] -> robot.package_paths (folders made absolute), ['K=V'] ->
    robot.xacro_args. Raises SceneError on a malformed item."""
    overrides = {}
    if sand_bodies:
        names = [name.strip() for name in sand_bodies.split(',') if name.strip()]
        overrides['rft.sand_bodies'] = 'auto' if names == ['auto'] else names
    for key, items, option in (('robot.package_paths', package_paths, '--package-path'),
                               ('robot.xacro_args', xacro_args, '--xacro-arg')):
        if not items:
            continue
        mapping = {}
        for item in items:
            name, sep, value = item.partition('=')
            if not sep or not name.strip():
                raise SceneError(f'{option} expects NAME=VALUE, got {item!r}')
            mapping[name.strip()] = value.strip()
        if key == 'robot.package_paths':
            mapping = {name: str(Path(folder).expanduser().resolve())
                       for name, folder in mapping.items()}
        overrides[key] = mapping
    return overrides


#: Scene keys whose text values name files (robot.package_paths: folders, per package).
PATH_KEYS = ('model', 'scenario', 'sand.surface.file', 'sand.zeta_map.file',
             'robot.package_paths')


def anchor_paths(overrides, folder):
    """A copy of `overrides` in which each relative file named by a PATH_KEYS value (a
    scenario only as a .py file) that exists under `folder` is made absolute, also where an
    override gives a whole mapping holding it (`sand.surface: {type: grid, file: ...}`):
    overrides given on a command line (`folder`: the working directory) or in a study file
    (its folder) name files from there. Others are left as given, for the scene's own
    look-up (the scene file's folder, the package's models/)."""
    def anchored(value):
        if not isinstance(value, str) or Path(value).is_absolute():
            return value
        there = Path(folder) / Path(value).expanduser()
        return str(there.resolve()) if there.exists() else value

    def anchored_value(key, value):
        if key == 'robot.package_paths' and isinstance(value, dict):
            return {name: anchored(path) for name, path in value.items()}
        if key != 'scenario' or (isinstance(value, str) and value.endswith('.py')):
            return anchored(value)
        return value

    def within(mapping, key, rest):
        """A copy of `mapping` with the PATH_KEYS entry `key` at its dotted path `rest`
        anchored (as given where it does not hold it)."""
        head, _, tail = rest.partition('.')
        if not isinstance(mapping, dict) or head not in mapping:
            return mapping
        inner = within(mapping[head], key, tail) if tail else anchored_value(key, mapping[head])
        return {**mapping, head: inner}
    out = dict(overrides)
    for key in PATH_KEYS:
        for given in list(out):
            if key == given:
                out[given] = anchored_value(key, out[given])
            elif key.startswith(given + '.'):
                out[given] = within(out[given], key, key[len(given) + 1:])
    return out


def apply_overrides(raw, overrides):
    """A copy of the scene mapping `raw` with `overrides` applied (see module docstring)."""
    raw = copy.deepcopy(raw)
    params = raw.setdefault('params', {}) or {}
    raw['params'] = params
    for key, value in overrides.items():
        if key in params:
            params[key] = value
            continue
        known = key in BY_PATH
        node = raw
        parts = key.split('.')
        for part in parts[:-1]:
            if known and not isinstance(node.get(part), dict):
                node[part] = {}
            if not isinstance(node.get(part), dict):
                raise _unknown_setting(key, params)
            node = node[part]
        if parts[-1] not in node and not known:
            raise _unknown_setting(key, params)
        node[parts[-1]] = value
        if key in _ALTERNATIVES:
            node.pop(_ALTERNATIVES[key].split('.')[-1], None)
    return raw


def _unknown_setting(key, params):
    """The SceneError of an override `key` that is neither a scene key nor one of the
    scenario's values `params`, with the closest of them."""
    close = difflib.get_close_matches(key, [*BY_PATH, *params], n=1)
    hint = f' (did you mean {close[0]}?)' if close else ''
    values = f", or one of the scenario's values ({', '.join(sorted(params))})" if params else ''
    return SceneError(f'unknown setting {key!r}{hint}: a setting is a scene key (listed in '
                      f'docs/scene-reference.md and by `rft-sim scenes NAME`){values}')


def _validate(raw, path, locator, notices=()):
    """SceneConfig from the overridden scene mapping `raw` of file `path`: the schema's
    checks (schema.check_scene) and those between keys; notices: the scene's own
    (SceneConfig.notices)."""
    values = check_scene(raw, locator)
    model_path = Path(values['model'])
    if not model_path.is_absolute():
        beside = path.parent / model_path
        model_path = beside if beside.is_file() else resources.models_dir() / model_path
    if not model_path.is_file():
        raise locator.error('model', f'file {values["model"]!r} not found (looked in '
                            f'{path.parent} and {resources.models_dir()})')
    rft = raw.get('rft') or {}
    if 'plates_per_body' in rft and 'plate_density_per_mm2' in rft:
        raise locator.error('rft.plate_density_per_mm2', 'give one of rft.plates_per_body '
                            'and rft.plate_density_per_mm2, not both')
    density = values.get('rft.plate_density_per_mm2')
    legs = values['legs']
    dynamic = None
    if 'rft.dynamic.lambda' in values:
        dynamic = {'lambda': values['rft.dynamic.lambda'],
                   'density': values['rft.dynamic.density']}
    return SceneConfig(
        name=str(values['name'] or path.stem),
        description=values['description'].strip(),
        scenario=_scenario_reference(values['scenario'], path),
        model_path=model_path,
        timestep=values['timestep'],
        duration=None if values['duration'] == 'auto' else values['duration'],
        zeta=values['zeta'],
        surface_height=values['sand.surface_height'],
        keep_floor=values['sand.keep_floor'],
        surface=_subsection(values, 'sand.surface', path, locator),
        zeta_map=_subsection(values, 'sand.zeta_map', path, locator) or None,
        deformable=_subsection(values, 'sand.deformable', path, locator),
        sand_bodies=tuple(values['rft.sand_bodies']),
        plate_geoms=values['rft.plate_geoms'],
        plates_per_body=None if density is not None else values['rft.plates_per_body'],
        plate_density_per_mm2=density,
        other_bodies_density_per_mm2=values['rft.other_bodies_density_per_mm2'],
        plates_by_body=dict(values['rft.plates']),
        normalisation=values['rft.normalisation'],
        coupling=values['rft.coupling'],
        low_velocity={'method': values['rft.low_velocity.method'],
                      'rest_speed': values['rft.low_velocity.rest_speed'],
                      'ema_alpha': values['rft.low_velocity.ema_alpha']},
        dynamic=dynamic,
        legs=legs if legs == 'auto' else {str(k): tuple(v) for k, v in legs.items()},
        base_body=values['base_body'],
        publish_rate=values['publish_rate'],
        control_rate=values['control_rate'],
        servo_kp=values['servo_kp'],
        params=dict(values['params']),
        raw=raw,
        values=values,
        servos=dict(values['servos']),
        keyframe=values['robot.keyframe'],
        initial_positions=dict(values['robot.initial_positions']),
        spawn=values['robot.spawn'],
        locator=locator,
        robot={'base': values['robot.base'],
               'package_paths': {name: str(path.parent / Path(folder).expanduser())
                                 for name, folder in values['robot.package_paths'].items()},
               'xacro_args': values['robot.xacro_args']},
        notices=tuple(notices),
    )


def _subsection(values, section, scene_path, locator):
    """{leaf: value} of the keys under `section` that have a value, a relative `file`
    resolved against the scene file's folder (`anchor_paths` made those given on a command
    line or in a study absolute); a file that is not there is refused."""
    prefix = section + '.'
    settings = {path[len(prefix):]: value for path, value in values.items()
                if path.startswith(prefix) and value is not None}
    if 'file' in settings:
        file = Path(settings['file']).expanduser()
        if not file.is_absolute():
            file = scene_path.parent / file
        if file.is_dir():
            raise locator.error(f'{section}.file', f'{str(file)!r} is a folder, not a file')
        if not file.is_file():
            tried = ('' if Path(settings['file']).expanduser().is_absolute() else
                     " (a relative file is read from the scene file's folder; one named with "
                     '--set or in scene_overrides from the working directory, here '
                     f'{Path.cwd()}; one named in a study from the study file\'s folder; '
                     'in Python, give load_scene an absolute path or '
                     'anchor_paths(overrides, folder))')
            raise locator.error(f'{section}.file', f'{settings["file"]!r} not found: no file '
                                f'{file}{tried}')
        settings['file'] = str(file)
    return settings


def _scenario_reference(scenario, scene_path):
    """A scenario given as a Python file, made absolute (relative to the scene file)."""
    if scenario.endswith('.py'):
        file = Path(scenario)
        return str(file if file.is_absolute() else (scene_path.parent / file).resolve())
    return scenario
