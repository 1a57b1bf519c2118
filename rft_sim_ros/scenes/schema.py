"""The scene file schema: every key a scene YAML may hold, with its type, unit, default, whether
it is required, and what it means. One table drives the validation (`check_scene`), the
effective values (`effective_values`) and the reference (docs/scene-reference.md, written by
`python -m rft_sim_ros.scenes.schema --write docs/scene-reference.md`; a test keeps it in
step).

Errors name the file, the line and the key (`scene.yaml:12: rft.plates_per_body: ...`); a
value that came from an override names the override instead (`--set timestep: ...`). Lines
come from PyYAML's node marks (`load_with_lines`).
"""
import difflib
import math
import re
import sys
from dataclasses import dataclass
from typing import Callable

import yaml

from ..control.hybrid import gain_patterns
from ..robot.joints import check_servos
from ..robot.pose import parse_spawn
from ..robot.sand_bodies import OTHER_BODIES_DENSITY_PER_MM2
from ..units import zeta_problem

#: The default of a key that must be given.
REQUIRED = object()


class SceneError(ValueError):
    """A scene cannot be loaded or is invalid; the message says what to fix."""


def _number(value, positive=False, minimum=None, maximum=None):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f'must be a finite number, got {value!r}')
    if positive and value <= 0:
        raise ValueError(f'must be > 0, got {value!r}')
    if minimum is not None and value < minimum:
        raise ValueError(f'must be >= {minimum}, got {value!r}')
    if maximum is not None and value > maximum:
        raise ValueError(f'must be <= {maximum}, got {value!r}')
    return float(value)


def _positive(value):
    return _number(value, positive=True)


def _finite(value):
    return _number(value)


def _count(value):
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ValueError(f'must be a positive integer, got {value!r}')
    return value


def _text(value):
    if not isinstance(value, str):
        raise ValueError(f'must be text, got {value!r}')
    return value


def _optional_text(value):
    return None if value is None else _text(value)


def _geom_reference(value):
    """A geom's name, or its id (an integer, for a geom without a name), as text."""
    if isinstance(value, int) and not isinstance(value, bool) and value >= 0:
        return str(value)
    if value is not None and not (isinstance(value, str) and value.strip()):
        raise ValueError(f"must be a geom's name or its id (an integer >= 0), got {value!r}")
    return value


def _names(value):
    """A list of names/patterns, or one text of comma-separated names/patterns."""
    if isinstance(value, str) and value.strip():
        return [part.strip() for part in value.split(',') if part.strip()]
    if not isinstance(value, list) or not value or not all(isinstance(v, str) for v in value):
        raise ValueError(f'must be a name or a list of names, got {value!r}')
    return list(value)


def _mapping(value):
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise ValueError(f'must be a mapping, got {value!r}')
    return dict(value)


def _text_mapping(value):
    """A mapping of names to values, all as text."""
    return {str(k): str(v) for k, v in _mapping(value).items()}


def _mapping_of(check):
    """A check of a mapping whose every value passes `check` (errors name the entry)."""
    def checked(value):
        value = _mapping(value)
        for name, item in value.items():
            try:
                check(item)
            except ValueError as error:
                raise ValueError(f'{name}: {error}') from None
        return value
    return checked


def _legs(value):
    if value == 'auto':
        return value
    value = _mapping(value)
    if not value or not all(isinstance(b, list) and b and all(isinstance(x, str) for x in b)
                            for b in value.values()):
        raise ValueError("must be 'auto' or map each leg name to a list of its sand bodies, "
                         f'got {value!r}')
    return {str(k): list(v) for k, v in value.items()}


def _servos(value):
    return check_servos(_mapping(value))


def _spawn(value):
    parse_spawn(value)
    return value


def _zeta(value):
    problem = zeta_problem(value)
    if problem:
        raise ValueError(problem.replace('zeta ', '', 1))
    return float(value)


def _duration(value):
    return value if value == 'auto' else _positive(value)


def _choice(*options):
    def check(value):
        if value not in options:
            raise ValueError(f'must be one of {", ".join(map(str, options))}, got {value!r}')
        return value
    return check


def _pair(value, positive=False):
    """[a, b] of two finite numbers (> 0 with `positive`)."""
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ValueError(f'must be [x, y], got {value!r}')
    return [_number(v, positive=positive) for v in value]


def _low_high(value):
    low, high = _pair(value)
    if high < low:
        raise ValueError(f'must be [low, high] with low <= high, got {value!r}')
    return [low, high]


