"""A run's summary as written out: JSON-safe values without float noise.

`significant` rounds floats to 12 significant digits (a float sum such as 6250 steps of
0.8 ms leaves 4.999999999999449 s; 12 digits keep every measured figure and drop that
noise); `finite` turns non-finite metrics into None (JSON has no NaN); `json_default`
serialises numpy scalars and arrays and paths.
"""
import math
from pathlib import Path

import numpy as np

#: Significant digits kept in written summaries.
DIGITS = 12


def significant(value, digits=DIGITS):
    """`value` (floats, or dicts/lists of them, numpy scalars included) with every float
    rounded to `digits` significant digits; other values unchanged."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float):
        return float(f'{value:.{digits}g}') if math.isfinite(value) else value
    if isinstance(value, dict):
        return {key: significant(item, digits) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [significant(item, digits) for item in value]
    return value


def finite(metrics):
    """Metrics with non-finite floats replaced by None (JSON has no NaN)."""
    return {key: None if isinstance(value, float) and not math.isfinite(value) else value
            for key, value in metrics.items()}


def json_default(value):
    """JSON form of numpy scalars and arrays and of paths (json.dumps default=)."""
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f'not JSON serialisable: {type(value).__name__}')
