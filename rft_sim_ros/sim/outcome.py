"""What happened to the robot in a run, said plainly: whether it fell, collapsed or sank, how
deep any of its bodies went into the sand, and how often the implicit solve did not settle.

`OutcomeWatch` looks, at a modest rate of sim time (the Simulation's OUTCOME_RATE, 25 Hz), at

- the base's tilt: the angle (deg) between its up axis (body z) now and as the robot was set
  down (`set_down`: its spawn's pose, before spawn rest settled it; on a slope, turned to
  it); the robot fell once it exceeds TILT_LIMIT_DEG (a quadruped on its side, a humanoid on
  its back; standing and walking robots stay well within it), an articulated robot only
  where it was set down upright and its up angle (below) exceeds it too (one set down on
  its back that rolls upright has not fallen: it was upside down);
- an articulated robot's up angle: the angle (deg) between its base's z axis and the world's
  up (against gravity). A standing robot's base frame has z up (REP 103: x forward, y left, z
  up), so the robot is upside down once that exceeds UPSIDE_DOWN_DEG (its z axis within
  TILT_LIMIT_DEG of straight down: a quadruped on its back; a humanoid lying flat, about 90
  deg, has fallen), also where it was set down so (a robot set down on its back has not
  turned from there, yet lies on its back); one set down tilted more than TILT_LIMIT_DEG is
  not called upright;
- an articulated robot (a free root with joints): its stance height, the height of its
  centre of mass (its root's subtree) above the lowest point of its sand bodies, against
  that height as set down; it collapsed once that is below COLLAPSE_SHARE of it (legs given
  way, belly on the sand) without turning over, however deep its feet sank; and its base's
  lowest point (its collision geoms', else its origin) against the sand surface: it sank
  once that is more than DEEP_M into the sand (belly in very soft sand, a robot too heavy
  for it);
- the lowest point of every collision geom of every moving body (exact: for a mesh its
  lowest vertex, of the convex hull MuJoCo collides where it made one), and the origin of
  every moving body welded to no collision geom (the model gave it none: it passes through
  the sand), against the sand surface under that point: the deepest one (body, depth
  m, time s, whether the body carries plates) and the deepest of the bodies without plates
  (`rft.other_bodies_density_per_mm2: null` allows them);

numpy over the geoms near the surface (their bounding spheres reach it), a few tens of
microseconds a look. `result` adds the share of steps
the implicit solve did not settle and says it all in words (`words`).

The summary's `outcome` (summary.json, /diagnostics):
  fell                        the base turned beyond tilt_limit_deg at some point;
  fell_at_s                   sim time of the first look that saw it (null: it did not fall);
  upside_down, upside_down_at_s
                              an articulated robot's base z axis pointed more than
                              UPSIDE_DOWN_DEG from up (on its back, or set down so), and the
                              first look that saw it (false, null: it did not, or not watched:
                              a robot that is one rigid body or fixed to the world);
  up_angle_set_down_deg, max_up_angle_deg, final_up_angle_deg
                              the base z axis' angle from up as set down, its largest and at
                              the end (deg; null: not watched);
  tilt_limit_deg              TILT_LIMIT_DEG;
  max_tilt_deg, final_tilt_deg
                              the base's largest tilt, and its tilt at the end;
  collapsed, collapsed_at_s   the stance height came down below collapse_share of its
                              height as set down, and the first look that saw it (false,
                              null: it did not; so where it is not watched: a robot that is
                              one rigid body or fixed to the world, one without sand bodies
                              with collision geoms in its own tree, or one set down with its
                              centre of mass within DEEP_M of its sand bodies);
  collapse_share              COLLAPSE_SHARE;
  stance_height_set_down_m, min_stance_height_m
                              the stance height (m) as set down and its lowest (null: not
                              watched);
  sank, sank_at_s             the base went more than DEEP_M into the sand, and the first
                              look that saw it (false, null: it did not, or not watched);
  max_base_depth_m            how far the base's lowest point went below the sand surface
                              (m; negative: it stayed above; null: not watched);
  final_base_speed_mps        the speed of the base's origin at the end (m/s; a fallen
                              robot faster than LYING_SPEED is still moving, not lying);
  deepest                     {body, sinkage_m, time_s, has_plates}: the deepest point below
                              the sand surface of any collision geom or bare body origin
                              (null: none ever went below it). Exact geometry, so it may
                              exceed generic_metrics' max_sinkage_m_<body>, which is over
                              the body's plates (sim/metrics.py);
  unsettled_step_share        steps in which the implicit solve froze a plate or its sets
                              did not settle, over the run's steps (0 without sand contact).
                              A plate is frozen where its leading/trailing set would cycle
                              within a step: at rest, where its direction of motion is
                              noise (a fallen humanoid lying still: most steps), and on a
                              foot turning slowly through the sand (the walking hexapod's
                              stance feet: 11 % of steps), where RFT's lift makes the law
                              non-monotone. It then takes the linear
                              response through its speed (implicit_solve._implicit_step): at
                              rest the resting law, moving a damper that brakes it;
  rows_handed_back_step_share steps whose constraint rows (contacts, limits, closed loops)
                              MuJoCo's own solver took because the implicit solve could
                              not settle them, over the run's steps;
  max_uncovered_sinkage_m deepest point below the surface of a body without plates, bare
                              body origins included (null: every watched body carries
                              plates);
  joint_past_limit            {joint, past_limit_rad (or _m), limit_rad (or _m), time_s}: the
                              joint pushed farthest past its range, beyond 5 deg (5 mm):
                              MuJoCo's soft limits yielding to an effort, a model's own
                              servo, a load (sim/joint_limits.py; null: none);
  words                       all that in a line: "fell at t = 0.80 s: base turned 95 deg;
                              lying on the sand"; "collapsed at t = 0.40 s: its centre of
                              mass came down to 15 cm above its sand bodies, from 54 cm as
                              set down; base turned at most 1 deg"; "sank at t = 0.36 s: its
                              base went 94 cm into the sand; ..."; "no body went below the
                              sand surface" where none did. A run that stopped (diverged, its
                              scenario raised) says so first: "until the run stopped at t =
                              0.0040 s: ...", of the looks before.
"""
import math

