"""The results table of a study: one row per run (run id, repeat, a column per varied key and
metric, wall_time_s, stable, reason), written as results.csv and as a columnar results.npz.

Why .npz for the columnar copy: one typed numpy array per column (floats stay exact, bools
stay bools, missing values are NaN), nothing to install beyond numpy, and one line to load:
`numpy.load('results.npz')` or `pandas.DataFrame(dict(numpy.load('results.npz')))`.
Parquet would need pyarrow (a 55 MB wheel) for a table of at most a few MB.
Files are written to a temporary name and renamed, so a reader never sees half a table.
"""
import csv
import io
import json
import math
import os
from pathlib import Path

import numpy as np

#: Columns after the varied keys and metrics.
TAIL = ('wall_time_s', 'stable', 'reason')


def columns(study):
    """Column names in order: run_id, repeat, varied keys, metrics, wall_time_s, stable,
    reason."""
    return ['run_id', 'repeat', *study.keys, *study.metrics, *TAIL]


def _number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def summary_values(summary):
    """{name: value} of a run's summary.json that metrics are named from: the summary's own
    (real_time_factor, implicit_solves_per_step, plates_active_mean, ...), then every
    scene's (`generic_metrics`: base_displacement_m, max_sinkage_m_<body>, ...), then the
    scenario's (`metrics`), a later one winning a name."""
    summary = summary or {}
    return {**summary, **(summary.get('generic_metrics') or {}),
            **(summary.get('metrics') or {})}


def summary_metrics(summary):
    """{name: number} of the metrics a study can tabulate from a run's summary.json
    (`summary_values`): its numbers, and each number of a list of numbers as name[i]
    (base_displacement_xyz_m[0]: the x of a vector)."""
    metrics = {}
    for name, value in summary_values(summary).items():
        if _number(value):
            metrics[name] = value
        elif isinstance(value, list) and value and all(_number(v) for v in value):
            metrics.update({f'{name}[{i}]': v for i, v in enumerate(value)})
    return metrics


def row(study, run, record):
    """The table row ({column: value}) of `run` (a spec.Run) from its record (execute)."""
    metrics = summary_metrics(record.get('summary'))
    return {'run_id': run.run_id, 'repeat': run.repeat,
            **{key: run.varied.get(key) for key in study.keys},
            **{name: metrics.get(name) for name in study.metrics},
            'wall_time_s': record['wall_time_s'], 'stable': bool(record['stable']),
            'reason': record['reason'] or ''}


def write_atomic(path, data):
    """Write bytes `data` to `path` through a temporary file and a rename."""
    path = Path(path)
    temporary = path.with_name(f'.{path.name}.{os.getpid()}.tmp')
    temporary.write_bytes(data)
    os.replace(temporary, path)


def _text(value):
    """A table cell's text: lists and mappings (a varied `sand.surface.size`, zeta-map
    regions) as JSON, which reads back as what they were; anything else as str."""
    return json.dumps(value) if isinstance(value, (list, tuple, dict)) else str(value)


def _cell(value):
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ''
    if isinstance(value, float):
        return repr(value)  # shortest text that reads back to the same float
    return _text(value)


def write_csv(path, names, rows):
    text = io.StringIO()
    writer = csv.writer(text, lineterminator='\n')
    writer.writerow(names)
    writer.writerows([_cell(r[name]) for name in names] for r in rows)
    write_atomic(path, text.getvalue().encode())


def column_array(values):
    """A typed numpy array for one column: bool, float (None -> NaN) or text."""
    present = [v for v in values if v is not None]
    if present and all(isinstance(v, bool) for v in present) and len(present) == len(values):
        return np.array(values, dtype=bool)
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in present):
        return np.array([math.nan if v is None else v for v in values], dtype=float)
    return np.array(['' if v is None else _text(v) for v in values], dtype=str)


def write_npz(path, names, rows):
    buffer = io.BytesIO()
    np.savez(buffer, **{name: column_array([r[name] for r in rows]) for name in names})
    write_atomic(path, buffer.getvalue())


def read_csv(path):
    """Rows of a results.csv as {column: text} (for tests and tools)."""
    with open(path, newline='') as handle:
        return list(csv.DictReader(handle))
