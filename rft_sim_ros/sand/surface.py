"""The sand's free surface: local height (and normal) at a world (x, y), for the kernels.

Every surface answers one question, `height(x, y)` (m, world z of the free surface above the
point), and hands the compiled kernels the same answer in a fixed form (`SurfaceData`): a
kind code plus a plane (height at the world origin and gradient) and a height grid.

- `Plane(height)`: horizontal plane (the default; the kernels keep their original path).
- `Slope(height, angle_deg, downhill_deg)`: inclined plane through (0, 0, height) that falls
  by tan(angle) per metre along the heading `downhill_deg` (degrees from +x towards +y).
- `HeightGrid(heights, size, center)`: a height field sampled on a regular grid of nodes
  (heights[iy, ix], m, world z; row 0 at the lowest y), spanning `size` = [x, y] m centred on
  `center`; bilinear between nodes, and outside the grid the edge values continue (or, as
  `within_plane` makes it, a plane around it).
  `from_file` reads a PNG (grey levels mapped onto a height range) or a .npy (heights in m);
  `from_mjcf_hfield` reads a MuJoCo model's own <hfield> geom.

Depth below a sloped surface is measured vertically, in world axes (see docs/terrain.md for
the literature behind this choice): depth = height(x, y) - z of the plate.

The grid carries a coarse "block maximum" and "block minimum" (the highest and lowest node
of each BLOCK x BLOCK tile) so that a kernel can tell in a few reads whether a bounding sphere
lies wholly above the sand, and whether the surface under it is level (block minimum ==
maximum: the bilinear height there is that level exactly, no look-up needed). On a rigid
grid the engine adds planes that bound the surface over tiles the size of its bodies
(`tile_planes`): a body on a smooth slope is bounded as on the analytic slope; and each
node's highest and lowest node over a window the size of its plate clusters
(`window_extremes`): a cluster's square is bounded by the nodes it reaches, in two reads.
"""
import hashlib
from collections import namedtuple
from pathlib import Path

import numpy as np

from .grid_files import file_format, grey_levels, read_npy
from .surface_codes import BLOCK, FLAT, GRID, SLOPE

#: What the kernels read: kind code; the plane's height at the world origin (m) and gradient
#: dh/dx, dh/dy; the grid (heights (ny, nx) m, origin = world (x, y) of node [0, 0], node
#: spacing (dx, dy) m) and its block maximum and minimum ((ceil((ny-1)/BLOCK)+1, ...) m). A
#: surface without a grid passes 2 x 2 placeholders.
SurfaceData = namedtuple('SurfaceData', ['kind', 'height', 'gradient', 'grid', 'origin',
                                         'spacing', 'block_max', 'block_min'])


def block_maximum(grid, block=BLOCK):
    """(by, bx) array: block [j, i] = max of the nodes [j*block .. (j+1)*block] x
    [i*block .. (i+1)*block] (inclusive, clipped to the grid), so every node n belongs to
    block n // block and the bilinear surface inside a cell never exceeds its blocks."""
    return _blocks(grid, block, np.max)


def block_minimum(grid, block=BLOCK):
    """As `block_maximum`, with each block's lowest node (the surface never goes below)."""
    return _blocks(grid, block, np.min)


def window_extremes(grid, span):
    """The highest and lowest node of every window of the grid: (high, low), each (ny, nx)
    (m), whose [j, i] holds the extremes of the nodes [j .. j + span_y] x [i .. i + span_x]
    (clipped to the grid), span = (span_x, span_y) nodes; so a square whose cells' nodes lie
    within span nodes of its first node, along each axis, is bounded by that node's entries
    (`surface_kernels.window_range`). By doubling: about log2(span) numpy passes per axis."""
    windows = []
    for reduce in (np.maximum, np.minimum):
        out = np.array(grid, float)
        for axis, length in ((1, span[0] + 1), (0, span[1] + 1)):
            out = np.moveaxis(out, axis, 0)  # (a view: the passes below work on axis 0)
            width = 1  # out[i] holds the extreme of nodes i .. i + width - 1 (clipped)
            while width < length:
                shift = min(width, length - width)  # up to doubling, at most to `length`
                reduce(out[:-shift], out[shift:], out=out[:-shift])
                width += shift
            out = np.moveaxis(out, 0, axis)
        windows.append(np.ascontiguousarray(out))
    return tuple(windows)