import mujoco
import numpy as np

from ..sand.geoms import bodies_without_collision, mesh_vertices, moving_collision_geoms
from . import joint_limits

#: deg: the robot fell once its base has turned this far from how it started.
TILT_LIMIT_DEG = 45.0
#: deg: an articulated robot is upside down once its base's z axis points this far from up:
#: within TILT_LIMIT_DEG of straight down.
UPSIDE_DOWN_DEG = 180.0 - TILT_LIMIT_DEG
#: m: a point this far below the surface is reported in the words (a foot sinking under its
#: robot's weight stays well within it on zeta 3.75 N/cm^3 sand); a fallen robot whose
#: lowest point ends within it lies on the sand.
DEEP_M = 0.05
#: The share of unsettled implicit steps above which the words say it.
UNSETTLED_SAID = 0.01
#: The robot collapsed once its centre of mass came down below this share of its height
#: above the sand as it was set down: folded onto its belly, its legs given way, sunk into
#: very soft sand (a walking or crouching robot stays well above it).
COLLAPSE_SHARE = 0.5
#: m/s: a fallen robot whose base moves faster than this at the end is still moving
#: (sliding, tumbling), not lying on the sand.
LYING_SPEED = 0.1

_SPHERE, _CAPSULE, _ELLIPSOID, _CYLINDER, _BOX, _MESH = (
    int(mujoco.mjtGeom.mjGEOM_SPHERE), int(mujoco.mjtGeom.mjGEOM_CAPSULE),
    int(mujoco.mjtGeom.mjGEOM_ELLIPSOID), int(mujoco.mjtGeom.mjGEOM_CYLINDER),
    int(mujoco.mjtGeom.mjGEOM_BOX), int(mujoco.mjtGeom.mjGEOM_MESH))