def _flag(value):
    if not isinstance(value, bool):
        raise ValueError(f'must be true or false, got {value!r}')
    return value


def _regions(value):
    if not isinstance(value, list) or not value or not all(isinstance(r, dict) for r in value):
        raise ValueError('must be a list of {x: [low, high], y: [low, high], factor: f}, '
                         f'got {value!r}')
    for index, region in enumerate(value):
        unknown = sorted(map(str, set(region) - {'x', 'y', 'factor'}))
        if unknown:
            raise ValueError(f'region {index}: unknown key{"s" * (len(unknown) > 1)} '
                             f'{", ".join(unknown)} (a region is {{x: [low, high], y: [low, '
                             'high], factor: f})')
    return value


def _vector3(value):
    if not isinstance(value, list) or len(value) != 3:
        raise ValueError(f'must be [x, y, z], got {value!r}')
    return [_number(v) for v in value]


def _seed(value):
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise ValueError(f'must be an integer >= 0, got {value!r}')
    return value


def _pixels(value):
    """A frame's side: an even integer >= 16 (H.264 in yuv420p halves it)."""
    if isinstance(value, bool) or not isinstance(value, int) or value < 16 or value % 2:
        raise ValueError(f'must be an even integer >= 16 (pixels), got {value!r}')
    return value


def _section(value):
    return _mapping(value)


def _optional_section(value):
    return None if value is None else _mapping(value)


@dataclass(frozen=True)
class Key:
    """One scene key: dotted `path`, `type` and `unit` as the reference shows them,
    `default` (REQUIRED: must be given; None: absent), `description`, and `check(value)`
    that returns the value to use or raises ValueError with what is wrong. `variants`: the
    kinds of its section the key belongs to (`VARIANTS`; empty: every kind), e.g. a slope's
    angle; given for another kind it is refused, not silently left without effect."""
    path: str
    type: str
    unit: str
    default: object
    description: str
    check: Callable
    variants: tuple = ()

    @property
    def required(self):
        return self.default is REQUIRED

    @property
    def section(self):
        """Whether the key is a mapping of further schema keys."""
        return self.check in (_section, _optional_section)


