"""Plots of a study: each metric against each varied key (one PNG each, under DIR/plots/).
Stable runs as dots (the mean over the runs sharing a value joined by a line); runs that did
not stay stable as red crosses at the bottom of the axes."""
import math
from pathlib import Path


def _number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


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
        categories = sorted({repr(v) for v in values}) if not numeric else None
        position = (lambda v: v) if numeric else (lambda v: categories.index(repr(v)))
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
                ax.set_xticks(range(len(categories)), categories, rotation=30)
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