class LowestPoints:
    """The lowest points (world, m) of a set of geoms of a model: each primitive's support
    point in the direction of world -z, each mesh's lowest vertex (`mesh_vertices`; other
    types: their bounding box's lowest corner, at or below them). A primitive's support
    point is a sum of terms whose coefficients are its sizes (zero where a term is not its
    type's), so that all of them take the same few array operations."""

    def __init__(self, model, geoms):
        self.geoms = np.asarray(geoms, dtype=int)
        kind = model.geom_type[self.geoms]
        size = model.geom_size[self.geoms]
        #: m: each geom's bounding sphere about its frame's origin (MuJoCo's geom_rbound)
        self.reach = model.geom_rbound[self.geoms]
        aabb = model.geom_aabb[self.geoms]
        is_ = {t: (kind == t)[:, None] for t in (_SPHERE, _CAPSULE, _CYLINDER, _ELLIPSOID,
                                                _BOX, _MESH)}
        other = ~(is_[_SPHERE] | is_[_CAPSULE] | is_[_CYLINDER] | is_[_ELLIPSOID]
                  | is_[_MESH])  # boxes and other types: a box, the bounding box
        # s = ball * down + ends * sign(down_z) e_z + rim * (down_x, down_y, 0) / |...|
        #     + shell^2 * down / |shell * down| + centre + half * sign(down)
        self._ball = np.where(is_[_SPHERE] | is_[_CAPSULE], size[:, :1], 0.0)
        self._ends = np.where(is_[_CAPSULE] | is_[_CYLINDER], size[:, 1:2], 0.0)[:, 0]
        self._rim = np.where(is_[_CYLINDER], size[:, :1], 0.0)
        self._shell = np.where(is_[_ELLIPSOID], size, 0.0)
        self._ellipsoid = is_[_ELLIPSOID][:, 0]
        self._half = np.where(other, np.where(is_[_BOX], size, aabb[:, 3:]), 0.0)
        self._centre = np.where(other & ~is_[_BOX], aabb[:, :3], 0.0)
        self._mesh = is_[_MESH][:, 0]
        self._vertices = {i: mesh_vertices(model, g) for i, g in enumerate(self.geoms)
                          if kind[i] == _MESH}

    def __call__(self, data, which=None):
        """(K, 3) world positions (m) of the lowest points, in `data`'s pose, of the geoms
        at indices `which` (into `geoms`; None: all)."""
        which = np.arange(len(self.geoms)) if which is None else which
        rotation = data.geom_xmat[self.geoms[which]].reshape(-1, 3, 3)
        down = -rotation[:, 2, :]  # world -z in each geom's frame
        support = self._ball[which] * down + self._centre[which] + np.copysign(
            self._half[which], down)
        support[:, 2] += np.copysign(self._ends[which], down[:, 2])
        flat = np.hypot(down[:, 0], down[:, 1])[:, None]
        support[:, :2] += self._rim[which] * down[:, :2] / np.maximum(flat, 1e-12)
        ellipsoids = np.flatnonzero(self._ellipsoid[which])
        if ellipsoids.size:
            shell = self._shell[which[ellipsoids]]
            stretched = shell ** 2 * down[ellipsoids]
            support[ellipsoids] += stretched / np.sqrt(
                np.einsum('gi,gi->g', stretched, down[ellipsoids]))[:, None]
        for j in np.flatnonzero(self._mesh[which]).tolist():
            vertices = self._vertices[int(which[j])]
            support[j] = vertices[np.argmax(vertices @ down[j])]
        return data.geom_xpos[self.geoms[which]] + np.einsum('gij,gj->gi', rotation, support)