KEYS = (
    Key('name', 'text', '', None, 'Scene name (default: the file name without .yaml).',
        _optional_text),
    Key('description', 'text', '', '', 'What the scene shows; its first line is listed by '
        '`rft-sim scenes`.', _text),
    Key('scenario', 'text', '', 'external', 'Behaviour of the scene: a bundled scenario '
        '(module of rft_sim_ros.scenes.scenarios), a Python file `path/to/file.py` (relative '
        'to the scene file; its class `Scenario`) or `module:Class` (importable). See '
        'docs/scene-reference.md, "Own scenarios".', _text),
    Key('model', 'text', '', REQUIRED, 'The robot: an MJCF (.xml), URDF (.urdf) or xacro '
        "(.xacro, .urdf.xacro) file, relative to the scene file or the package's models/ "
        'folder.', _text),
    Key('timestep', 'number > 0', 's', 0.001, 'Integration timestep.', _positive),
    Key('duration', "number > 0 or 'auto'", 's', 10.0, "Sim time `rft-sim run` runs; "
        "'auto': as long as the scenario says.", _duration),
    Key('zeta', 'number in (0, 100]', 'N/cm^3', 3.75, 'Sand stiffness (the RFT literature '
        'unit; 3.75 = Quikrete play sand).', _zeta),
    Key('sand', 'mapping', '', {}, 'The sand bed.', _section),
    Key('sand.surface_height', 'number', 'm', 0.0, 'z of the horizontal sand surface (the '
        "plane's; a slope's at the origin, a grid's offset; sand.surface).", _finite),
    Key('sand.keep_floor', 'true or false', '', False, "Keep the model's own floor planes "
        '(plane geoms fixed to the world that can touch the robot) as rigid MuJoCo floors; by '
        'default their collisions are switched off, since the sand carries the robot.', _flag),
    Key('sand.surface', 'mapping', '', {}, 'Shape of the sand surface (docs/terrain.md).',
        _section),
    Key('sand.surface.type', "'plane', 'slope', 'grid' or 'hfield'", '', 'plane',
        'Horizontal plane at sand.surface_height; inclined plane; height field from a file; '
        "the model's own <hfield> geom.", _choice('plane', 'slope', 'grid', 'hfield')),
    Key('sand.surface.angle_deg', 'number in [0, 89.9]', 'deg', 0.0, 'Slope: inclination '
        '(through (0, 0, sand.surface_height)).',
        lambda v: _number(v, minimum=0.0, maximum=89.9), variants=('slope',)),
    Key('sand.surface.downhill_deg', 'number', 'deg', 0.0, 'Slope: heading of the downhill '
        'direction, from +x towards +y.', _finite, variants=('slope',)),
    Key('sand.surface.file', 'text', '', None, 'Grid: a PNG (grey levels) or .npy (heights, '
        'm, added to sand.surface_height), relative to the scene file.', _optional_text,
        variants=('grid',)),
    Key('sand.surface.size', '[x, y] > 0', 'm', None, "Grid: extent of the file's nodes.",
        lambda v: _pair(v, positive=True), variants=('grid',)),
    Key('sand.surface.center', '[x, y]', 'm', [0.0, 0.0], "Grid: world (x, y) of the grid's "
        'centre.', _pair, variants=('grid',)),
    Key('sand.surface.height_range', '[low, high]', 'm', None, 'Grid: heights that grey 0..1 '
        'maps to (required for a PNG; rescales a .npy).', _low_high, variants=('grid',)),
    Key('sand.surface.geom', 'text or id', '', None, "Hfield: the model's hfield geom, fixed "
        "to the world, by its name, its <hfield>'s, or its id (default: the only one; its "
        'rigid collisions are switched off).', _geom_reference, variants=('hfield',)),
    Key('sand.surface.beyond', "'edge' or 'plane'", '', 'edge', 'Grid, hfield: the sand '
        "beyond the field: its edge heights continued, or the plane at sand.surface_height "
        '(met over one cell outside the field: a patch of terrain in a flat bed).',
        _choice('edge', 'plane'), variants=('grid', 'hfield')),
    Key('sand.zeta_map', 'mapping or null', '', None, 'Factors multiplying zeta by position '
        '(docs/terrain.md); null: zeta everywhere.', _optional_section),
    Key('sand.zeta_map.regions', 'list of {x, y, factor}', 'm', None, 'Rectangles {x: [low, '
        'high], y: [low, high], factor: f}, later over earlier.', _regions,
        variants=('regions',)),
    Key('sand.zeta_map.cell', 'number > 0', 'm', 0.01, 'Raster of the regions.', _positive,
        variants=('regions',)),
    Key('sand.zeta_map.file', 'text', '', None, 'Instead of regions: a .npy of factors or a '
        'PNG (grey levels onto sand.zeta_map.range), relative to the scene file.',
        _optional_text, variants=('file',)),
    Key('sand.zeta_map.size', '[x, y] > 0', 'm', None, "File: extent of the map's cells.",
        lambda v: _pair(v, positive=True), variants=('file',)),
    Key('sand.zeta_map.center', '[x, y]', 'm', [0.0, 0.0], "File: world (x, y) of the map's "
        'centre.', _pair, variants=('file',)),
    Key('sand.zeta_map.range', '[low, high]', '', None, 'PNG file: factors that grey 0..1 '
        'maps to.', _low_high, variants=('file',)),
    Key('sand.deformable', 'mapping', '', {}, 'Deformable sand: footprints, craters, piles, '
        'avalanches (docs/terrain.md).', _section),
    Key('sand.deformable.enabled', 'true or false', '', False, 'Whether the robot changes '
        'the surface.', _flag),
    Key('sand.deformable.cell', 'number > 0', 'm', 0.01, 'Side of the square cells of the '
        'deformable bed (about the plates\' size or larger).', _positive),
    Key('sand.deformable.repose_deg', 'number in (0, 89.9]', 'deg', 30.0, 'Angle of repose: '
        'steeper slopes avalanche.', lambda v: _number(v, positive=True, maximum=89.9)),
    Key('sand.deformable.size', '[x, y] > 0', 'm', [2.0, 2.0], 'Extent of the deformable bed '
        '(outside it the surface stays as it is).', lambda v: _pair(v, positive=True)),
    Key('sand.deformable.center', '[x, y] or null', 'm', None, "World (x, y) of the bed's "
        'centre; null: under the base body in the initial pose (its x, y to the nearest whole '
        'cell), so that a robot placed anywhere starts on the bed.',
        lambda v: None if v is None else _pair(v)),
    Key('rft', 'mapping', '', {}, 'Which bodies feel sand and how they are discretised.',
        _section),
    Key('rft.sand_bodies', "'auto', a name or glob, or a list of them", '', 'auto', 'The bodies '
        "that touch sand: MuJoCo body names, glob patterns ('*_calf', '*foot*') or auto (one "
        'per kinematic branch: the body with its lowest collision geometry in the initial pose, '
        'and every body touching the ground; '
        'rft_sim_ros/robot/sand_bodies.py), alone or beside names and globs ([auto, crate]: '
        "auto's picks and a loose crate's). The bodies chosen are printed at start-up.", _names),
    Key('rft.plate_geoms', "'collision' or 'visual'", '', 'collision', 'Which geoms of a sand '
        'body carry its plates: the ones MuJoCo collides (a body without any: its visual '
        'geoms; a body whose collision geoms are separate spheres, contact points for rigid '
        'ground, carries them on their convex hull, the sole they mark), or its visual geoms, '
        'the shape as drawn (a body without visual geoms keeps its collision geoms).',
        _choice('collision', 'visual')),
    Key('rft.plates_per_body', 'integer >= 1', 'plates', 300, 'Plates on each sand body '
        '(ignored when rft.plate_density_per_mm2 is given).', _count),
    Key('rft.plate_density_per_mm2', 'number > 0', 'plates/mm^2', None, 'Plates per mm^2 '
        'of body surface instead of a count (replaces rft.plates_per_body).', _positive),
    Key('rft.other_bodies_density_per_mm2', 'number > 0 or null', 'plates/mm^2',
        OTHER_BODIES_DENSITY_PER_MM2, 'Plates per mm^2 on every other moving body with '
        'collision geoms (not chosen by rft.sand_bodies: shins, trunk, head, arms), so that no '
        'body passes through the sand (a fallen robot lies on it); coarser than the sand bodies '
        "(a mesh as the convex outline MuJoCo collides; a small body its geoms' coarsest "
        'tessellation, said at start-up where that is more), and free while above the sand; '
        'null: only the rft.sand_bodies carry plates, the others '
        'pass through the sand (rft_sim_ros/robot/sand_bodies.py).',
        lambda v: None if v is None else _positive(v)),
    Key('rft.plates', 'mapping body -> integer', 'plates', {}, 'Per-body plate counts that '
        'replace the default count.', _mapping_of(_count)),
    Key('rft.normalisation', "'treers' or 'rft_sim'", '', 'treers', 'Which normalisation of '
        'the RFT coefficients (docs: README, "RFT conventions").', _choice('treers', 'rft_sim')),
    Key('rft.coupling', "'exact' or 'paper'", '', 'exact', 'How sand forces meet the '
        'dynamics: exact (from the state being integrated, no lag) or paper (the RFT-SiM '
        "code's loop: forces from the last step's poses and finite-difference velocities, "
        'applied one step late; for comparisons, rft_sim_ros/sand/paper_loop.py).',
        _choice('exact', 'paper')),
    Key('rft.low_velocity', 'mapping', '', {}, 'Treatment of RFT near rest (rft_sim_ros/sand/'
        'engine.py, LowVelocity).', _section),
    Key('rft.low_velocity.method', "'implicit', 'ema' or 'none'", '', 'implicit',
        'Implicit rest-holding law, the paper\'s moving average, or raw explicit RFT.',
        _choice('implicit', 'ema', 'none')),
    Key('rft.low_velocity.rest_speed', 'number > 0', 'm/s', 1e-5, "The implicit law's "
        'regularisation speed.', _positive),
    Key('rft.low_velocity.ema_alpha', 'number in (0, 1]', '', 0.1, "The 'ema' method's "
        'smoothing factor.', lambda v: _number(v, positive=True, maximum=1.0)),
    Key('rft.dynamic', 'mapping or null', '', None, 'The dynamic (inertial) RFT term; null: '
        'off.', _optional_section),
    Key('rft.dynamic.lambda', 'number >= 0', '', 1.0, 'Scale of the dynamic term.',
        lambda v: _number(v, minimum=0.0)),
    Key('rft.dynamic.density', 'number > 0', 'kg/m^3', 1600.0, 'Sand bulk density of the '
        'dynamic term.', _positive),
    Key('legs', "'auto' or mapping leg -> list of sand bodies", '', 'auto', 'The legs whose '
        'summed sand wrench is reported (/rft/<leg>/wrench, per-leg metrics); the last body of '
        "each list is the leg's reference point. auto: one leg per branch of the kinematic "
        'tree from the base that holds sand bodies, named after its first body.', _legs),
    Key('base_body', 'text', '', None, 'The body whose pose is /odom and the base metrics '
        '(default: the first body under the world).', _optional_text),
    Key('publish_rate', 'number > 0', 'Hz', 100.0, 'Sim-time rate of published and recorded '
        'states.', _positive),
    Key('control_rate', 'number > 0', 'Hz', 500.0, 'Sim-time rate at which the scenario and '
        'the command targets are applied (held in between).', _positive),
    Key('servo_kp', 'number > 0 or null', 'N m/rad or N/m', None, "Stiffness that replaces "
        "every MuJoCo position actuator's kp.",
        lambda v: None if v is None else _positive(v)),
    Key('servos', "mapping joint pattern -> {kp, kd, effort} or 'passive'", '', {},
        'Position-interface gains per joint (glob patterns, later ones win): kp N m/rad or '
        'N/m, kd N m s/rad or N s/m, effort limit N m or N; passive: no interfaces, the joint '
        "moves freely (the model's own actuators on it switched off, with a notice). A joint "
        "the model drives with another actuator kind (velocity, a muscle) gets a servo only "
        "when named here (those actuators switched off). A pattern that matches no joint is "
        'refused. Defaults from the robot mass (docs/robots.md).', _servos),
    Key('joint_gains', 'mapping joint pattern -> {kp, kd}', '', {}, 'Gains of the hybrid '
        'joint commands (a sensor_msgs/JointState on the joint commands topic: tau = kp (q* - '
        'q) + kd (dq* - dq) + tau_ff, docs/ros.md), glob patterns, later ones win: kp N m/rad '
        "or N/m, kd N m s/rad or N s/m, each >= 0; joints not named: their position servo's "
        'gains.', lambda v: gain_patterns(_mapping(v))),
    Key('sensors', 'mapping', '', {}, 'What the robot senses, published and recorded with '
        'the state (rft_sim_ros/sim/sensors.py, docs/ros.md); all off by default.', _section),
    Key('sensors.imu', 'true or false', '', False, 'An IMU (sensor_msgs/Imu): orientation, '
        'angular velocity, specific force (+g up at rest).', _flag),
    Key('sensors.imu_topic', 'text', '', '/imu/data', "The IMU's topic.", _text),
    Key('sensors.imu_frame', 'text or null', '', None, "The IMU's site or body; null: the site "
        "of the model's imu sensors, else a body named imu*, *_imu or *_imu_link, else the "
        'base.', _optional_text),
    Key('sensors.imu_noise', 'mapping', '', {}, "The IMU's noise and biases (none by default).",
        _section),
    Key('sensors.imu_noise.gyro_std', 'number >= 0', 'rad/s', 0.0, 'White noise of the '
        'angular velocity (standard deviation, each axis).', lambda v: _number(v, minimum=0.0)),
    Key('sensors.imu_noise.accel_std', 'number >= 0', 'm/s^2', 0.0, 'White noise of the '
        'linear acceleration (standard deviation, each axis).',
        lambda v: _number(v, minimum=0.0)),
    Key('sensors.imu_noise.gyro_bias', '[x, y, z]', 'rad/s', [0.0, 0.0, 0.0], 'Constant '
        'bias of the angular velocity, IMU axes.', lambda v: _vector3(v)),
    Key('sensors.imu_noise.accel_bias', '[x, y, z]', 'm/s^2', [0.0, 0.0, 0.0], 'Constant '
        'bias of the linear acceleration, IMU axes.', lambda v: _vector3(v)),
    Key('sensors.imu_noise.seed', 'integer or null', '', None, 'Seed of the noise (null: a '
        'new one each run).', lambda v: None if v is None else _seed(v)),
    Key('sensors.contacts', 'true or false', '', False, 'Foot contacts per leg: stance flag '
        'and normal force (/rft/foot_contacts).', _flag),
    Key('sensors.contact_threshold', 'number > 0 or null', 'N', None, 'Normal force above '
        "which a leg is in stance; null: 5 % of the robot's weight over its legs.",
        lambda v: None if v is None else _positive(v)),
    Key('sensors.model_sensors', 'true or false', '', False, "The MJCF model's own named "
        '<sensor>s, each on a topic named after it (docs/ros.md).', _flag),
    Key('robot', 'mapping', '', {}, 'How the robot file is loaded, its initial pose and '
        'spawn.', _section),
    Key('robot.base', "'floating', 'fixed' or null", '', None, 'The root body: free '
        '(6-DOF) or welded to the world; null: as the file says (a URDF welded where a fixed '
        'joint hangs it from a `world` link, else free; an MJCF as written). An MJCF root '
        'body moving on other joints than one free joint is refused.',
        _choice('floating', 'fixed', None)),
    Key('robot.package_paths', 'mapping package -> folder', '', {}, 'Folders of the ROS '
        'packages that $(find PKG) and package://PKG name (relative to the scene file); '
        'else the ament index or ROS_PACKAGE_PATH.', _text_mapping),
    Key('robot.xacro_args', 'mapping name -> value', '', {}, 'xacro arguments ($(arg NAME)).',
        _text_mapping),
    Key('robot.keyframe', 'text or null', '', None, 'Named keyframe of the model for the '
        'initial pose (held until commands arrive); null: the first of home, stand, standing '
        "and default the model has (vendors' and MuJoCo Menagerie's standing poses), else its "
        "first keyframe, else its qpos0 (the choice is printed at start-up); '': its qpos0.",
        _optional_text),
    Key('robot.initial_positions', 'mapping joint -> number', 'rad or m', {}, 'Joint '
        'positions of the initial pose, applied after the keyframe.', _mapping_of(_finite)),
    Key('robot.spawn', "'auto', 'model', 'rest' or 'drop:HEIGHT'", 'm', 'auto', 'Where the '
        'robot starts: as the model/scenario puts it; rest = lowered onto the sand and settled '
        'before the run; drop:H = lowest sand-body point H m above the sand, released; auto '
        '= rest under the external scenario (a robot file, or a scene naming it, starts so), '
        'model under any other. Rest and drop first turn the robot to the plane of a sloped '
        'surface under its sand bodies; a base fixed to the world starts where the model puts '
        'it.',
        _spawn),
    Key('video', 'mapping', '', {}, "The run's video (docs/video.md).", _section),
    Key('video.enabled', 'true or false', '', False, 'Whether `rft-sim run` renders the run '
        'into video.mp4 in its output folder (`--video` sets it).', _flag),
    Key('video.fps', 'number > 0', 'Hz', 25.0, 'Frames per second of sim time: the video '
        'plays in real time.', _positive),
    Key('video.width', 'even integer >= 16', 'px', 640, 'Frame width.', lambda v: _pixels(v)),
    Key('video.height', 'even integer >= 16', 'px', 480, 'Frame height.', lambda v: _pixels(v)),
    Key('video.camera', "'follow', 'fixed' or a camera's name", '', 'follow', "'follow' "
        "tracks the robot's base, 'fixed' stays where it starts; or one of the model's "
        'cameras.', _text),
    Key('video.forces', 'true or false', '', True, "An arrow for each leg's ground force.",
        _flag),
    Key('video.plates', 'true or false', '', True, 'The plates in the sand, coloured by '
        'their stress.', _flag),
    Key('video.sand_alpha', 'number in (0, 1]', '', 0.55, "The sand's opacity: below 1 the "
        'plates and the feet in it show through; 1 (opaque) costs about half as much a frame '
        'and hides them.', lambda v: _number(v, positive=True, maximum=1.0)),
    Key('params', 'mapping', '', {}, "The scenario's own values (see its module docstring); "
        'each can be overridden with `--set NAME=VALUE`.', _mapping),
)