def window_span(radius, spacing):
    """(span_x, span_y) of the windows (`window_extremes`) that bound every square of
    half-side up to `radius` (m) on a grid of node spacing (dx, dy) (m): the nodes of the
    cells such a square touches lie at most ceil(2 radius / spacing) + 1 nodes on from its
    first, and one more allows for rounding."""
    return tuple(int(np.ceil(2 * radius / d)) + 2 for d in spacing)


def tile_planes(grid, origin, spacing, step):
    """Upper-bound planes of a grid over overlapping tiles, read by the gather kernels as
    one bound for a whole body (`surface_kernels.tile_plane`). Tile [tj, ti] covers the
    nodes [tj*step .. tj*step + 2*step] x [ti*step .. ti*step + 2*step] (clipped to the
    grid), so that a square of up to `step` node spacings a side lies in one. Returns
    (ntx * nty, 4), row tj * ntx + ti (ntx = (nx - 2) // step + 1): the least-squares plane
    z = a + gx x + gy y (world, m) of the tile's nodes, raised by their largest height above
    it, so that the bilinear surface over the tile never exceeds it (a bilinear function
    less a plane peaks at a node), as (a, gx, gy, usable). usable is 0 where that rise is
    more than a quarter of the tile's height range (a surface far from a plane there:
    ripples, steps), where the grid's blocks bound it better, and where the tile is level
    (its blocks give the level itself, read as a plane's)."""
    grid = np.asarray(grid, float)
    ny, nx = grid.shape
    nty, ntx = (ny - 2) // step + 1, (nx - 2) // step + 1
    out = np.zeros((nty * ntx, 4))
    for tj in range(nty):
        for ti in range(ntx):
            rows = slice(tj * step, min(tj * step + 2 * step, ny - 1) + 1)
            cols = slice(ti * step, min(ti * step + 2 * step, nx - 1) + 1)
            h = grid[rows, cols]
            x = origin[0] + spacing[0] * np.arange(cols.start, cols.stop)
            y = origin[1] + spacing[1] * np.arange(rows.start, rows.stop)
            dx, dy = x - x.mean(), y - y.mean()  # (a full lattice: x and y fit apart)
            gx = (h * dx[None, :]).sum() / (dx @ dx * len(y))
            gy = (h * dy[:, None]).sum() / (dy @ dy * len(x))
            plane = h.mean() + gx * dx[None, :] + gy * dy[:, None]
            rise = (h - plane).max()
            a = h.mean() - gx * x.mean() - gy * y.mean() + rise
            span = h.max() - h.min()
            out[tj * ntx + ti] = a, gx, gy, float(0.0 < span and rise <= 0.25 * span)
    return out


def _blocks(grid, block, reduce):
    ny, nx = grid.shape
    by, bx = (ny - 1) // block + 1, (nx - 1) // block + 1
    out = np.empty((by, bx))
    for j in range(by):
        for i in range(bx):
            out[j, i] = reduce(grid[j * block:(j + 1) * block + 1,
                                    i * block:(i + 1) * block + 1])
    return out


#: deg: the steepest slope the model was checked on (a plate comes to rest on 10 and 20 deg
#: slopes without creeping, test/test_terrain.py); a steeper surface is said at start-up.
CHECKED_SLOPE_DEG = 20.0


def steepest_squared(grid, spacing):
    """The largest squared gradient (dz/dx^2 + dz/dy^2) of the bilinear surface on the
    heights `grid` [iy, ix] with node `spacing` (dx, dy) m: in each cell it is steepest at a
    corner, where it is the two edges' slopes meeting there."""
    dx = np.diff(grid, axis=1) / spacing[0]  # (ny, nx - 1): along the x edges
    dy = np.diff(grid, axis=0) / spacing[1]  # (ny - 1, nx): along the y edges
    corners = [dx[:-1] ** 2 + dy[:, :-1] ** 2, dx[1:] ** 2 + dy[:, :-1] ** 2,
               dx[:-1] ** 2 + dy[:, 1:] ** 2, dx[1:] ** 2 + dy[:, 1:] ** 2]
    return float(max(c.max() for c in corners))