class OutcomeWatch:
    """Tracks a run's outcome (module docstring) for the robot whose base is body `base` of
    `model`; `plated`: ids of the bodies that carry plates, `feet` those of its sand
    bodies."""

    def __init__(self, model, base, plated, feet=(), tilt_limit_deg=TILT_LIMIT_DEG):
        self._model, self._base = model, int(base)
        self._root = int(model.body_rootid[base])
        self.tilt_limit_deg = float(tilt_limit_deg)
        self._lowest = LowestPoints(model, moving_collision_geoms(model))
        self._bare = np.array(bodies_without_collision(model), dtype=int)  # (by their origins)
        plated, feet = set(int(b) for b in plated), set(int(b) for b in feet)
        self._bodies = np.concatenate([model.geom_bodyid[self._lowest.geoms], self._bare])
        self._has_plates = np.array([int(b) in plated for b in self._bodies], dtype=bool)
        self._feet = np.array([i for i, g in enumerate(self._lowest.geoms)  # (its own tree's)
                               if int(model.geom_bodyid[g]) in feet
                               and model.body_rootid[model.geom_bodyid[g]] == self._root],
                              dtype=int)
        self._watch_up = articulated(model, self._root)
        self._watch_body = self._watch_up and self._feet.size > 0
        gravity = np.asarray(model.opt.gravity, dtype=float)
        norm = float(np.linalg.norm(gravity))
        self._world_up = (-gravity / norm if norm > 0.0 else np.array([0.0, 0.0, 1.0])).tolist()
        welded = model.body_weldid[base]  # the base: its geoms', else its origin's depth
        self._base_geoms = np.array([i for i, g in enumerate(self._lowest.geoms)
                                     if model.body_weldid[model.geom_bodyid[g]] == welded],
                                    dtype=int)
        self._base_origin = int(welded)
        self._up = self._stance_set_down = self.up_angle_set_down = None
        self._upright_set_down = True
        self._limits = joint_limits.LimitWatch(model)
        self.start()

    def set_down(self, data):
        """The robot as it was set down (`data`, before it settled): its base's up axis now
        is upright, and (`_watch_body`: an articulated robot on a free root) its stance
        height now is its height as set down (`stance_height`; not watched where it is
        within DEEP_M: set down lying)."""
        self._up = data.xmat[self._base].reshape(3, 3)[:, 2].tolist()
        self.up_angle_set_down = self.up_angle(data) if self._watch_up else None
        # (one set down tilted or upside down can turn over or upright, not fall)
        self._upright_set_down = (self.up_angle_set_down is None
                                  or self.up_angle_set_down <= self.tilt_limit_deg)
        stance = self.stance_height(data) if self._watch_body else None
        self._stance_set_down = stance if stance is not None and stance > DEEP_M else None

    def start(self):
        """From a (re)start: nothing seen yet."""
        self.fell_at = self.collapsed_at = self.sank_at = self.upside_down_at = None
        self.max_tilt = 0.0
        self.max_up_angle = -math.inf
        self.min_stance, self.base_depth = math.inf, -math.inf
        self.deepest = None  # (depth m, index into the watched bodies, time s)
        self.uncovered = 0.0 if (~self._has_plates).any() else None
        self._limits.start()

    @property
    def down(self):
        """Whether the robot has fallen, turned upside down, collapsed or sunk since the
        (re)start."""
        return any(at is not None for at in (self.fell_at, self.upside_down_at,
                                             self.collapsed_at, self.sank_at))

    def tilt(self, data):
        """deg between the base's up axis now and as it was set down."""
        return 0.0 if self._up is None else self._angle_to(data, self._up)

    def up_angle(self, data):
        """deg between the base's z axis now and the world's up (against gravity)."""
        return self._angle_to(data, self._world_up)

    def _angle_to(self, data, direction):
        """deg between the base's z axis now and `direction` (a unit vector, world)."""
        x, y, z = direction
        rotation = data.xmat[self._base]  # (row-major: its z axis is column 2)
        cosine = rotation[2] * x + rotation[5] * y + rotation[8] * z
        return math.degrees(math.acos(min(1.0, max(-1.0, cosine)))) if cosine == cosine \
            else math.nan

    def stance_height(self, data):
        """m: the height of the robot's centre of mass (its root's subtree) above the lowest
        point of its sand bodies' geoms: what its legs hold up, however deep its feet sank."""
        feet = self._lowest(data, self._feet)
        return float(data.subtree_com[self._root][2] - feet[:, 2].min())

    def base_depth_now(self, data, surface):
        """m: how far the base's lowest point lies below the sand surface (negative: above):
        that of its collision geoms (those welded to it too), else of its origin."""
        if self._base_geoms.size:
            return float(self.depths(data, surface, self._base_geoms).max())
        x, y, z = data.xpos[self._base_origin]
        return float(surface.height(np.array([x]), np.array([y]))[0] - z)

    def _judge(self, data, surface):
        """(stance height m, base depth m, collapsed, sank) now, of a watched robot
        (`set_down`): collapsed, its stance below COLLAPSE_SHARE of its height as set down;
        sank, its base more than DEEP_M into the sand."""
        stance, depth = self.stance_height(data), self.base_depth_now(data, surface)
        return (stance, depth, stance < COLLAPSE_SHARE * self._stance_set_down,
                depth > DEEP_M)

    def problem(self, data, surface):
        """'collapsed: ...' or 'sank: ...' where the robot (a watched one: `set_down`) is
        now collapsed or sunk (`_judge`); else None."""
        if self._stance_set_down is None:
            return None
        stance, depth, collapsed, sank = self._judge(data, surface)
        if collapsed:
            return (f'collapsed: its centre of mass {length(stance)} above its sand '
                    f'bodies, from {length(self._stance_set_down)} as set down')
        return f'sank: its base {length(depth)} into the sand' if sank else None

    def depths(self, data, surface, which=None):
        """(K,) m: how far the lowest point of each collision geom (at indices `which`;
        None: all) lies below `surface` (a sand.surface.Surface) under it (negative:
        above)."""
        points = self._lowest(data, which)
        return surface.height(points[:, 0], points[:, 1]) - points[:, 2]

    def _near(self, data, surface):
        """Indices of the geoms whose bounding sphere reaches below the surface under its
        centre raised by its radius (so on any slope up to 45 deg): the only ones that
        can be in the sand, found in a few array operations."""
        centres = data.geom_xpos[self._lowest.geoms]
        reach = self._lowest.reach
        ground = surface.height(centres[:, 0], centres[:, 1])
        return np.flatnonzero(centres[:, 2] - reach < ground + reach)

    def _watched(self, data, surface, near=None):
        """(indices into the watched bodies' list, depths m): the geoms at indices `near`
        (None: all) and the bare bodies' origins, how far each lies below the surface."""
        which = (np.arange(len(self._lowest.geoms)) if near is None
                 else np.asarray(near, dtype=int))
        depth = self.depths(data, surface, which) if len(which) else np.zeros(0)
        if self._bare.size:
            origins = data.xpos[self._bare]
            which = np.concatenate([which, len(self._lowest.geoms) + np.arange(self._bare.size)])
            depth = np.concatenate([depth, surface.height(origins[:, 0], origins[:, 1])
                                    - origins[:, 2]])
        return which, depth

    def observe(self, data, surface, time):
        """One look at `data` at sim time `time` (s)."""
        tilt = self.tilt(data)
        if not np.isfinite(tilt):  # (a diverged state: nothing to learn from it)
            return
        self.max_tilt = max(self.max_tilt, tilt)
        up = self.up_angle(data) if self._watch_up else None
        if up is not None:
            self.max_up_angle = max(self.max_up_angle, up)
            if self.upside_down_at is None and up > UPSIDE_DOWN_DEG:
                self.upside_down_at = time
        if self.fell_at is None and tilt > self.tilt_limit_deg and self._upright_set_down and (
                up is None or up > self.tilt_limit_deg):
            self.fell_at = time
        self._limits.observe(data, time)
        if self._stance_set_down is not None:
            stance, depth, collapsed, sank = self._judge(data, surface)
            self.min_stance = min(self.min_stance, stance)
            self.base_depth = max(self.base_depth, depth)
            if self.collapsed_at is None and collapsed:
                self.collapsed_at = time
            if self.sank_at is None and sank:
                self.sank_at = time
        near = self._near(data, surface) if self._lowest.geoms.size else ()
        which, depth = self._watched(data, surface, near)
        if not len(which):
            return
        i = int(np.argmax(depth))
        if depth[i] > 0.0 and (self.deepest is None or depth[i] > self.deepest[0]):
            self.deepest = (float(depth[i]), int(which[i]), time)
        bare = ~self._has_plates[which]
        if self.uncovered is not None and bare.any():
            self.uncovered = max(self.uncovered, float(depth[bare].max()))

    def _body(self, i):
        return self._model.body(int(self._bodies[i])).name

    def _base_speed(self, data):
        """m/s: the speed of the base's origin."""
        velocity = np.empty(6)
        mujoco.mj_objectVelocity(self._model, data, mujoco.mjtObj.mjOBJ_XBODY, self._base,
                                 velocity, 0)
        return float(np.linalg.norm(velocity[3:]))

    def result(self, data, surface, steps, unsettled, handed_back=0, stopped_at=None):
        """The `outcome` mapping (module docstring) of the run so far, `data` its final state;
        steps: the run's steps; unsettled: how many of them the implicit solve did not
        settle; handed_back: in how many it handed MuJoCo's constraint rows back;
        stopped_at: sim time (s) the run stopped at (diverged; None: it did not)."""
        final = self.tilt(data)
        deepest = None
        if self.deepest is not None:
            depth, i, time = self.deepest
            deepest = {'body': self._body(i), 'sinkage_m': depth, 'time_s': time,
                       'has_plates': bool(self._has_plates[i])}
        def seen(value, watched=self._stance_set_down is not None):  # (else null)
            return value if watched and math.isfinite(value) else None
        outcome = {
            'fell': self.fell_at is not None, 'fell_at_s': self.fell_at,
            'tilt_limit_deg': self.tilt_limit_deg, 'max_tilt_deg': self.max_tilt,
            'final_tilt_deg': final,
            'upside_down': self.upside_down_at is not None,
            'upside_down_at_s': self.upside_down_at,
            'up_angle_set_down_deg': self.up_angle_set_down,
            'max_up_angle_deg': seen(self.max_up_angle, self._watch_up),
            'final_up_angle_deg': seen(self.up_angle(data), self._watch_up),
            'collapsed': self.collapsed_at is not None, 'collapsed_at_s': self.collapsed_at,
            'collapse_share': COLLAPSE_SHARE,
            'stance_height_set_down_m': self._stance_set_down,
            'min_stance_height_m': seen(self.min_stance),
            'sank': self.sank_at is not None, 'sank_at_s': self.sank_at,
            'max_base_depth_m': seen(self.base_depth),
            'final_base_speed_mps': self._base_speed(data),
            'deepest': deepest,
            'unsettled_step_share': unsettled / steps if steps else 0.0,
            'rows_handed_back_step_share': handed_back / steps if steps else 0.0,
            'max_uncovered_sinkage_m': self.uncovered,
            'joint_past_limit': self._limits.result(),
        }
        which, now = self._watched(data, surface)
        final_depth, final_body = -math.inf, ''  # (nothing watched: nothing below)
        if len(now):
            lowest = int(np.argmax(now))
            final_depth, final_body = float(now[lowest]), self._body(which[lowest])
        outcome['words'] = words(outcome, final_depth, final_body)
        if stopped_at is not None:
            outcome['words'] = f'until the run stopped at t = {stopped_at:.4f} s: ' \
                + outcome['words']
        return outcome


