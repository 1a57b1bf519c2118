"""Plots of a study: each metric against each varied key (one PNG each, under DIR/plots/).
Stable runs as dots (the mean over the runs sharing a value joined by a line); runs that did
not stay stable as red crosses at the bottom of the axes. A key whose values are not all
numbers is plotted by category, in the order its values first appear in the study, each
labelled by what sets it apart (`category_labels`)."""
import json
import math
import textwrap
from pathlib import Path

#: A category's tick label: characters per line, and lines at most (then an ellipsis).
LABEL_WIDTH, LABEL_LINES = 22, 4


def _number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _flat(value, prefix=''):
    """A mapping's entries as {dotted key: value} (nested mappings flattened, as `--set`
    keys name them); any other value as {'': value}."""
    if not isinstance(value, dict) or not value:
        return {prefix: value}
    flat = {}
    for key, item in value.items():
        flat.update(_flat(item, f'{prefix}.{key}' if prefix else str(key)))
    return flat


def _identity(value):
    """A value's identity as a category (mappings equal whatever their keys' order)."""
    return json.dumps(value, sort_keys=True, default=str)


def _text(value):
    return value if isinstance(value, str) else json.dumps(value, default=str)


def category_labels(values):
    """Tick labels of a varied key's values (any JSON-like values, in their order): a string
    as it is, a number or a list as compact JSON, a mapping as key=value for only the
    entries (nested keys dotted) that are not the same in every mapping given; each wrapped
    at LABEL_WIDTH characters and cut to LABEL_LINES lines. Labels that would read alike
    are numbered."""
    flats = [_flat(v) for v in values]
    mappings = [f for f, v in zip(flats, values) if isinstance(v, dict)]
    keys = {k for f in mappings for k in f}
    shared = {k for k in keys if all(k in f and f[k] == mappings[0][k] for f in mappings)}
    labels = []
    for flat, value in zip(flats, values):
        if isinstance(value, dict):
            parts = [f'{k}={_text(v)}' for k, v in flat.items() if k not in shared]
            text = ', '.join(parts) or ', '.join(f'{k}={_text(v)}' for k, v in flat.items())
        else:
            text = _text(value)
        labels.append('\n'.join(textwrap.wrap(text, LABEL_WIDTH, max_lines=LABEL_LINES,
                                               placeholder=' ...') or ['""']))
    if len(set(labels)) < len(labels):
        labels = [f'({i + 1}) {label}' for i, label in enumerate(labels)]
    return labels


def plot_study(out_dir, study, rows):
    """Write DIR/plots/<metric>_vs_<key>.png for every metric and varied key; return the
    file names written."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    out = Path(out_dir) / 'plots'
    out.mkdir(parents=True, exist_ok=True)
    names = []
    for key in study.keys:
        values = [r[key] for r in rows]
        numeric = all(_number(v) for v in values if v is not None)
        categories = None
        if not numeric:  # each distinct value, first seen first
            categories = {}
            for value in values:
                if value is not None:
                    categories.setdefault(_identity(value), value)
        position = ((lambda v: v) if numeric else
                    (lambda v: list(categories).index(_identity(v))))
        for metric in study.metrics:
            good = [(position(r[key]), r[metric]) for r in rows
                    if r['stable'] and r[key] is not None and _number(r[metric])]
            bad = [position(r[key]) for r in rows if not r['stable'] and r[key] is not None]
            fig, ax = plt.subplots(figsize=(5.5, 4))
            if good:
                xs, ys = zip(*good)
                ax.plot(xs, ys, 'o', alpha=0.6, label='runs')
                means = {}
                for x, y in good:
                    means.setdefault(x, []).append(y)
                line = sorted((x, sum(v) / len(v)) for x, v in means.items())
                ax.plot(*zip(*line), '-', color='0.3', label='mean')
            if bad:
                low = min((y for _, y in good), default=0.0)
                ax.plot(bad, [low] * len(bad), 'x', color='red', label='not stable')
            if categories:
                ax.set_xticks(range(len(categories)),
                              category_labels(list(categories.values())), rotation=30,
                              ha='right', fontsize='small')
            ax.set_xlabel(key)
            ax.set_ylabel(metric)
            ax.set_title(f'{metric} against {key}')
            ax.grid(alpha=0.3)
            if good or bad:
                ax.legend(fontsize='small')
            fig.tight_layout()
            name = f'{metric}_vs_{key}.png'.replace('/', '_')
            fig.savefig(out / name, dpi=100)
            plt.close(fig)
            names.append(name)
    return names
