"""A robot's initial pose and where it starts above the sand.

Initial pose: the model's own (qpos0), then a keyframe (`robot.keyframe` names it; by default
the first of DEFAULT_KEYFRAMES the model has, else its first keyframe), then single joints
set by name (`robot.initial_positions`, rad or m; a robot description's ros2_control
initial values come this way too).

Spawn (`robot.spawn`), for a robot whose root body has a free joint:
  auto        (the default) rest under the `external` scenario (a robot that holds its pose
              for commands: a robot file's scene, and a scene file naming the same robot,
              start alike), model under any other (its scenario sets the start);
  model       the pose as the model (or scenario) gives it;
  drop:H      turned to the sand surface under its sand bodies where that is not level (a
              slope: `align_to`), then moved vertically so that its sand bodies' geoms are
              H m or more above the sand surface under each (slopes, grids: the surface's
              highest point under each geom's bounding box), and one exactly H, at rest,
              then released;
  rest        as drop:0 (turned, the lowest clearance 0: on the surface), released, and
              settled before the run starts: stepped (joints holding their initial targets)
              until the base moves slower than REST_SPEED for REST_HOLD_S of sim time (at
              most SETTLE_LIMIT_S); the run's clock then starts at 0 from that state.
"""
import mujoco
import numpy as np

from ..sand.geoms import body_geoms
from .joints import movable_joints
from .sand_bodies import free_root_joint, geom_footprint, geom_lowest_z

#: spawn 'rest' is settled once the base is slower than this (m/s) for REST_HOLD_S (s).
REST_SPEED = 1e-3
REST_HOLD_S = 0.1
#: spawn 'rest' gives up after this much sim time (s).
SETTLE_LIMIT_S = 3.0
#: Nodes per side of the lattice on which `align_to` samples the surface under the robot.
ALIGN_SAMPLES = 9
#: A fitted plane less steep than this (dz/dx, m/m) is level: the rounding of a fit over a
#: level or symmetric surface (1e-16) turns nothing.
LEVEL_GRADIENT = 1e-9


#: The scenario under which spawn 'auto' is 'rest'.
HOLDING_SCENARIO = 'external'


def parse_spawn(text, scenario=HOLDING_SCENARIO):
    """'auto' | 'model' | 'rest' | 'drop:H' -> (kind, height m or None), 'auto' resolved
    for `scenario` (the scene's scenario reference; module docstring); raises ValueError."""
    if text == 'auto':
        return ('rest' if scenario == HOLDING_SCENARIO else 'model'), None
    if text in ('model', 'rest'):
        return text, None
    kind, _, height = str(text).partition(':')
    try:
        value = float(height)
    except ValueError:
        value = float('nan')
    if kind != 'drop' or not value >= 0 or value == float('inf'):
        raise ValueError(f"must be auto, model, rest or drop:HEIGHT (m, >= 0), got {text!r}")
    return 'drop', value


#: The keyframes the initial pose starts from when the scene names none, in the order looked
#: for: the standing pose of vendors' and MuJoCo Menagerie's models (Unitree's Go2, B2 and
#: H1 call theirs home; Menagerie's humanoids stand, standing or default); a model with none
#: of these starts from its first keyframe, and a model without keyframes from its qpos0.
DEFAULT_KEYFRAMES = ('home', 'stand', 'standing', 'default')


def initial_keyframe(model, keyframe=None):
    """The keyframe the initial pose starts from: `keyframe` (robot.keyframe: a name) where
    given ('': none, the model's qpos0); else the first of DEFAULT_KEYFRAMES the model has,
    else its first keyframe (its id where it has no name), else None."""
    if keyframe is not None:
        return keyframe or None
    for name in DEFAULT_KEYFRAMES:
        if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, name) >= 0:
            return name
    if model.nkey:
        return model.key(0).name or 0
    return None


def keyframe_label(keyframe):
    """How a notice names `keyframe` (a name, or the id of one without a name)."""
    return f'#{keyframe}' if isinstance(keyframe, int) else repr(keyframe)


def set_initial_pose(model, data, keyframe=None, initial_positions=None):
    """Put `keyframe` (a name, or an id) and then `initial_positions` ({joint: rad or m}) into data.qpos
    (and the keyframe's qvel, act, ctrl, mocap), then move each hinge or slide joint outside
    its range to the range's nearest end (`into_ranges`: a URDF's zero pose may lie outside
    a knee's range, and a servo holding it there fights the limit for ever). Returns what
    `into_ranges` moved; raises ValueError naming what is unknown."""
    if keyframe is not None and keyframe != '':
        key = (keyframe if isinstance(keyframe, int)
               else mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, keyframe))
        if key < 0:
            names = [model.key(k).name for k in range(model.nkey)]
            raise ValueError(f'keyframe {keyframe!r} is not in the model (keyframes: '
                             f'{", ".join(names) or "none"})')
        mujoco.mj_resetDataKeyframe(model, data, key)
    for joint, value in (initial_positions or {}).items():
        try:
            j = model.joint(joint).id
        except KeyError:
            raise ValueError(f'initial position for {joint!r}: no such joint') from None
        if j not in movable_joints(model):
            raise ValueError(f'initial position for {joint!r}: not a hinge or slide joint')
        data.qpos[model.jnt_qposadr[j]] = value
    return into_ranges(model, data)


