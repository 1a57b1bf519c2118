"""Plots of a study: each metric against each varied key (one PNG each, under DIR/plots/),
axes named with units (sim/labels.py). Stable runs as dots, a colour per value of the study's
next varied key (the mean over the runs sharing both values joined by a line); runs that did
not stay stable as red crosses at the bottom of the axes. A key whose values are not all
numbers is plotted by category, in the order its values first appear in the study, each
labelled by what sets it apart (`category_labels`)."""
import json
import math
import textwrap
from pathlib import Path

from ..sim.labels import label

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


def _distinct(values):
    """{identity: value} of the values that are not None, first seen first."""
    found = {}
    for value in values:
        if value is not None:
            found.setdefault(_identity(value), value)
    return found


def plot_study(out_dir, study, rows):
    """Write DIR/plots/<metric>_vs_<key>.png for every metric and varied key; return the
    file names written. Axes carry readable names with units (sim/labels.py); with two or
    more varied keys, the runs get one colour per value of the next key (after the plotted
    one, cyclically), each colour's mean joined by a line, the legend right of the axes."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    out = Path(out_dir) / 'plots'
    out.mkdir(parents=True, exist_ok=True)
    names = []
    keys = list(study.keys)
    for k, key in enumerate(keys):
        values = [r[key] for r in rows]
        numeric = all(_number(v) for v in values if v is not None)
        categories = None if numeric else _distinct(values)
        position = ((lambda v: v) if numeric else
                    (lambda v: list(categories).index(_identity(v))))
        colour_key = keys[(k + 1) % len(keys)] if len(keys) > 1 else None
        shades = _distinct(r[colour_key] for r in rows) if colour_key else {'': None}
        shade_names = (category_labels(list(shades.values())) if colour_key else ['runs'])
        cmap = plt.get_cmap('tab10' if len(shades) <= 10 else 'viridis')
        for metric in study.metrics:
            fig, ax = plt.subplots(figsize=(7.5, 4.2), layout='constrained')
            plotted = []
            for i, (identity, shade_name) in enumerate(zip(shades, shade_names)):
                colour = cmap(i % 10) if len(shades) <= 10 else cmap(i / (len(shades) - 1))
                good = [(position(r[key]), r[metric]) for r in rows
                        if r['stable'] and r[key] is not None and _number(r[metric])
                        and (colour_key is None or _identity(r[colour_key]) == identity)]
                if not good:
                    continue
                plotted += [y for _, y in good]
                xs, ys = zip(*good)
                means = {}
                for x, y in good:
                    means.setdefault(x, []).append(y)
                line = sorted((x, sum(v) / len(v)) for x, v in means.items())
                ax.plot(xs, ys, 'o', alpha=0.6, color=colour)
                ax.plot(*zip(*line), '-o', color=colour, markersize=3,
                        label=shade_name.replace('\n', ' '))
            bad = [position(r[key]) for r in rows if not r['stable'] and r[key] is not None]
            if bad:
                low = min(plotted, default=0.0)
                ax.plot(bad, [low] * len(bad), 'x', color='red', label='not stable')
            if categories:
                ax.set_xticks(range(len(categories)),
                              category_labels(list(categories.values())), rotation=30,
                              ha='right', fontsize='small')
            ax.set_xlabel(label(key))
            ax.set_ylabel(label(metric))
            ax.set_title(f'{label(metric)}\nagainst {label(key)}', fontsize='medium')
            ax.grid(alpha=0.3)
            if ax.get_legend_handles_labels()[0]:
                ax.legend(title=(label(colour_key) + ' (mean line)' if colour_key
                                 else 'mean line'),
                          loc='upper left', bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0,
                          fontsize='small', title_fontsize='small')
            name = f'{metric}_vs_{key}.png'.replace('/', '_')
            fig.savefig(out / name, dpi=100)
            plt.close(fig)
            names.append(name)
    return names