def articulated(model, root):
    """Whether the tree of root body `root` hangs on a free joint and has joints of its own
    (a robot that can fold, not one rigid body or one fixed to the world)."""
    joints = [j for j in range(model.njnt) if model.body_rootid[model.jnt_bodyid[j]] == root]
    free = [j for j in joints if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
    return bool(free) and len(joints) > len(free)


def length(metres):
    """A length in words: in cm below a metre ('14.7 cm'), else in m ('11.9 m')."""
    return f'{metres * 100:.3g} cm' if abs(metres) < 1.0 else f'{metres:.3g} m'


def words(outcome, final_depth, final_body):
    """`outcome` in a line; final_depth (m): how far below the surface the lowest point of
    final_body lies at the end."""
    below = f'{final_body} ends {length(final_depth)} below the sand surface'
    turned = f"base turned at most {outcome['max_tilt_deg']:.0f} deg"
    over = outcome['fell'] or outcome.get('upside_down')
    if over:
        speed = outcome.get('final_base_speed_mps', 0.0)
        parts = [f"fell at t = {outcome['fell_at_s']:.2f} s: base turned "
                 f"{outcome['max_tilt_deg']:.0f} deg"] if outcome['fell'] else []
        if outcome.get('upside_down'):
            parts.append(_upside_down(outcome))
        final_up = outcome.get('final_up_angle_deg')
        parts.append('upright again at the end'
                     if final_up is not None and final_up <= TILT_LIMIT_DEG else
                     below if final_depth > DEEP_M else
                     f'still moving at {speed:.2g} m/s at the end' if speed > LYING_SPEED else
                     'lying on the sand')
    elif outcome.get('collapsed'):
        parts = [f"collapsed at t = {outcome['collapsed_at_s']:.2f} s: its centre of mass "
                 f"came down to {length(outcome['min_stance_height_m'])} above its sand "
                 f"bodies, from {length(outcome['stance_height_set_down_m'])} as set "
                 f'down', turned]
    else:
        set_down = outcome.get('up_angle_set_down_deg')
        parts = [('' if outcome.get('sank') else
                  f'set down tilted {set_down:.0f} deg from up: '
                  if set_down is not None and set_down > TILT_LIMIT_DEG else 'upright: ')
                 + turned]
    if outcome.get('sank'):
        parts.insert(0, f"sank at t = {outcome['sank_at_s']:.2f} s: its base went "
                        f"{length(outcome['max_base_depth_m'])} into the sand")
    if not over and (outcome.get('collapsed') or outcome.get('sank')) \
            and final_depth > DEEP_M:
        parts.append(below)
    deepest = outcome['deepest']
    if deepest is None:  # (a short run, a robot held above the sand: its metrics say no contact)
        parts.append('no body went below the sand surface')
    elif deepest['sinkage_m'] > DEEP_M:
        parts.append(f"deepest: {deepest['body']} {length(deepest['sinkage_m'])} below the "
                     f"surface at t = {deepest['time_s']:.2f} s"
                     + ('' if deepest['has_plates'] else ' (no plates: it passed through)'))
    uncovered = outcome['max_uncovered_sinkage_m']
    if uncovered is not None and uncovered > DEEP_M and (deepest or {}).get('has_plates'):
        parts.append(f'a body without plates reached {length(uncovered)} into the sand')
    if outcome.get('joint_past_limit'):
        parts.append(joint_limits.words(outcome['joint_past_limit']))
    share = outcome['unsettled_step_share']
    if share > UNSETTLED_SAID:
        parts.append(f'in {share * 100:.0f} % of steps the implicit solve froze plates whose '
                     'leading/trailing sets cycled (at rest, or turning slowly in the sand): '
                     "they took a linear response through their speed, not RFT's switch")
    handed_back = outcome.get('rows_handed_back_step_share', 0.0)
    if handed_back > UNSETTLED_SAID:
        parts.append(f"in {handed_back * 100:.0f} % of steps MuJoCo's own solver took the "
                     'constraint rows (contacts, limits, loops) the implicit solve could not '
                     'settle')
    return '; '.join(parts)


def _upside_down(outcome):
    """The words for an upside-down robot (`outcome['upside_down']`)."""
    final = outcome['final_up_angle_deg']
    at_end = 'unknown' if final is None else f'{final:.0f} deg'  # (null: a diverged end)
    if outcome['up_angle_set_down_deg'] > UPSIDE_DOWN_DEG:
        return (f"set down upside down: its base's z axis {outcome['up_angle_set_down_deg']:.0f} "
                f'deg from up, {at_end} at the end')
    return (f"upside down at t = {outcome['upside_down_at_s']:.2f} s: its base's z axis "
            f'{at_end} from up at the end (at most {outcome["max_up_angle_deg"]:.0f} deg)')