#: Schema keys by dotted path.
BY_PATH = {key.path: key for key in KEYS}

#: Mappings whose own keys are free (not schema keys).
_FREE = ('params', 'legs', 'rft.plates', 'robot.package_paths', 'robot.xacro_args')


class NumberLoader(getattr(yaml, 'CSafeLoader', yaml.SafeLoader)):
    """PyYAML's safe loader (on libyaml's parser when PyYAML was built with it: a scene file
    in about 0.5 ms instead of 6; else its pure-Python one, the same content and marks) that
    reads numbers as YAML 1.2 does: PyYAML follows YAML 1.1, where `1e-3` and `5e-2` (no
    decimal point) are text, and users mean numbers."""


NumberLoader.add_implicit_resolver(
    'tag:yaml.org,2002:float',
    re.compile(r'''^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                 |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
                 |[-+]?\.[0-9_]+(?:[eE][-+]?[0-9]+)?
                 |[-+]?\.(?:inf|Inf|INF)
                 |\.(?:nan|NaN|NAN))$''', re.X),
    list('-+0123456789.'))


def load_yaml(text):
    """The content of the YAML `text`, numbers read as YAML 1.2 does (`NumberLoader`)."""
    return yaml.load(text, Loader=NumberLoader)


def load_with_lines(text, source='<scene>'):
    """Parse YAML `text` -> (content, {dotted key: 1-based line}) from PyYAML's node marks.
    Raises SceneError with the file and line of a syntax error."""
    loader = NumberLoader(text)
    try:  # parsed once: the content is constructed from the node tree
        node = loader.get_single_node()
        content = None if node is None else loader.construct_document(node)
    except yaml.YAMLError as error:
        mark = getattr(error, 'problem_mark', None)
        where = f'{source}:{mark.line + 1}' if mark else source
        problem = getattr(error, 'problem', None) or str(error)
        raise SceneError(f'{where}: not valid YAML: {problem}') from None
    finally:
        loader.dispose()
    lines = {}

    def walk(node, prefix):
        if not isinstance(node, yaml.MappingNode):
            return
        for key_node, value_node in node.value:
            path = f'{prefix}{key_node.value}'
            lines[path] = key_node.start_mark.line + 1
            walk(value_node, path + '.')

    walk(node, '')
    return content, lines


