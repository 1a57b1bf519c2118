"""Scene configuration: one YAML file per scene, validated into a `SceneConfig`.

A scene names the MJCF model, the bodies that touch sand and how they are discretised, the
sand (surface height, zeta), the timestep and duration (s, or `auto`: as long as the
scenario's own values say, e.g. one rotation at the set speed), the legs to report, and values of
the scene's own (`params`: masses, drop heights, gait...) that its scenario module uses.
Every value can be overridden from the command line or the ROS node (`--set key=value`):
a key is either a name in `params` or a dotted path into the file (e.g. `rft.plates_per_body`).

Units: SI throughout except zeta, in N/cm^3 (the paper's unit).
"""
import copy
import math
from dataclasses import dataclass
from pathlib import Path

import yaml

from .. import resources
from ..units import zeta_problem


#: Settings that replace each other: overriding one removes the other.
_ALTERNATIVES = {'rft.plates_per_body': 'rft.plate_density_per_mm2',
                 'rft.plate_density_per_mm2': 'rft.plates_per_body'}

#: Every setting the scene format knows (dotted paths); any may be overridden, set or not.
SCHEMA_KEYS = frozenset({
    'name', 'description', 'scenario', 'model', 'timestep', 'duration', 'zeta',
    'sand', 'sand.surface_height', 'rft', 'rft.bodies', 'rft.plates_per_body',
    'rft.plate_density_per_mm2', 'rft.plates', 'rft.normalisation', 'rft.low_velocity',
    'rft.low_velocity.method', 'rft.low_velocity.rest_speed', 'rft.low_velocity.ema_alpha',
    'rft.dynamic', 'rft.dynamic.lambda', 'rft.dynamic.density', 'legs', 'base_body',
    'publish_rate', 'control_rate', 'servo_kp'})


class SceneError(ValueError):
    """A scene cannot be loaded or is invalid; the message says what to fix."""


@dataclass(frozen=True)
class SceneConfig:
    """A validated scene. `raw` keeps the whole (overridden) YAML content."""
    name: str
    description: str
    scenario: str
    model_path: Path
    timestep: float
    duration: float
    zeta: float
    surface_height: float
    sand_bodies: tuple
    plates_per_body: int
    plate_density_per_mm2: float
    plates_by_body: dict
    normalisation: str
    low_velocity: dict
    dynamic: dict
    legs: dict
    base_body: str
    publish_rate: float
    control_rate: float
    servo_kp: float
    params: dict
    raw: dict


def bundled_scenes():
    """{name: path} of the scene YAML files shipped with the package."""
    return {path.stem: path for path in sorted(resources.config_dir().glob('*.yaml'))
            if _is_scene_file(path)}


def _is_scene_file(path):
    try:
        content = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError):
        return False
    return isinstance(content, dict) and 'scenario' in content


def load_scene(name_or_path, overrides=None):
    """Load a bundled scene by name, or a scene YAML by path, apply `overrides`
    ({key: value}, see module docstring) and validate it. Raises SceneError."""
    path = Path(name_or_path)
    if not (path.suffix in ('.yaml', '.yml') and path.is_file()):
        scenes = bundled_scenes()
        if str(name_or_path) not in scenes:
            raise SceneError(f'unknown scene {name_or_path!r}: not a YAML file and not one '
                             f'of the bundled scenes ({", ".join(scenes)})')
        path = scenes[str(name_or_path)]
    try:
        raw = yaml.safe_load(path.read_text())
    except yaml.YAMLError as error:
        raise SceneError(f'{path}: not valid YAML: {error}') from None
    if not isinstance(raw, dict):
        raise SceneError(f'{path}: a scene file must hold a mapping')
    raw = apply_overrides(raw, overrides or {})
    return _validate(raw, path)


def parse_assignment(text):
    """'key=value' -> (key, value), the value read as YAML (numbers, lists, booleans; 1e6
    counts as a number)."""
    key, sep, value = text.partition('=')
    if not sep or not key.strip():
        raise SceneError(f'--set expects key=value, got {text!r}')
    try:
        parsed = yaml.safe_load(value)
    except yaml.YAMLError:
        parsed = value
    if isinstance(parsed, str):  # YAML 1.1 reads 1e6 as text; users mean a number
        try:
            parsed = float(parsed)
        except ValueError:
            pass
    return key.strip(), parsed