class Surface:
    """A sand surface. Subclasses define `height` and `data`; `notices`: what reading it
    decided for the user (one line each); `rigid`: whether it stays as it is (deformable
    sand, `deformable.DeformableSand`, is not)."""

    notices = ()
    rigid = True

    def height(self, x, y):
        """World z of the free surface at world (x, y) (m; arrays broadcast)."""
        raise NotImplementedError

    def bounds(self, x0, x1, y0, y1):
        """(lowest, highest) world z (m) of the surface over the rectangle x0 <= x <= x1,
        y0 <= y <= y1 (m), or (a grid) bounds of them within those of the grid cells the
        rectangle touches; equal where the surface is level there (exactly, on a grid)."""
        raise NotImplementedError

    def highest(self, x0, x1, y0, y1):
        """World z (m) of the highest surface point over the rectangle (`bounds`)."""
        return self.bounds(x0, x1, y0, y1)[1]

    def describe(self):
        """What this surface is, JSON-ready (SI), for a run's record (`summary.json`'s
        `surface`): its kind and parameters; a grid's placement and a SHA-256 of its heights,
        which tells two grids apart however they were made."""
        raise NotImplementedError

    def steepest_deg(self):
        """The surface's steepest inclination (deg): a plane's 0, a slope's angle, a grid's
        steepest cell (the gradient of the bilinear surface at the cell's corners)."""
        return 0.0

    def normal(self, x, y, step=1e-4):
        """Unit upward normal of the surface at (x, y) ((..., 3)), from the height's central
        differences over +-step m."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        gx = (self.height(x + step, y) - self.height(x - step, y)) / (2 * step)
        gy = (self.height(x, y + step) - self.height(x, y - step)) / (2 * step)
        n = np.stack(np.broadcast_arrays(-gx, -gy, np.ones_like(gx)), axis=-1)
        return n / np.linalg.norm(n, axis=-1, keepdims=True)

    @property
    def data(self):
        """The kernels' SurfaceData."""
        raise NotImplementedError


_NO_GRID = np.zeros((2, 2))


class Plane(Surface):
    """Horizontal sand surface at z = height (m)."""

    def __init__(self, height=0.0):
        self.level = float(height)

    def height(self, x, y):
        return np.full(np.broadcast(x, y).shape, self.level) if np.ndim(x) or np.ndim(y) \
            else self.level

    def bounds(self, x0, x1, y0, y1):
        return self.level, self.level

    def describe(self):
        return {'type': 'plane', 'height_m': self.level}

    @property
    def data(self):
        return SurfaceData(FLAT, self.level, (0.0, 0.0), _NO_GRID, (0.0, 0.0), (1.0, 1.0),
                           _NO_GRID, _NO_GRID)


class Slope(Surface):
    """Inclined plane: z = height at the world origin, falling by tan(angle_deg) per metre
    along the heading downhill_deg (degrees from +x towards +y)."""

    def __init__(self, height=0.0, angle_deg=0.0, downhill_deg=0.0):
        if not 0.0 <= angle_deg < 90.0:
            raise ValueError(f'sand.surface.angle_deg must be in [0, 90), got {angle_deg}')
        self.level, self.angle_deg, self.downhill_deg = float(height), angle_deg, downhill_deg
        fall, heading = np.tan(np.radians(angle_deg)), np.radians(downhill_deg)
        self.gradient = (-fall * np.cos(heading), -fall * np.sin(heading))

    def height(self, x, y):
        return self.level + self.gradient[0] * np.asarray(x) + self.gradient[1] * np.asarray(y)

    def bounds(self, x0, x1, y0, y1):
        corners = self.height(np.array([x0, x1, x0, x1]), np.array([y0, y0, y1, y1]))
        return float(np.min(corners)), float(np.max(corners))

    def steepest_deg(self):
        return float(self.angle_deg)

    def describe(self):
        return {'type': 'slope', 'height_m': self.level, 'angle_deg': float(self.angle_deg),
                'downhill_deg': float(self.downhill_deg)}

    @property
    def data(self):
        return SurfaceData(SLOPE, self.level, self.gradient, _NO_GRID, (0.0, 0.0), (1.0, 1.0),
                           _NO_GRID, _NO_GRID)


#: A height grid may reach at most this many of its node spacings from the world origin, so
#: that float64 coordinates resolve a node spacing to 2e-7 of it.
RESOLVED_SPACINGS = 1e9
#: A height grid and its values, as errors name them.
GRID_VALUES = ('a height grid', 'heights')