class Locator:
    """Where a scene value came from, for error messages: file and line, or an override;
    given_by: how the overrides were given ('--set', the ROS node's 'scene_overrides')."""

    def __init__(self, source, lines=None, overridden=(), given_by='--set'):
        self.source, self.lines, self.overridden = str(source), lines or {}, set(overridden)
        self.given_by = given_by

    def where(self, path):
        """'file:line: path' (or 'file: --set path' for an overridden value, as given_by)."""
        if path in self.overridden:
            return f'{self.source}: {self.given_by} {path}'
        parts = path.split('.')
        for end in range(len(parts), 0, -1):  # the key's own line, else its section's
            line = self.lines.get('.'.join(parts[:end]))
            if line is not None:
                return f'{self.source}:{line}: {path}'
        return f'{self.source}: {path}'

    def error(self, path, message):
        return SceneError(f'{self.where(path)}: {message}')


#: Sections whose keys belong to kinds (`Key.variants`): {section: (the kind a scene has,
#: from its values and the dotted paths it gives, None where it gives none; what a kind is
#: called in a message)}.
VARIANTS = {
    'sand.surface': (lambda values, given: values['sand.surface.type'],
                     lambda kind: f'sand.surface.type {kind}'),
    'sand.zeta_map': (lambda values, given: next((kind for kind in ('regions', 'file')
                                                   if f'sand.zeta_map.{kind}' in given), None),
                      lambda kind: {'regions': 'a map of sand.zeta_map.regions',
                                    'file': 'a map from sand.zeta_map.file'}[kind]),
}


