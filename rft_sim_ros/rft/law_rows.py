"""The rows of a plate table, the compiled RFT law's input (`rft.kernel.leading_forces`): one
plate per column (structure of arrays, so the law's loop vectorises). Plain constants, so
that code laying out such tables (`sand.layout`) does not import the compiler. Callers may
keep further rows of their own after LAW_ROWS (DIRECTION comes last, so they can extend it).
"""
NORMAL = 0        # outward unit normal, world (3 rows)
NORMAL_SPEED = 3  # n . v, m/s
SCALE = 4         # zeta_si x depth x area, N; 0 for a plate that feels no force
AREA = 5          # m^2 (the dynamic term's); 0 for a plate that feels no force
DIRECTION = 6     # unit direction of motion, world (3 rows); zero for a plate at rest
LAW_ROWS = 9