class HeightGrid(Surface):
    """Height field on a regular grid of nodes: heights[iy, ix] (m, world z; row 0 at the
    lowest y), spanning size = (x, y) m centred on center = (x, y) m; bilinear between nodes,
    the edge values continued outside. Its `grid` and the bounds derived from it are
    read-only (`rigid`): the engine reads them as they were when it was built, so another
    surface is another HeightGrid (deformable sand changes its own, bounds included)."""

    def __init__(self, heights, size, center=(0.0, 0.0)):
        grid = np.array(heights, dtype=float)
        if grid.ndim != 2:
            raise ValueError(f'{GRID_VALUES[0]} is a 2-D array of {GRID_VALUES[1]} [rows (y), '
                             f'columns (x)], got {grid.ndim} dimension(s), shape {grid.shape}')
        if min(grid.shape) < 2:
            raise ValueError(f'a height grid needs at least 2 x 2 nodes, got shape {grid.shape}')
        if not np.all(np.isfinite(grid)):
            raise ValueError('a height grid must hold finite heights')
        size = tuple(float(s) for s in size)
        if len(size) != 2 or not min(size) > 0 or not np.all(np.isfinite(size)):
            raise ValueError(f'sand.surface.size must be [x, y] > 0 m, finite, got {size}')
        center = tuple(float(c) for c in center)
        if len(center) != 2 or not np.all(np.isfinite(center)):
            raise ValueError(f"a height grid's center must be [x, y] m, finite, got {center}")
        self.grid = np.ascontiguousarray(grid)
        self.size, self.center = size, center
        ny, nx = grid.shape
        self.spacing = (size[0] / (nx - 1), size[1] / (ny - 1))
        self.origin = (self.center[0] - size[0] / 2, self.center[1] - size[1] / 2)
        far = max(abs(self.center[0]) + size[0] / 2, abs(self.center[1]) + size[1] / 2)
        if not far <= RESOLVED_SPACINGS * min(self.spacing):
            raise ValueError(f'a height grid reaching {far:.3g} m from the world origin with '
                             f'nodes {min(self.spacing):.3g} m apart: world coordinates '
                             '(float64) do not resolve its cells there; centre it nearer the '
                             'origin')
        self.block_max = block_maximum(self.grid)
        self.block_min = block_minimum(self.grid)
        for array in (self.grid, self.block_max, self.block_min):
            array.flags.writeable = not self.rigid

    def steepest_deg(self):
        return float(np.degrees(np.arctan(np.sqrt(steepest_squared(self.grid,
                                                                   self.spacing)))))

    def placement(self):
        """Where the nodes lie, for a saved grid: heights[iy, ix] is the world z (m) at world
        x, y = origin_m + (ix, iy) * spacing_m; nodes_xy: (columns, rows)."""
        ny, nx = self.grid.shape
        return {'origin_m': list(self.origin), 'spacing_m': list(self.spacing),
                'nodes_xy': [nx, ny]}

    def describe(self):
        return {'type': 'grid', **self.placement(), 'heights_sha256': heights_digest(self.grid)}

    @classmethod
    def from_file(cls, path, size, center=(0.0, 0.0), height_range=None, base=0.0):
        """A grid from a .npy (heights in m above `base`; `height_range` [low, high] m, if
        given, rescales its values onto that range) or a PNG (grey levels 0..1 mapped onto
        `height_range`, which is then required; the image's top row is the +y edge, as a map
        seen from above)."""
        key = 'sand.surface.file'
        path = Path(path)
        if file_format(path, key) == 'npy':
            values = read_npy(path, key, GRID_VALUES)
            if height_range is not None:
                values = _rescale(values, height_range)
        else:
            if height_range is None:
                raise ValueError('sand.surface.height_range [low, high] m is needed for a '
                                 'PNG height field')
            low, high = _range(height_range)
            values = low + (high - low) * grey_levels(path, key, GRID_VALUES)
        return cls(base + values, size, center)

    @classmethod
    def from_mjcf_hfield(cls, model, geom=None, beyond=None):
        """The height field of the MuJoCo model's hfield geom `geom` (`hfield_geom`: its name,
        its <hfield>'s, or its id; None: the model's only one), world frame, as MuJoCo places
        it: heights pos_z + data x size_z over the geom's local x in +-size_x and y in
        +-size_y. The geom must be fixed to the world (in the world body, or a body welded to
        it) and level; it may be turned about world z by any angle. A multiple of 90 deg is
        read exactly (the data's rows and columns turned with it), and so is a turn whose
        farthest node lies within SNAP_SPACINGS node spacings of a quarter turn's (said in
        `notices`); any other turn is resampled (`_resampled`, said in `notices`). A tilt is
        refused with its angle. beyond: None, the field's edge heights continue beyond it;
        or the world z (m) of a plane around it (`within_plane`, in the field's own frame, so
        that a turned field's plane is met over one of its cells outside its own edges)."""
        import mujoco
        g = hfield_geom(model, geom)
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)  # the pose of a geom fixed to the world
        rotation, pos = data.geom_xmat[g].reshape(3, 3), data.geom_xpos[g].copy()
        yaw = np.arctan2(rotation[1, 0], rotation[0, 0])
        label = f'hfield geom {hfield_label(model, g)!r}'
        if abs(rotation[2, 2] - 1.0) > 1e-9:
            tilt = np.degrees(np.arccos(np.clip(rotation[2, 2], -1.0, 1.0)))
            raise ValueError(f'sand.surface.geom: {label} is tilted {tilt:.6g} deg: only level '
                             'hfields (turned about z alone) are read')
        h = int(model.geom_dataid[g])
        rows, cols = int(model.hfield_nrow[h]), int(model.hfield_ncol[h])
        start = int(model.hfield_adr[h])
        heights = pos[2] + model.hfield_size[h][2] * \
            model.hfield_data[start:start + rows * cols].reshape(rows, cols)
        field = cls(heights, 2.0 * model.hfield_size[h][:2])  # (the geom's frame)
        turns = int(np.rint(yaw / (np.pi / 2)))
        off = yaw - turns * np.pi / 2
        move = abs(off) * 0.5 * np.hypot(*field.size)  # m: its farthest node's, were it snapped
        if beyond is not None:
            field = field.within_plane(beyond)
        if move > SNAP_SPACINGS * min(field.spacing):
            return _resampled(field, yaw, (pos[0], pos[1]), label)
        # rows are y (row 0 lowest), so a turn counterclockwise seen from above is rot90's
        # clockwise one
        grid = cls(np.rot90(field.grid, -turns),
                   field.size if turns % 2 == 0 else field.size[::-1], (pos[0], pos[1]))
        if move > ROUNDING_SPACINGS * min(field.spacing):  # (not a quarter turn's rounding)
            grid.notices = (f'{label} is turned {np.degrees(yaw):.6g} deg about z: read as '
                            f'{90 * turns} deg, exactly (its nodes move at most '
                            f'{move * 1e3:.2g} mm, {move / min(field.spacing):.2g} of its node '
                            'spacing)',)
        return grid

    def within_plane(self, level):
        """This grid in a plane at `level` (m): one ring of nodes at that level around it, so
        that beyond the field the edge continued is the plane, met over one cell."""
        grid = HeightGrid(np.pad(self.grid, 1, constant_values=float(level)),
                          (self.size[0] + 2 * self.spacing[0],
                           self.size[1] + 2 * self.spacing[1]), self.center)
        grid.notices = self.notices
        return grid

    def height(self, x, y):
        """The bilinear height the gather kernels read (`surface_kernels.grid_heights`),
        compiled: a Python caller (metrics, scenarios) sampling thousands of points at the
        publish rate pays microseconds, not a numpy pass per operation."""
        from .. import prebuilt  # (the kernel prebuilt, or numba's: imported when first used)
        from ..kernel_names import GRID_HEIGHTS
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        out = np.empty(x.shape)
        prebuilt.kernel(GRID_HEIGHTS)(  # (the points copied: C-contiguous and writeable)
            self.grid, float(self.origin[0]), float(self.origin[1]), 1.0 / self.spacing[0],
            1.0 / self.spacing[1], np.array(x, float).reshape(-1),
            np.array(y, float).reshape(-1), out.reshape(-1))
        return out if out.ndim else float(out)  # (a point in, a number out, as on a plane)

    def bounds(self, x0, x1, y0, y1):
        """The lowest and highest node of the cells the rectangle touches (the edge nodes
        outside)."""
        ny, nx = self.grid.shape
        (ox, oy), (dx, dy) = self.origin, self.spacing
        i0, i1 = (int(np.clip(np.floor((x0 - ox) / dx), 0, nx - 1)),
                  int(np.clip(np.ceil((x1 - ox) / dx), 0, nx - 1)))
        j0, j1 = (int(np.clip(np.floor((y0 - oy) / dy), 0, ny - 1)),
                  int(np.clip(np.ceil((y1 - oy) / dy), 0, ny - 1)))
        nodes = self.grid[j0:j1 + 1, i0:i1 + 1]
        return float(nodes.min()), float(nodes.max())

    @property
    def data(self):
        return SurfaceData(GRID, 0.0, (0.0, 0.0), self.grid, self.origin, self.spacing,
                           self.block_max, self.block_min)