def apply_overrides(raw, overrides):
    """A copy of the scene mapping `raw` with `overrides` applied (see module docstring)."""
    raw = copy.deepcopy(raw)
    params = raw.setdefault('params', {}) or {}
    raw['params'] = params
    for key, value in overrides.items():
        if key in params:
            params[key] = value
            continue
        known = key in SCHEMA_KEYS
        node = raw
        parts = key.split('.')
        for part in parts[:-1]:
            if known and not isinstance(node.get(part), dict):
                node[part] = {}
            if not isinstance(node.get(part), dict):
                raise SceneError(f'unknown setting {key!r}: scene values are '
                                 f'{sorted(params)} or dotted keys of the scene file')
            node = node[part]
        if parts[-1] not in node and not known:
            raise SceneError(f'unknown setting {key!r}: scene values are {sorted(params)} '
                             'or dotted keys of the scene file')
        node[parts[-1]] = value
        if key in _ALTERNATIVES:
            node.pop(_ALTERNATIVES[key].split('.')[-1], None)
    return raw


def _number(raw, key, where, positive=True, default=None):
    value = raw.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise SceneError(f'{where}: {key} must be a finite number, got {value!r}')
    if positive and value <= 0:
        raise SceneError(f'{where}: {key} must be > 0, got {value!r}')
    return float(value)


def _validate(raw, path):
    where = f'scene {raw.get("name", path.stem)}'
    for key in ('scenario', 'model'):
        if not isinstance(raw.get(key), str):
            raise SceneError(f'{where}: missing {key!r}')
    model_path = Path(raw['model'])
    if not model_path.is_absolute():
        beside = path.parent / model_path
        model_path = beside if beside.is_file() else resources.models_dir() / model_path
    if not model_path.is_file():
        raise SceneError(f'{where}: model file {raw["model"]!r} not found '
                         f'(looked in {path.parent} and {resources.models_dir()})')
    problem = zeta_problem(raw.get('zeta'))
    if problem:
        raise SceneError(f'{where}: {problem}')
    sand = raw.get('sand') or {}
    rft = raw.get('rft') or {}
    bodies = rft.get('bodies')
    if not bodies or not isinstance(bodies, list) or not all(isinstance(b, str) for b in bodies):
        raise SceneError(f'{where}: rft.bodies must list the bodies that touch sand')
    count, density = rft.get('plates_per_body'), rft.get('plate_density_per_mm2')
    if (count is None) == (density is None):
        raise SceneError(f'{where}: give exactly one of rft.plates_per_body and '
                         'rft.plate_density_per_mm2')
    if count is not None and (isinstance(count, bool) or not isinstance(count, int) or count < 1):
        raise SceneError(f'{where}: rft.plates_per_body must be a positive integer, got {count!r}')
    if density is not None:
        density = _number(rft, 'plate_density_per_mm2', where)
    by_body = rft.get('plates') or {}
    if not isinstance(by_body, dict) or not all(
            b in bodies and isinstance(n, int) and not isinstance(n, bool) and n >= 1
            for b, n in by_body.items()):
        raise SceneError(f'{where}: rft.plates must map sand bodies to positive plate counts, '
                         f'got {by_body!r}')
    legs = raw.get('legs') or {}
    if not isinstance(legs, dict) or not all(
            isinstance(v, list) and v and all(b in bodies for b in v) for v in legs.values()):
        raise SceneError(f'{where}: legs must map each leg name to a list of its sand bodies')
    return SceneConfig(
        name=str(raw.get('name', path.stem)),
        description=str(raw.get('description', '')).strip(),
        scenario=raw['scenario'],
        model_path=model_path,
        timestep=_number(raw, 'timestep', where),
        duration=(None if raw.get('duration') == 'auto' else _number(raw, 'duration', where)),
        zeta=float(raw['zeta']),
        surface_height=_number(sand, 'surface_height', where, positive=False, default=0.0),
        sand_bodies=tuple(bodies),
        plates_per_body=count,
        plate_density_per_mm2=density,
        plates_by_body=dict(by_body),
        normalisation=str(rft.get('normalisation', 'treers')),
        low_velocity=dict(rft.get('low_velocity') or {}),
        dynamic=rft.get('dynamic'),
        legs={str(k): tuple(v) for k, v in legs.items()},
        base_body=str(raw.get('base_body', bodies[0])),
        publish_rate=_number(raw, 'publish_rate', where, default=100.0),
        control_rate=_number(raw, 'control_rate', where, default=500.0),
        servo_kp=(None if raw.get('servo_kp') is None
                  else _number(raw, 'servo_kp', where)),
        params=dict(raw.get('params') or {}),
        raw=raw,
    )