def into_ranges(model, data):
    """Move each limited hinge or slide joint whose data.qpos lies outside its range to the
    range's nearest end. Returns [(joint name, position it had, range low, range high)]
    (rad or m) of those moved."""
    moved = []
    for j in movable_joints(model):
        if not model.jnt_limited[j]:
            continue
        low, high = model.jnt_range[j]
        adr = model.jnt_qposadr[j]
        if not low <= data.qpos[adr] <= high:
            moved.append((model.joint(j).name, float(data.qpos[adr]), float(low), float(high)))
            data.qpos[adr] = min(max(data.qpos[adr], low), high)
    return moved


def surface_gradient(height, box, samples=ALIGN_SAMPLES):
    """(dz/dx, dz/dy) of the least-squares plane of the surface `height(x, y)` (m, world;
    arrays in and out) over the horizontal box (x0, x1, y0, y1) (m), sampled on a lattice of
    `samples` x `samples` nodes; exactly (0, 0) over a level surface."""
    x0, x1, y0, y1 = box
    x, y = np.meshgrid(np.linspace(x0, x1, samples), np.linspace(y0, y1, samples))
    z = np.asarray(height(x.ravel(), y.ravel()), dtype=float)
    if np.all(z == z[0]):
        return 0.0, 0.0
    x, y = x.ravel() - x.mean(), y.ravel() - y.mean()
    fit, *_ = np.linalg.lstsq(np.column_stack([x, y, np.ones_like(x)]), z, rcond=None)
    return float(fit[0]), float(fit[1])


def align_to(model, data, base, bodies, height):
    """Turn the free root of body `base`, at rest, by the smallest rotation that takes world
    z to the normal of the surface's least-squares plane under the geoms of `bodies` (ids;
    `surface_gradient` over the box that holds their bounding boxes), about the box's centre
    at its lowest point (so those geoms stay over the ground the plane was fitted to), so
    that a robot set down on a slope stands on it as it would on level sand. `height(x, y)`:
    the surface height (m, world). Returns the angle turned (rad; 0 where the surface under
    the bodies is level, its gradient below LEVEL_GRADIENT, and the pose is then untouched).
    Raises ValueError without a free root."""
    joint = free_root_joint(model, base)
    if joint is None:
        raise ValueError('spawn needs a floating base (a free joint on the root body)')
    mujoco.mj_kinematics(model, data)
    geoms = [geom for body in bodies for geom in body_geoms(model, body)]
    boxes = np.array([geom_footprint(model, data, geom) for geom in geoms])
    box = (boxes[:, 0].min(), boxes[:, 1].max(), boxes[:, 2].min(), boxes[:, 3].max())
    gx, gy = surface_gradient(height, box)
    if np.hypot(gx, gy) < LEVEL_GRADIENT:
        return 0.0
    axis = np.array([gy, -gx, 0.0])  # z x n for n ~ (-gx, -gy, 1)
    angle = float(np.arctan(np.hypot(gx, gy)))
    turn, orientation, rotation = np.empty(4), np.empty(4), np.empty(9)
    mujoco.mju_axisAngle2Quat(turn, axis / np.linalg.norm(axis), angle)
    mujoco.mju_quat2Mat(rotation, turn)
    pivot = np.array([0.5 * (box[0] + box[1]), 0.5 * (box[2] + box[3]),
                      min(geom_lowest_z(model, data, geom) for geom in geoms)])
    adr = model.jnt_qposadr[joint]
    data.qpos[adr:adr + 3] = pivot + rotation.reshape(3, 3) @ (data.qpos[adr:adr + 3] - pivot)
    mujoco.mju_mulQuat(orientation, turn, data.qpos[adr + 3:adr + 7])
    data.qpos[adr + 3:adr + 7] = orientation / np.linalg.norm(orientation)
    data.qvel[model.jnt_dofadr[joint]:model.jnt_dofadr[joint] + 6] = 0.0
    mujoco.mj_kinematics(model, data)
    return angle


def lift_to(model, data, base, bodies, clearance, ground):
    """Move the free root of body `base` vertically, at rest, so that the geoms of `bodies`
    (ids; the geoms that carry their plates, `sand.geoms.body_geoms`) clear the sand surface by
    `clearance` m: the lowest point of each one's bounding box at least `clearance` above
    `ground(x0, x1, y0, y1)`, the surface's highest point over the box's horizontal extent
    (m; `Surface.highest`), and one of them exactly. Raises ValueError without a free root."""
    joint = free_root_joint(model, base)
    if joint is None:
        raise ValueError('spawn needs a floating base (a free joint on the root body)')
    mujoco.mj_kinematics(model, data)
    lift = -float('inf')
    for body in bodies:
        for geom in body_geoms(model, body):
            top = ground(*geom_footprint(model, data, geom))
            lift = max(lift, (top + clearance) - geom_lowest_z(model, data, geom))
    data.qpos[model.jnt_qposadr[joint] + 2] += lift
    data.qvel[model.jnt_dofadr[joint]:model.jnt_dofadr[joint] + 6] = 0.0