#: Scene keys given a new name, {old dotted path: new dotted path}. A scene file or an
#: override that gives the old name still loads, for one release after the rename, with a
#: notice that says the new name (`renamed_keys`); the reference lists them.
RENAMED_KEYS = {'rft.bodies': 'rft.sand_bodies'}


def renamed_keys(raw, overrides, source, lines, given_by='--set'):
    """The scene mapping `raw` and the overrides {key: value} with every old key name of
    RENAMED_KEYS given the new name -> (raw, overrides, notices): one notice a renamed key,
    naming where it was given and its new name. `lines` ({dotted key: line}, load_with_lines)
    gets the new names' lines, so that errors point at the line as written. Raises
    SceneError where a scene gives a key by both names; given_by: how the overrides were
    given, as the notices name them (`Locator`)."""
    raw, overrides, notices = dict(raw), dict(overrides), []
    for old, new in RENAMED_KEYS.items():
        section, _, old_leaf = old.rpartition('.')
        new_leaf = new.rpartition('.')[2]
        mapping = raw.get(section) if section else raw
        if isinstance(mapping, dict) and old_leaf in mapping:
            where = f'{source}:{lines[old]}' if old in lines else str(source)
            if new_leaf in mapping:
                raise SceneError(f'{where}: {old} is the old name of {new}, which the scene '
                                 f'also gives: keep {new} only')
            mapping = {new_leaf if k == old_leaf else k: v for k, v in mapping.items()}
            raw = {**raw, section: mapping} if section else mapping
            if old in lines:
                lines[new] = lines[old]
            notices.append(f'{where}: {old} is deprecated, now called {new} (the old name is '
                           'accepted for this release)')
        if old in overrides:
            if new in overrides:
                raise SceneError(f'{given_by} {old} and {new} name the same key ({old} is its '
                                 f'old name): give {new} only')
            overrides = {new if k == old else k: v for k, v in overrides.items()}
            notices.append(f'{given_by} {old} is deprecated, now called {new} (the old name is '
                           'accepted for this release)')
    return raw, overrides, notices


