"""Patches of different sand: a map of factors that multiply the scene's zeta by position.

A `ZetaMap` is a grid of square cells (side `cell`, m) whose corner [0, 0] lies at world
`origin` (x, y); factors[iy, ix] multiplies zeta for plates above cell (ix, iy) (row 0 at
the lowest y); outside the map the factor is 1. The dynamic `zeta` parameter keeps scaling
the whole map (the engine multiplies zeta x factor).

Scenes give it as `sand.zeta_map` with either
- `file` (.npy of factors, or a PNG whose grey levels 0..1 map onto `range` [low, high]),
  `size` [x, y] m and optional `center` [x, y] m; or
- `regions`: a list of {x: [low, high], y: [low, high], factor: f} rectangles (m), later
  ones over earlier ones, rasterised on `cell` m cells (default 0.01) over their bounding box.
"""
from pathlib import Path

import numpy as np

from .grid_files import file_format, grey_levels, read_npy
from .grid_memory import check_grid_memory

#: Bytes of a raster of regions per cell at its peak (its factors, a mask of each region's
#: cells, the grid of cell centres: 8 + 1 + 8, rounded up).
RASTER_BYTES_PER_CELL = 24
#: A zeta map and its values, as errors name them.
MAP_VALUES = ('a zeta map', 'factors')


class ZetaMap:
    """factors (ny, nx) > 0 on square cells of side `cell` m from world corner `origin`."""

    def __init__(self, factors, origin, cell):
        factors = np.array(factors, dtype=float)
        if factors.ndim != 2 or factors.size == 0:
            raise ValueError(f'a zeta map needs a 2-D grid of factors, got shape {factors.shape}')
        if not np.all(np.isfinite(factors)) or np.any(factors <= 0):
            raise ValueError('zeta map factors must be finite and > 0')
        if not cell > 0:
            raise ValueError(f'sand.zeta_map.cell must be > 0 m, got {cell}')
        self.factors = np.ascontiguousarray(factors)
        self.origin = (float(origin[0]), float(origin[1]))
        self.cell = float(cell)

    def factor(self, x, y):
        """The factor at world (x, y) (arrays broadcast); 1 outside the map."""
        u = np.floor((np.asarray(x, float) - self.origin[0]) / self.cell).astype(int)
        v = np.floor((np.asarray(y, float) - self.origin[1]) / self.cell).astype(int)
        ny, nx = self.factors.shape
        inside = (u >= 0) & (v >= 0) & (u < nx) & (v < ny)
        return np.where(inside, self.factors[np.clip(v, 0, ny - 1), np.clip(u, 0, nx - 1)], 1.0)

    @classmethod
    def from_regions(cls, regions, cell=0.01):
        """Rectangles [{x: [lo, hi], y: [lo, hi], factor: f}] (m), later over earlier, on
        square cells of side `cell` m (a cell takes the factor of the region holding its
        centre)."""
        if not isinstance(regions, list) or not regions:
            raise ValueError('sand.zeta_map.regions must be a non-empty list of '
                             '{x: [lo, hi], y: [lo, hi], factor: f}')
        boxes = []
        for index, region in enumerate(regions):
            try:
                (x0, x1), (y0, y1) = region['x'], region['y']
                box = tuple(float(v) for v in (x0, x1, y0, y1, region['factor']))
            except (KeyError, TypeError, ValueError):
                raise ValueError(f'sand.zeta_map.regions[{index}] must be {{x: [lo, hi], '
                                 f'y: [lo, hi], factor: f}}, got {region!r}') from None
            if not (np.all(np.isfinite(box[:4])) and box[1] > box[0] and box[3] > box[2]):
                raise ValueError(f'sand.zeta_map.regions[{index}]: bounds must be finite with '
                                 f'lo < hi, got {region!r}')
            if not (np.isfinite(box[4]) and box[4] > 0):
                raise ValueError(f'sand.zeta_map.regions[{index}]: factor must be finite and > '
                                 f'0, got {region["factor"]!r}')
            boxes.append(box)
        boxes = np.array(boxes)
        x_lo, y_lo = boxes[:, 0].min(), boxes[:, 2].min()
        cells = [float(np.ceil((boxes[:, 1].max() - x_lo) / cell)),
                 float(np.ceil((boxes[:, 3].max() - y_lo) / cell))]
        check_grid_memory(cells, RASTER_BYTES_PER_CELL,
                          f'sand.zeta_map: the regions\' raster ({cell:g} m cells)',
                          'bound the regions to where the robot goes, or make '
                          'sand.zeta_map.cell larger', unit='cells')
        nx, ny = (int(n) for n in cells)
        xc = x_lo + (np.arange(nx) + 0.5) * cell
        yc = y_lo + (np.arange(ny) + 0.5) * cell
        factors = np.ones((ny, nx))
        for index, (x0, x1, y0, y1, f) in enumerate(boxes):
            inside = ((yc >= y0) & (yc < y1))[:, None] & ((xc >= x0) & (xc < x1))[None, :]
            if not inside.any():
                raise ValueError(f'sand.zeta_map.regions[{index}] (x {x0:g} .. {x1:g}, y {y0:g} '
                                 f'.. {y1:g} m) holds no cell centre of the {cell:g} m cells '
                                 'the regions are rasterised on, so it would change nothing: '
                                 'widen it or make sand.zeta_map.cell smaller')
            factors[inside] = f
        return cls(factors, (x_lo, y_lo), cell)

    @classmethod
    def from_file(cls, path, size, center=(0.0, 0.0), value_range=None):
        """Factors from a .npy, or from a PNG's grey levels mapped onto value_range [low,
        high] (required for a PNG; top image row = +y edge), over `size` [x, y] m centred on
        `center`. Cells must be square."""
        key = 'sand.zeta_map.file'
        path = Path(path)
        if file_format(path, key) == 'npy':
            if value_range is not None:
                raise ValueError('sand.zeta_map.range maps a PNG\'s grey levels; a .npy holds '
                                 'the factors themselves: leave the range out')
            factors = read_npy(path, key, MAP_VALUES)
        else:
            if value_range is None:
                raise ValueError('sand.zeta_map.range [low, high] is needed for a PNG zeta map')
            low, high = (float(v) for v in value_range)
            factors = low + (high - low) * grey_levels(path, key, MAP_VALUES)
        ny, nx = factors.shape
        cell_x, cell_y = float(size[0]) / nx, float(size[1]) / ny
        if not np.isclose(cell_x, cell_y, rtol=1e-6):
            raise ValueError(f'sand.zeta_map: size {list(size)} over {nx} x {ny} cells gives '
                             'cells that are not square')
        origin = (float(center[0]) - float(size[0]) / 2, float(center[1]) - float(size[1]) / 2)
        return cls(factors, origin, cell_x)


def zeta_map_from_settings(settings):
    """The ZetaMap a scene's `sand.zeta_map` mapping describes, or None without one.
    Raises ValueError with the reason."""
    if not settings:
        return None
    if not isinstance(settings, dict):
        raise ValueError(f'sand.zeta_map must be a mapping, got {settings!r}')
    if 'regions' in settings:
        return ZetaMap.from_regions(settings['regions'], float(settings.get('cell', 0.01)))
    if 'file' not in settings or 'size' not in settings:
        raise ValueError('sand.zeta_map needs regions, or file and size [x, y] m')
    return ZetaMap.from_file(settings['file'], settings['size'], settings.get('center', (0.0, 0.0)),
                             settings.get('range'))