#: A turn about z that would move an hfield's farthest node by at most this many node
#: spacings from a quarter turn's place is read as that quarter turn: resampling would
#: smooth the field by more.
SNAP_SPACINGS = 0.1
#: A move below this many node spacings is the rounding of a quarter turn (an euler of 90
#: deg), read without a notice.
ROUNDING_SPACINGS = 1e-9
#: Any other turn is resampled at the field's finer node spacing / RESAMPLE_REFINE, or a
#: coarser fraction of it (never coarser than the field's own spacing) where that grid would
#: pass RESAMPLE_NODES nodes (8 MB of heights, a 12 MB cloud where the node publishes the
#: whole grid).
RESAMPLE_REFINE = 4
RESAMPLE_NODES = 1_000_000


def heights_digest(heights):
    """SHA-256 (hex) of a grid of heights: its shape and its float64 values, row-major."""
    heights = np.ascontiguousarray(heights, dtype=np.float64)
    return hashlib.sha256(repr(heights.shape).encode() + heights.tobytes()).hexdigest()


def _resampled(field, yaw, center, what):
    """`field` (a HeightGrid in its own frame, centred on its origin) turned by `yaw` (rad)
    about z and moved to `center` (world x, y), resampled onto a world-aligned grid over the
    turned field's bounding box at a fraction of the field's finer node spacing
    (RESAMPLE_REFINE): each node takes the field's bilinear height at its place, a node
    beyond the turned field its nearest edge point's. So the sand equals the field at the
    nodes, reads a field linear across a cell as it is, and lies within a cell's node range
    inside it, except within one resampled cell of the field's edge, where the field's
    heights blend with those continued beyond it. `what` names the field in the notice the
    grid carries."""
    c, s = np.cos(yaw), np.sin(yaw)
    sx, sy = field.size
    extent = (abs(c) * sx + abs(s) * sy, abs(s) * sx + abs(c) * sy)
    refine = RESAMPLE_REFINE
    while refine > 1 and np.prod([e * refine / min(field.spacing) + 1 for e in extent]) > \
            RESAMPLE_NODES:
        refine -= 1
    spacing = min(field.spacing) / refine
    nodes = [int(np.ceil(e / spacing - 1e-9)) + 1 for e in extent]
    size = ((nodes[0] - 1) * spacing, (nodes[1] - 1) * spacing)
    dx, dy = np.meshgrid(spacing * np.arange(nodes[0]) - size[0] / 2,  # from the centre;
                         spacing * np.arange(nodes[1]) - size[1] / 2)  # row 0: lowest y
    grid = HeightGrid(field.height(c * dx + s * dy, c * dy - s * dx), size, center)
    grid.notices = (f'{what} is turned {np.degrees(yaw):.6g} deg about z: resampled onto a '
                    f'world-aligned grid of {nodes[0]} x {nodes[1]} nodes '
                    f'{spacing * 1e3:.3g} mm apart (1/{refine} of its node spacing; '
                    'bilinear; a quarter turn is read exactly)',)
    return grid


