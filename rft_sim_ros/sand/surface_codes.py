"""The numbers the sand surfaces (`surface`) and their compiled look-ups (`surface_kernels`)
share: the kind code a kernel branches on (and its name, which names its gather kernel) and
the side of a grid's blocks. Apart from both so
that each can import them (the surfaces call the compiled look-ups; the look-ups compile these
in)."""

#: Kind codes read by the kernels: an infinite level plane, an infinite inclined plane, a
#: height grid.
FLAT, SLOPE, GRID = 0, 1, 2
#: The name of each kind code (KINDS[code]): what its gather kernel is named by
#: (`kernel_names.GATHERS`).
KINDS = ('plane', 'slope', 'grid')
#: Nodes per side of a block of a grid's block maximum and minimum.
BLOCK = 8
