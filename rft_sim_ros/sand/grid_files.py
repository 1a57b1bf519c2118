"""Read the grids that scene files name: a height field's heights (`surface.HeightGrid`) and a
zeta map's factors (`zeta_map.ZetaMap`), from a .npy or a PNG, each checked so that a file the
reader cannot take exactly is refused with the reason instead of becoming another surface.

Arrays are returned as (rows, columns) floats with row 0 at the lowest y: a .npy as stored,
a PNG's top image row being the +y edge (a map seen from above).

PNG grey levels are read exactly at every bit depth: a greyscale PNG of depth b holds levels
0 .. 2^b - 1 (b = 1, 2, 4, 8 or 16), read as level / (2^b - 1). Colour and palette images are
read where every pixel is grey (red = green = blue, as image editors save greys); alpha is
ignored. A 16-bit colour or grey+alpha PNG is refused: Pillow, the PNG reader, reduces those
to 8 bits. A .npy must hold finite real numbers (integers or floats).
"""
import struct
import zlib

import numpy as np

from .grid_memory import check_grid_memory

#: PNG colour types (the IHDR chunk's), by code.
PNG_COLOUR_TYPES = {0: 'greyscale', 2: 'RGB', 3: 'palette', 4: 'grey+alpha', 6: 'RGBA'}
#: The bytes every .npy file starts with.
NPY_MAGIC = b'\x93NUMPY'
#: Bytes a PNG takes per pixel at the peak of reading it (Pillow's image, RGBA and float
#: copies of it), for the memory check (`grid_memory`).
PNG_BYTES_PER_PIXEL = 48
#: The 8 bytes every PNG starts with.
PNG_SIGNATURE = b'\x89PNG\r\n\x1a\n'


def file_format(path, key):
    """'npy' or 'png': the format of the file at `path` (a Path) by its suffix; ValueError
    naming the scene key `key` for a missing file, a folder or another suffix."""
    if path.is_dir():
        raise ValueError(f'{key} {str(path)!r} is a folder, not a file')
    if not path.is_file():
        raise ValueError(f'{key} {str(path)!r} not found')
    suffix = path.suffix.lower()
    if suffix not in ('.npy', '.png'):
        raise ValueError(f'{key} must be a .png or .npy, got {path.name!r}')
    return suffix[1:]


def read_npy(path, key, what):
    """The 2-D array of finite real numbers in the .npy at `path` (floats); key: the scene
    key naming the file, what: (the grid, its values) named in errors, e.g. ('a height
    grid', 'heights') (ValueError with the reason)."""
    with open(path, 'rb') as stream:
        if stream.read(len(NPY_MAGIC)) != NPY_MAGIC:
            raise ValueError(f'{key} {str(path)!r} is not a .npy file (numpy.save writes one)')
    try:
        values = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError) as error:
        raise ValueError(f'{key} {str(path)!r} is not a readable .npy file ({error})') from None
    if values.dtype.kind not in 'iuf':
        raise ValueError(f'{key} {str(path)!r} holds {values.dtype} values: it must hold '
                         'real numbers (integers or floats)')
    return _checked(values.astype(float), key, path, what)


def grey_levels(path, key, what):
    """The grey levels 0..1 of the PNG at `path`, (rows, columns) with row 0 the image's
    bottom row (lowest y); key, what: as in `read_npy`, for errors (ValueError with the
    reason). See the module docstring for what is read and what is refused."""
    width, height, depth, colour = png_header(path, key)
    check_grid_memory((float(width), float(height)), PNG_BYTES_PER_PIXEL,
                      f'{key} {str(path)!r}: an image', 'downsample it, or save a .npy',
                      unit='pixels')
    if depth == 16 and colour != 0:
        raise ValueError(f'{key} {str(path)!r} is a 16-bit {PNG_COLOUR_TYPES[colour]} PNG, '
                         'which the PNG reader (Pillow) reduces to 8 bits: save it as a 16-bit '
                         'greyscale PNG without alpha, or as a .npy')
    from PIL import Image
    bomb_limit, Image.MAX_IMAGE_PIXELS = Image.MAX_IMAGE_PIXELS, None  # (checked above)
    try:
        with Image.open(path) as image:
            image.load()
            if colour == 0:
                levels = np.asarray(image, dtype=float)
                top = 1.0 if image.mode == '1' else (65535.0 if depth == 16 else 255.0)
            else:  # (Pillow expands palettes and grey+alpha; alpha is dropped)
                levels = np.asarray(image.convert('RGBA'), dtype=float)[..., :3]
                top = 255.0
    except (OSError, SyntaxError, ValueError) as error:
        raise ValueError(f'{key} {str(path)!r} is not a readable PNG ({error})') from None
    finally:
        Image.MAX_IMAGE_PIXELS = bomb_limit
    if levels.ndim == 3:
        if np.any(levels[..., 1:] != levels[..., :1]):
            raise ValueError(f'{key} {str(path)!r} is a colour image ({PNG_COLOUR_TYPES[colour]} '
                             'with pixels that are not grey): the values are read from grey '
                             'levels; save it as a greyscale PNG')
        levels = levels[..., 0]
    return _checked(levels[::-1] / top, key, path, what)


def png_header(path, key):
    """(width, height, bit depth, colour type) from the IHDR chunk of the PNG at `path`;
    ValueError naming `key` if the file does not start as a PNG does."""
    with open(path, 'rb') as stream:
        head = stream.read(33)
    if len(head) < 33 or head[:8] != PNG_SIGNATURE or head[12:16] != b'IHDR':
        raise ValueError(f'{key} {str(path)!r} is not a PNG file')
    width, height = struct.unpack('>II', head[16:24])
    depth, colour = head[24], head[25]
    if zlib.crc32(head[12:29]) != struct.unpack('>I', head[29:33])[0] or \
            colour not in PNG_COLOUR_TYPES:
        raise ValueError(f'{key} {str(path)!r} is not a readable PNG (a damaged header)')
    return width, height, depth, colour


def _checked(values, key, path, what):
    """values if a 2-D array of finite numbers with something in it; else ValueError."""
    if values.ndim != 2:
        raise ValueError(f'{key} {str(path)!r}: {what[0]} is a 2-D array of {what[1]} [rows '
                         f'(y), columns (x)], got {values.ndim} dimension(s), shape '
                         f'{values.shape}')
    if values.size == 0:
        raise ValueError(f'{key} {str(path)!r} holds no values (shape {values.shape})')
    if not np.all(np.isfinite(values)):
        bad = int(np.count_nonzero(~np.isfinite(values)))
        raise ValueError(f'{key} {str(path)!r} holds {bad} value(s) that are not finite '
                         '(NaN or inf): fill them first (e.g. from their neighbours)')
    return values