def hfield_geom(model, name=None):
    """Id of the MuJoCo model's hfield geom `name`: the geom's name, the name of the
    <hfield> asset that only this geom uses, or the geom's id (a geom without a name whose
    asset other geoms use too; as errors list it); with name None the model's only hfield
    geom. The geom must be fixed to the world (no joint or mocap body between it and the
    world). Raises ValueError with the reason."""
    import mujoco
    hfields = [g for g in range(model.ngeom)
               if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_HFIELD]
    listed = ', '.join(hfield_label(model, g) for g in hfields)
    if name is None:
        if not hfields:
            raise ValueError("sand.surface.type 'hfield' reads the model's own <hfield> geom; "
                             'the model has none')
        if len(hfields) > 1:
            raise ValueError('sand.surface.geom: name the hfield geom to read; the model has '
                             f'{len(hfields)} ({listed})')
        g = hfields[0]
    else:
        g = _named_hfield_geom(model, str(name), hfields, listed)
    if model.body_weldid[model.geom_bodyid[g]] != 0:  # (a joint or a mocap body between)
        raise ValueError(f'sand.surface.geom: hfield geom {hfield_label(model, g)!r} must be '
                         'fixed to the world (its body or a parent has a joint or is a '
                         'mocap body)')
    return g


def _named_hfield_geom(model, name, hfields, listed):
    """`hfield_geom`'s look-up of a given name among the hfield geoms `hfields`."""
    import mujoco
    g = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
    if g < 0 and name.isdigit() and int(name) < model.ngeom:
        g = int(name)
    if g < 0:
        users = [h for h in hfields if model.geom_dataid[h]
                 == mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_HFIELD, name)]
        if len(users) != 1:
            why = f'{len(users)} geoms use <hfield> {name!r}' if users else \
                f'no geom or <hfield> {name!r} in the model'
            raise ValueError(f'sand.surface.geom: {why}; its hfield geoms: {listed or "none"}')
        g = users[0]
    if g not in hfields:
        raise ValueError(f'sand.surface.geom: geom {name!r} is not an hfield geom; the '
                         f"model's: {listed or 'none'}")
    return g


