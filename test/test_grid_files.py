"""Grids from the files scene keys name (sand/grid_files.py): PNG grey levels read exactly at
every bit depth and colour type the reader takes, the others refused with the reason, and
.npy files checked; through `surface_from_settings` and the zeta map as a scene gives them."""
import struct
import zlib

import numpy as np
import pytest
from PIL import Image

from rft_sim_ros.sand.grid_files import grey_levels, read_npy
from rft_sim_ros.sand.surface import surface_from_settings
from rft_sim_ros.sand.zeta_map import zeta_map_from_settings

WHAT = ('a height grid', 'heights')


def write_png(path, levels, depth, colour=0):
    """A PNG of integer `levels` (rows, columns[, channels]) at bit `depth` and colour type
    `colour`, written byte by byte (Pillow writes neither 2/4-bit greys nor 16-bit colour)."""
    levels = np.asarray(levels)
    rows, columns = levels.shape[:2]
    if depth < 8:  # (greys only: pixels packed into bytes, most significant bits first)
        bits = np.unpackbits(levels.astype(np.uint8)[..., None], axis=-1)[..., 8 - depth:]
        raw = np.packbits(bits.reshape(rows, -1), axis=1)
    else:
        raw = levels.astype('>u2' if depth == 16 else np.uint8).reshape(rows, -1)
        raw = raw.view(np.uint8).reshape(rows, -1)
    data = b''.join(b'\0' + row.tobytes() for row in raw)  # (filter type 0 on every row)

    def chunk(kind, body):
        return (struct.pack('>I', len(body)) + kind + body
                + struct.pack('>I', zlib.crc32(kind + body)))
    header = struct.pack('>IIBBBBB', columns, rows, depth, colour, 0, 0, 0)
    path.write_bytes(b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', header)
                     + chunk(b'IDAT', zlib.compress(data)) + chunk(b'IEND', b''))
    return path


@pytest.mark.parametrize('depth', [1, 2, 4, 8, 16])
def test_greyscale_pngs_of_every_bit_depth_read_as_level_over_the_largest(tmp_path, depth):
    """A ramp of every level 0 .. 2^depth - 1 along the top row reads as level / (2^depth - 1);
    the top image row is the +y edge (row 0 of the grid the lowest y)."""
    top = 2 ** depth - 1
    ramp = np.round(np.linspace(0, top, 17)).astype(int)
    image = np.vstack([ramp, np.zeros_like(ramp)])
    levels = grey_levels(write_png(tmp_path / 'g.png', image, depth), 'key', WHAT)
    assert levels.shape == (2, 17)
    np.testing.assert_array_equal(levels[1], ramp / top)  # (exact: one division)
    np.testing.assert_array_equal(levels[0], 0.0)


@pytest.mark.parametrize('mode', ['L', 'LA', 'RGB', 'RGBA', 'P'])
def test_eight_bit_greys_in_colour_alpha_and_palette_pngs_read_as_their_grey(tmp_path, mode):
    """Image editors save greys as RGB, with alpha, or as a palette: their grey is read (alpha
    ignored), exactly as the same greyscale image."""
    grey = np.arange(0, 256, 15, dtype=np.uint8).reshape(1, -1).repeat(3, axis=0)
    Image.fromarray(grey, 'L').convert(mode).save(tmp_path / 'c.png')
    levels = grey_levels(tmp_path / 'c.png', 'key', WHAT)
    np.testing.assert_array_equal(levels, grey[::-1] / 255.0)


def test_pngs_whose_values_are_not_greys_read_exactly_are_refused(tmp_path):
    """A colour image (its channels differ), 16-bit colour and 16-bit grey+alpha (Pillow
    reduces them to 8 bits: a ramp in 1000 steps read as 235 levels), and files that are no
    PNG or are cut short, each with the reason."""
    red = np.zeros((2, 3, 3), dtype=np.uint8)
    red[..., 0] = 200
    Image.fromarray(red, 'RGB').save(tmp_path / 'red.png')
    with pytest.raises(ValueError, match="key .*red.png' is a colour image .RGB with pixels "
                                         'that are not grey.'):
        grey_levels(tmp_path / 'red.png', 'key', WHAT)
    for colour, channels, name in ((2, 3, 'RGB'), (4, 2, 'grey\\+alpha'), (6, 4, 'RGBA')):
        levels = np.full((2, 3, channels), 40000)
        path = write_png(tmp_path / f'c{colour}.png', levels, 16, colour)
        with pytest.raises(ValueError, match=f'is a 16-bit {name} PNG, which the PNG reader '
                                             r'\(Pillow\) reduces to 8 bits'):
            grey_levels(path, 'key', WHAT)
    (tmp_path / 'text.png').write_text('not an image')
    with pytest.raises(ValueError, match="key .*text.png' is not a PNG file"):
        grey_levels(tmp_path / 'text.png', 'key', WHAT)
    whole = write_png(tmp_path / 'whole.png', np.arange(400).reshape(20, 20) % 256, 8)
    (tmp_path / 'cut.png').write_bytes(whole.read_bytes()[:60])
    with pytest.raises(ValueError, match="key .*cut.png' is not a readable PNG"):
        grey_levels(tmp_path / 'cut.png', 'key', WHAT)