def check_scene(raw, locator):
    """Validate the scene mapping `raw` against the schema -> {dotted path: value} for every
    leaf key (defaults filled in; sections whose value is null have no leaves). Raises
    SceneError naming file, line and key."""
    if not isinstance(raw, dict):
        raise SceneError(f'{locator.source}: a scene file must hold a mapping')
    values = {}
    _check_section(raw, '', locator, values)
    _check_variants(set(given_paths(raw)), values, locator)
    return values


def given_paths(content, prefix=''):
    """The dotted paths of the schema keys the (checked) scene mapping `content` gives, not
    left to their defaults."""
    for name, value in content.items():
        path = f'{prefix}{name}'
        yield path
        if isinstance(value, dict) and BY_PATH[path].section:
            yield from given_paths(value, path + '.')


def _check_variants(given, values, locator):
    """Refuse a given key of another kind than its section's in this scene (a slope's angle
    on a plane, a file's size beside regions): it would have no effect."""
    for path in sorted(given):
        key = BY_PATH[path]
        if not key.variants:
            continue
        kind_of, name = VARIANTS[path.rpartition('.')[0]]
        kind = kind_of(values, given)
        if kind is not None and kind not in key.variants:
            wanted = ' or '.join(name(v) for v in key.variants)
            raise locator.error(path, f'applies to {wanted}, and this scene has {name(kind)}: '
                                'drop the key or change that')