def hfield_label(model, g):
    """How errors and notices name hfield geom g, in a form `hfield_geom` takes back: its
    name, else its <hfield>'s if no other geom uses that, else its id g."""
    import mujoco
    if model.geom(g).name:
        return model.geom(g).name
    asset = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_HFIELD, model.geom_dataid[g])
    users = np.count_nonzero((model.geom_type == mujoco.mjtGeom.mjGEOM_HFIELD)
                             & (model.geom_dataid == model.geom_dataid[g]))
    if asset and users == 1 and mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, asset) < 0:
        return asset
    return str(g)


def _range(height_range):
    try:
        low, high = (float(v) for v in height_range)
    except (TypeError, ValueError):
        raise ValueError(f'sand.surface.height_range must be [low, high] m, '
                         f'got {height_range!r}') from None
    if not high >= low:
        raise ValueError(f'sand.surface.height_range needs high >= low, got {height_range!r}')
    return low, high


def _rescale(values, height_range):
    low, high = _range(height_range)
    span = values.max() - values.min()
    unit = (values - values.min()) / span if span > 0 else np.zeros_like(values)
    return low + (high - low) * unit


SURFACE_TYPES = ('plane', 'slope', 'grid', 'hfield')
#: The kind code (kernel) of each sand.surface.type.
SURFACE_KINDS = {'plane': FLAT, 'slope': SLOPE, 'grid': GRID, 'hfield': GRID}


def surface_from_settings(settings, base_height=0.0, model=None):
    """The Surface a scene's `sand.surface` mapping describes (see module docstring).

    settings: {'type': 'plane' | 'slope' | 'grid' | 'hfield', ...}; base_height: the scene's
    sand.surface_height (m): the plane's height, the slope's height at the origin, the
    offset of a grid's heights, and with 'beyond': 'plane' the plane around a grid or hfield
    (`HeightGrid.within_plane`). model: the compiled MuJoCo model (hfield). Raises ValueError
    with the reason."""
    settings = dict(settings or {})
    kind = settings.get('type', 'plane')
    if kind not in SURFACE_TYPES:
        raise ValueError(f'sand.surface.type must be one of {SURFACE_TYPES}, got {kind!r}')
    if kind == 'plane':
        return Plane(base_height)
    if kind == 'slope':
        return Slope(base_height, float(settings.get('angle_deg', 0.0)),
                     float(settings.get('downhill_deg', 0.0)))
    beyond = settings.get('beyond', 'edge')
    if beyond not in ('edge', 'plane'):
        raise ValueError(f"sand.surface.beyond must be 'edge' or 'plane', got {beyond!r}")
    if kind == 'hfield':  # (a turned field meets its plane in its own frame)
        return HeightGrid.from_mjcf_hfield(model, settings.get('geom'),
                                           base_height if beyond == 'plane' else None)
    if 'file' not in settings or 'size' not in settings:
        raise ValueError('a grid surface needs sand.surface.file and sand.surface.size [x, y] m')
    grid = HeightGrid.from_file(settings['file'], settings['size'],
                                settings.get('center', (0.0, 0.0)),
                                settings.get('height_range'), base_height)
    return grid.within_plane(base_height) if beyond == 'plane' else grid
