"""What happened to the robot in a run, said plainly: whether it fell, how deep any of its
bodies went into the sand, and how often the implicit solve did not settle.

`OutcomeWatch` looks, at a modest rate of sim time (the Simulation's OUTCOME_RATE, 25 Hz), at

- the base's tilt: the angle (deg) between its up axis (body z) now and at the (re)start,
  after spawn rest settled it; the robot fell once it exceeds TILT_LIMIT_DEG (a quadruped on
  its side, a humanoid on its back; standing and walking robots stay well within it);
- the lowest point of every collision geom of every moving body (exact: for a mesh its
  lowest vertex, of the convex hull MuJoCo collides where it made one), against the sand
  surface under that point: the deepest one (body, depth
  m, time s, whether the body carries plates) and the deepest of the bodies without plates
  (`rft.other_bodies_density_per_mm2: null` allows them);

numpy over the geoms near the surface (their bounding spheres reach it), a few tens of
microseconds a look. `result` adds the share of steps
the implicit solve did not settle and says it all in words (`words`).

The summary's `outcome` (summary.json, /diagnostics):
  fell                        the base turned beyond tilt_limit_deg at some point;
  fell_at_s                   sim time of the first look that saw it (null: it did not fall);
  tilt_limit_deg              TILT_LIMIT_DEG;
  max_tilt_deg, final_tilt_deg
                              the base's largest tilt, and its tilt at the end;
  deepest                     {body, sinkage_m, time_s, has_plates}: the deepest point below
                              the sand surface of any collision geom (null: no geom ever
                              went below it);
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
  max_uncovered_sinkage_m deepest point below the surface of a body without plates
                              (null: every collision body carries plates);
  words                       all that in a line: "fell at t = 0.80 s: base turned 95 deg;
                              lying on the sand"; "no body has reached the sand" where no
                              geom went below the surface.
"""
import math

import mujoco
import numpy as np

from ..sand.geoms import is_collision_geom, mesh_vertices

#: deg: the robot fell once its base has turned this far from how it started.
TILT_LIMIT_DEG = 45.0
#: m: a point this far below the surface is reported in the words (a foot sinking under its
#: robot's weight stays well within it on zeta 3.75 N/cm^3 sand); a fallen robot whose
#: lowest point ends within it lies on the sand.
DEEP_M = 0.05
#: The share of unsettled implicit steps above which the words say it.
UNSETTLED_SAID = 0.01

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
    `model`; `plated`: ids of the bodies that carry plates."""

    def __init__(self, model, base, plated, tilt_limit_deg=TILT_LIMIT_DEG):
        self._model, self._base = model, int(base)
        self.tilt_limit_deg = float(tilt_limit_deg)
        geoms = [g for g in range(model.ngeom) if model.body_weldid[model.geom_bodyid[g]] != 0
                 and is_collision_geom(model, g)]
        self._lowest = LowestPoints(model, geoms)
        plated = set(int(b) for b in plated)
        self._bodies = model.geom_bodyid[self._lowest.geoms]
        self._has_plates = np.array([int(b) in plated for b in self._bodies], dtype=bool)
        self.start(None, 0.0)

    def start(self, data, time):
        """From a (re)start at sim time `time` (s): the base's up axis now is upright."""
        self._up = None if data is None else data.xmat[self._base].reshape(3, 3)[:, 2].tolist()
        self.fell_at = None
        self.max_tilt = 0.0
        self.deepest = None  # (depth m, geom index, time s)
        self.uncovered = 0.0 if (~self._has_plates).any() else None

    def tilt(self, data):
        """deg between the base's up axis now and at the start."""
        if self._up is None:
            return 0.0
        x, y, z = self._up
        rotation = data.xmat[self._base]  # (row-major: its up axis is column 2)
        cosine = rotation[2] * x + rotation[5] * y + rotation[8] * z
        return math.degrees(math.acos(min(1.0, max(-1.0, cosine)))) if cosine == cosine \
            else math.nan

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

    def observe(self, data, surface, time):
        """One look at `data` at sim time `time` (s)."""
        tilt = self.tilt(data)
        if not np.isfinite(tilt):  # (a diverged state: nothing to learn from it)
            return
        self.max_tilt = max(self.max_tilt, tilt)
        if self.fell_at is None and tilt > self.tilt_limit_deg:
            self.fell_at = time
        near = self._near(data, surface) if self._lowest.geoms.size else ()
        if not len(near):
            return
        depth = self.depths(data, surface, near)
        i = int(np.argmax(depth))
        if depth[i] > 0.0 and (self.deepest is None or depth[i] > self.deepest[0]):
            self.deepest = (float(depth[i]), int(near[i]), time)
        bare = ~self._has_plates[near]
        if self.uncovered is not None and bare.any():
            self.uncovered = max(self.uncovered, float(depth[bare].max()))

    def _body(self, g):
        return self._model.body(int(self._bodies[g])).name

    def result(self, data, surface, steps, unsettled, handed_back=0):
        """The `outcome` mapping (module docstring) of the run so far, `data` its final state;
        steps: the run's steps; unsettled: how many of them the implicit solve did not
        settle; handed_back: in how many it handed MuJoCo's constraint rows back."""
        final = self.tilt(data)
        deepest = None
        if self.deepest is not None:
            depth, g, time = self.deepest
            deepest = {'body': self._body(g), 'sinkage_m': depth, 'time_s': time,
                       'has_plates': bool(self._has_plates[g])}
        outcome = {
            'fell': self.fell_at is not None, 'fell_at_s': self.fell_at,
            'tilt_limit_deg': self.tilt_limit_deg, 'max_tilt_deg': self.max_tilt,
            'final_tilt_deg': final, 'deepest': deepest,
            'unsettled_step_share': unsettled / steps if steps else 0.0,
            'rows_handed_back_step_share': handed_back / steps if steps else 0.0,
            'max_uncovered_sinkage_m': self.uncovered,
        }
        now = self.depths(data, surface) if self._lowest.geoms.size else np.zeros(1)
        lowest = int(np.argmax(now))
        outcome['words'] = words(outcome, float(now[lowest]),
                                 self._body(lowest) if self._lowest.geoms.size else '')
        return outcome


def words(outcome, final_depth, final_body):
    """`outcome` in a line; final_depth (m): how far below the surface the lowest point of
    final_body lies at the end."""
    if outcome['fell']:
        parts = [f"fell at t = {outcome['fell_at_s']:.2f} s: base turned "
                 f"{outcome['max_tilt_deg']:.0f} deg"]
        parts.append('lying on the sand' if final_depth <= DEEP_M else
                     f'{final_body} ends {final_depth * 100:.3g} cm below the sand surface')
    else:
        parts = [f"upright: base turned at most {outcome['max_tilt_deg']:.0f} deg"]
    deepest = outcome['deepest']
    if deepest is None:  # (a short run, a robot held above the sand: its metrics say no contact)
        parts.append('no body has reached the sand')
    elif deepest['sinkage_m'] > DEEP_M:
        parts.append(f"deepest: {deepest['body']} {deepest['sinkage_m'] * 100:.3g} cm below the "
                     f"surface at t = {deepest['time_s']:.2f} s"
                     + ('' if deepest['has_plates'] else ' (no plates: it passed through)'))
    uncovered = outcome['max_uncovered_sinkage_m']
    if uncovered is not None and uncovered > DEEP_M and (deepest or {}).get('has_plates'):
        parts.append(f'a body without plates reached {uncovered * 100:.3g} cm into the sand')
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