@pytest.mark.parametrize('values, reason', [
    (np.zeros((3, 3), complex), 'holds complex128 values: it must hold real numbers'),
    (np.zeros((3, 3), bool), 'holds bool values'),
    (np.zeros((0, 4)), r'holds no values \(shape \(0, 4\)\)'),
    (np.zeros((2, 2, 2)), r'a height grid is a 2-D array of heights \[rows \(y\), columns '
                          r'\(x\)\], got 3 dimension'),
    (np.array([[0.0, np.nan], [1.0, np.inf]]), r'holds 2 value\(s\) that are not finite'),
])
def test_npy_files_that_hold_no_grid_of_numbers_are_refused(tmp_path, values, reason):
    np.save(tmp_path / 'g.npy', values)
    with pytest.raises(ValueError, match=reason):
        read_npy(tmp_path / 'g.npy', 'key', WHAT)


def test_files_that_are_no_npy_are_said_to_be_none(tmp_path):
    (tmp_path / 'empty.npy').write_bytes(b'')
    (tmp_path / 'text.npy').write_text('not numpy')
    np.savez(tmp_path / 'archive.npz', a=np.zeros((2, 2)))
    (tmp_path / 'archive.npy').write_bytes((tmp_path / 'archive.npz').read_bytes())
    for name in ('empty', 'text', 'archive'):
        with pytest.raises(ValueError, match=rf"key .*{name}.npy' is not a .npy file"):
            read_npy(tmp_path / f'{name}.npy', 'key', WHAT)
    np.save(tmp_path / 'short.npy', np.zeros((20, 20)))
    (tmp_path / 'cut.npy').write_bytes((tmp_path / 'short.npy').read_bytes()[:200])
    with pytest.raises(ValueError, match="key .*cut.npy' is not a readable .npy file"):
        read_npy(tmp_path / 'cut.npy', 'key', WHAT)


def test_scene_files_of_the_surface_and_the_zeta_map_read_their_pngs_exactly(tmp_path):
    """A 2-bit height PNG onto [0, 0.1] m gives heights 0 .. 0.1 m (read through matplotlib
    it gave 8.5 m); a 4-bit zeta map PNG onto [0.1, 1] gives factors 0.1 .. 1; a NaN in a
    .npy that `height_range` rescales is refused, not turned into a flat surface."""
    ramp = np.tile(np.arange(4), (3, 1))
    grid = surface_from_settings({'type': 'grid', 'file': str(write_png(
        tmp_path / 'h.png', ramp, 2)), 'size': [0.3, 0.2], 'height_range': [0.0, 0.1]})
    np.testing.assert_allclose(grid.grid[0], [0.0, 0.1 / 3, 0.2 / 3, 0.1], rtol=0, atol=1e-15)
    zmap = zeta_map_from_settings({'file': str(write_png(tmp_path / 'z.png', ramp * 5, 4)),
                                   'size': [0.4, 0.3], 'range': [0.1, 1.0]})
    np.testing.assert_allclose(zmap.factors[0], [0.1, 0.4, 0.7, 1.0], rtol=1e-15)
    heights = np.linspace(0.0, 0.1, 12).reshape(3, 4)
    heights[0, 0] = np.nan
    np.save(tmp_path / 'hole.npy', heights)
    with pytest.raises(ValueError, match=r"sand.surface.file .*hole.npy' holds 1 value\(s\) "
                                         'that are not finite'):
        surface_from_settings({'type': 'grid', 'file': str(tmp_path / 'hole.npy'),
                               'size': [0.3, 0.2], 'height_range': [0.0, 0.1]})
    np.save(tmp_path / 'factors.npy', np.ones((3, 4)))
    with pytest.raises(ValueError, match="sand.zeta_map.range maps a PNG's grey levels"):
        zeta_map_from_settings({'file': str(tmp_path / 'factors.npy'), 'size': [0.4, 0.3],
                                'range': [0.1, 1.0]})


def test_a_png_too_large_for_the_machine_is_refused_before_it_is_read(tmp_path):
    """The header's size is checked against the machine's memory first (Pillow's own guard
    against decompression bombs would raise a traceback above 179 Mpx instead)."""
    path = write_png(tmp_path / 'huge.png', np.zeros((1, 8)), 8)
    data = bytearray(path.read_bytes())
    data[16:24] = struct.pack('>II', 2 ** 30, 2 ** 30)  # the header says 2^30 x 2^30
    data[29:33] = struct.pack('>I', zlib.crc32(bytes(data[12:29])))
    path.write_bytes(bytes(data))
    with pytest.raises(ValueError, match=r"key .*huge.png': an image of 1073741824 x 1073741824 "
                                         'pixels needs about'):
        grey_levels(path, 'key', WHAT)


def test_a_palette_png_with_transparency_reads_without_a_warning(tmp_path, recwarn):
    grey = np.array([[0, 128, 255]], dtype=np.uint8)
    image = Image.fromarray(grey, 'L').convert('P')
    image.save(tmp_path / 'p.png', transparency=bytes([0, 255, 128]))  # (per palette entry)
    np.testing.assert_array_equal(grey_levels(tmp_path / 'p.png', 'key', WHAT), grey / 255.0)
    assert not [w for w in recwarn if 'Transparency' in str(w.message)]
