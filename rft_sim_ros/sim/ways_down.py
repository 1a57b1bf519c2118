"""The ways a run's outcome (sim/outcome.py) says the robot went down, for those that read a
summary's `outcome` (the run's first line, /diagnostics, the report page, the plots): plain
data, so that the node imports it without the simulation (no MuJoCo)."""

#: (key, its time's key, as a run's first line says it).
DOWN = (('fell', 'fell_at_s', 'fell'), ('upside_down', 'upside_down_at_s', 'was upside down'),
        ('collapsed', 'collapsed_at_s', 'collapsed'), ('sank', 'sank_at_s', 'sank'))


def is_down(outcome):
    """Whether an `outcome` mapping (OutcomeWatch.result; None: none yet) says the robot
    went down in any way (DOWN)."""
    return any((outcome or {}).get(key) for key, _, _ in DOWN)