def _check_section(content, prefix, locator, values):
    for name in content:
        path = f'{prefix}{name}'
        if path not in BY_PATH:
            siblings = [k.path for k in KEYS if k.path.rsplit('.', 1)[0] == prefix.rstrip('.')
                        or (not prefix and '.' not in k.path)]
            close = difflib.get_close_matches(path, siblings, n=1)
            hint = f' (did you mean {close[0]}?)' if close else ''
            raise locator.error(path, f'unknown key{hint}; the scene keys are listed in '
                                'docs/scene-reference.md')
    for key in KEYS:
        parent, _, leaf = key.path.rpartition('.')
        if parent != prefix.rstrip('.') or '.' in key.path[len(prefix):]:
            continue
        if leaf not in content or (content[leaf] is None and key.section):
            if key.required:
                raise locator.error(key.path, 'missing (required)')
            value = key.default
            if key.section:
                if value is None:
                    continue
                _check_section({}, key.path + '.', locator, values)
                continue
            if value is not None:
                value = key.check(value)  # the form a given value would have ('auto' -> list)
        else:
            try:
                value = key.check(content[leaf])
            except ValueError as error:
                raise locator.error(key.path, str(error)) from None
            if key.section:
                if value is not None:
                    _check_section(value, key.path + '.', locator, values)
                continue
        values[key.path] = value


def reference_table():
    """The markdown table of every scene key (the generated part of docs/scene-reference.md)."""
    rows = ['| key | type | unit | default | required | description |',
            '|---|---|---|---|---|---|']
    for key in KEYS:
        default = '' if key.required or key.default is None else f'`{key.default!r}`'
        if key.default == {}:
            default = ''
        rows.append(f'| `{key.path}` | {key.type} | {key.unit} | {default} | '
                    f'{"yes" if key.required else "no"} | {key.description} |')
    rows += ['', 'Renamed keys, still accepted with a notice for one release:', '',
             '| old key | new key |', '|---|---|']
    rows += [f'| `{old}` | `{new}` |' for old, new in RENAMED_KEYS.items()]
    return '\n'.join(rows) + '\n'


#: Markers around the generated table in docs/scene-reference.md.
TABLE_BEGIN = '<!-- scene keys: generated by python -m rft_sim_ros.scenes.schema -->'
TABLE_END = '<!-- end of scene keys -->'


def with_reference_table(document):
    """`document` (markdown) with the text between TABLE_BEGIN and TABLE_END replaced by the
    current reference_table()."""
    head, begin, rest = document.partition(TABLE_BEGIN)
    _, end, tail = rest.partition(TABLE_END)
    if not (begin and end):
        raise ValueError(f'the document has no {TABLE_BEGIN} ... {TABLE_END} block')
    return f'{head}{TABLE_BEGIN}\n{reference_table()}{TABLE_END}{tail}'


def main(argv=None):
    """`python -m rft_sim_ros.scenes.schema [--write DOC]`: print the key table, or rewrite
    its block in DOC."""
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ['--write'] and len(argv) == 2:
        with open(argv[1]) as f:
            document = f.read()
        with open(argv[1], 'w') as f:
            f.write(with_reference_table(document))
    else:
        sys.stdout.write(reference_table())
    return 0


if __name__ == '__main__':
    sys.exit(main())
