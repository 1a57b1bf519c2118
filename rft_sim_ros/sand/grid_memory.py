"""Refuse a grid too large for this machine before any of it is allocated: deformable sand's
bed (`deformable.check_memory`; a study's workers holding beds at once: `study.sweep`), a
zeta map's raster of regions (`zeta_map`) and a PNG (`grid_files`). Nodes are
counted as floats, so that any size and cell, however absurd, is told rather than
overflowing."""
import os

#: A grid may take at most this fraction of the machine's physical memory.
MEMORY_FRACTION = 0.5


def machine_memory():
    """This machine's physical memory, bytes; None where the system does not say (not
    POSIX)."""
    try:
        return os.sysconf('SC_PAGE_SIZE') * os.sysconf('SC_PHYS_PAGES')
    except (AttributeError, ValueError, OSError):
        return None


def check_grid_memory(nodes, bytes_per_node, what, advice, unit='nodes'):
    """Raise ValueError where a grid of `nodes` (nx, ny: floats, inf for an absurd grid) of
    `bytes_per_node` bytes each would take more than MEMORY_FRACTION of this machine's
    memory: '`what` of NX x NY `unit` needs about N GiB, ...: `advice`'. Not checked where
    the system does not say its memory (`machine_memory`)."""
    memory = machine_memory()
    if memory is None:
        return
    nx, ny = nodes
    need = nx * ny * bytes_per_node
    if need > MEMORY_FRACTION * memory:
        counts = ' x '.join(f'{n:.0f}' if n < 1e15 else f'{n:.3g}' for n in (nx, ny))
        raise ValueError(f'{what} of {counts} {unit} needs about {need / 2**30:.3g} GiB, more '
                         f'than half of this machine\'s {memory / 2**30:.3g} GiB: {advice}')
