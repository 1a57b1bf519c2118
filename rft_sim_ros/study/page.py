"""A study's pages: DIR/report.html (the study: what varied, the results table with a link
to each run's page, the plots, the files) and DIR/runs/<id>/report.html for each run (the
run's page, sim/page.py, with what the study set for it and a link back). Plain static HTML
like the run's page; a study's runs record no time series, so their pages have no plots.
"""
import json
from pathlib import Path

from ..sim.labels import label
from ..sim.page import PAGE, Markup, esc, href, html_page, table, write_run_page

#: The study's own files the page links to, when present.
STUDY_FILES = ('study.yaml', 'results.csv', 'results.npz', 'study.json')


def _run_pages(out, rows):
    """Write each run's page from its runs/<id>/summary.json (those unreadable skipped)."""
    for row in rows:
        folder = Path(out) / 'runs' / row['run_id']
        try:
            saved = json.loads((folder / 'summary.json').read_text())
        except (OSError, ValueError):
            continue
        mark = saved.get('study_run') or {}
        cells = [[label(key), value] for key, value in (mark.get('varied') or {}).items()]
        cells += [['repeat', mark.get('repeat')], ['stable', mark.get('stable')],
                  ['reason', mark.get('reason') or ''], ['wall time (s)', mark.get('wall_time_s')],
                  ['worker', mark.get('worker')]]
        back = f'<p><a href="{href("../../" + PAGE)}">the study</a></p>'
        write_run_page(folder, saved.get('summary'),
                       extra=[('study-run', 'Study run', back + table(['', ''], cells))])


def write_study_page(out, study, rows, plots):
    """Write `out`/report.html and each run's page; rows: the results table's rows
    (table.row); plots: the file names under `out`/plots. Returns the page's path."""
    out = Path(out)
    _run_pages(out, rows)
    keys, metrics = list(study.keys), list(study.metrics)
    header = ['run', 'repeat', *map(label, keys), *map(label, metrics), 'wall time (s)',
              'stable', 'reason']
    body = []
    for row in rows:
        page = Path('runs') / row['run_id'] / PAGE
        run = (Markup(f'<a href="{href(page)}">{esc(row["run_id"])}</a>')
               if (out / page).is_file() else row['run_id'])
        stable = Markup('yes', 'ok') if row['stable'] else Markup('no', 'bad')
        body.append([run, row['repeat'], *(row[k] for k in keys), *(row[m] for m in metrics),
                     row['wall_time_s'], stable, row['reason']])
    failed = sum(not row['stable'] for row in rows)
    overview = (f'<p>{len(rows)} runs of scene <code>{esc(study.scene)}</code>, '
                f'{failed} not stable; varied: '
                + ', '.join(f'<code>{esc(k)}</code>' for k in keys) + '</p>')
    description = (getattr(study, 'source', None) or {}).get('description')
    if description:
        overview = f'<p>{esc(description)}</p>' + overview
    images = '\n'.join(f'<figure><img src="{href(Path("plots") / name)}" alt="{esc(name)}">'
                       '</figure>' for name in plots if (out / 'plots' / name).is_file())
    files = '<ul>' + ''.join(f'<li><a href="{href(name)}">{esc(name)}</a></li>'
                             for name in STUDY_FILES if (out / name).is_file()) + '</ul>'
    path = out / PAGE
    path.write_text(html_page(f'study of {study.scene}', [
        ('overview', 'Overview', overview),
        ('table', 'Results', table(header, body)),
        ('plots', 'Plots', images or '<p>no plots</p>'),
        ('files', 'Files', files),
    ]), encoding='utf-8')
    return path
