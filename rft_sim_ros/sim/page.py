"""A run's page: report.html in its folder, plain static HTML (inline CSS, no script, no
server, nothing fetched from elsewhere) that a browser opens from disk.

Sections (each a <section> with that id): `outcome` (stable or not and why, the fall, the
deepest body, the notices), `metrics` (the run's numbers with readable names and units:
labels.label), `video` (video.mp4 of the folder in a <video> element, when there is one),
`plots` (the folder's PNGs), `scene` (the scene as run: every key's effective value) and
`files` (a link to each file of the folder, the bag's included). Every text that comes from
a user (names, descriptions, values, file names) is escaped; links are relative, so the
folder can be moved or copied whole.

`html_page` and `table` are the building blocks the study's page (study/page.py) shares.
"""
import html
import json
import math
from pathlib import Path
from typing import NamedTuple
from urllib.parse import quote

from .labels import label, run_name
from .ways_down import DOWN, is_down

#: The page's own style (no external assets).
STYLE = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1200px;
       padding: 0 1em; color: #222; background: #fff; }
h1 { font-size: 1.5em; margin-bottom: 0.2em; }
h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; padding-bottom: 0.2em; }
table { border-collapse: collapse; margin: 0.5em 0; }
td, th { border: 1px solid #ddd; padding: 0.2em 0.6em; text-align: left;
         vertical-align: top; }
th { background: #f3f3f3; }
td.number { text-align: right; font-variant-numeric: tabular-nums; }
.ok { color: #176117; font-weight: bold; }
.bad { color: #a11; font-weight: bold; }
img, video { max-width: 100%; border: 1px solid #ddd; }
figure { display: inline-block; margin: 0.5em; vertical-align: top; }
code { background: #f3f3f3; padding: 0 0.2em; }
summary { cursor: pointer; margin: 0.5em 0; }
"""

#: The page's file name in a run (or study) folder.
PAGE = 'report.html'
#: The video a run writes into its folder (rft-sim run --video).
VIDEO = 'video.mp4'
#: Summary numbers shown first, in this order, when present.
KEY_NUMBERS = ('sim_time_s', 'wall_time_s', 'real_time_factor', 'zeta', 'zeta_final',
               'timestep_s', 'steps', 'plates_total', 'plates_active_mean')


def esc(value):
    """`value` as text safe inside HTML elements and attribute values."""
    return html.escape(str(value), quote=True)


def href(path):
    """A relative link to `path` (a str or Path relative to the page), percent-encoded."""
    return esc(quote(Path(path).as_posix()))


def number(value):
    """A value as a table shows it: floats to 4 significant digits, lists joined, None as
    a dash."""
    if value is None:
        return '-'
    if isinstance(value, bool):
        return 'yes' if value else 'no'
    if isinstance(value, float):
        return f'{value:.4g}' if math.isfinite(value) else str(value)
    if isinstance(value, (list, tuple)) and all(isinstance(v, (int, float)) for v in value):
        return ', '.join(number(v) for v in value)
    if isinstance(value, (dict, list, tuple)):
        return json.dumps(value, default=str)
    return str(value)


class Markup(NamedTuple):
    """A table cell already made HTML (escaped where it must be), with a CSS class."""
    html: str
    css: str = ''


def table(header, rows):
    """An HTML table: `header` names, `rows` lists of cells; a cell is a value (shown as
    `number` shows it, escaped) or Markup."""
    def cell(value, tag):
        if isinstance(value, Markup):
            return f'<{tag} class="{esc(value.css)}">{value.html}</{tag}>'
        is_number = isinstance(value, (int, float)) and not isinstance(value, bool)
        return (f'<{tag}{" class=number" if is_number else ""}>'
                f'{esc(number(value))}</{tag}>')
    head = ''.join(f'<th>{esc(name)}</th>' for name in header)
    body = ''.join('<tr>' + ''.join(cell(v, 'td') for v in row) + '</tr>' for row in rows)
    return f'<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>'


def html_page(title, sections):
    """A whole page: `title` (text) and `sections`, (id, heading, html) triples."""
    parts = [f'<section id="{esc(key)}"><h2>{esc(heading)}</h2>\n{markup}\n</section>'
             for key, heading, markup in sections]
    return ('<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
            f'<title>{esc(title)}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n'
            f'<h1>{esc(title)}</h1>\n' + '\n'.join(parts) + '\n</body>\n</html>\n')


def _files(folder):
    """Every file under `folder` (relative paths, sorted), the page itself left out."""
    return sorted(p.relative_to(folder) for p in folder.rglob('*')
                  if p.is_file() and p.name != PAGE)


def _size(path):
    size = path.stat().st_size
    for unit in ('B', 'KB', 'MB', 'GB'):
        if size < 1024 or unit == 'GB':
            return f'{size:.0f} {unit}' if unit == 'B' else f'{size:.1f} {unit}'
        size /= 1024


def _outcome(summary):
    """The outcome section's markup."""
    stable = summary.get('stable')
    lines = [f'<p class="{"ok" if stable else "bad"}">'
             f'{"stable" if stable else "not stable"}'
             + (' (interrupted)' if summary.get('interrupted') else '') + '</p>']
    if summary.get('reason'):
        lines.append(f'<p>reason: {esc(summary["reason"])}</p>')
    outcome = summary.get('outcome') or {}
    if outcome.get('words'):
        css = 'bad' if is_down(outcome) else 'ok'
        lines.append(f'<p class="{css}">{esc(outcome["words"])}</p>')
    rows = []
    if outcome:
        for _, key, said in DOWN:
            if outcome.get(key) is not None:
                rows.append([f'{said} at (s)', outcome[key]])
        for key, name in (('max_tilt_deg', 'largest base tilt (deg)'),
                          ('final_tilt_deg', 'final base tilt (deg)'),
                          ('tilt_limit_deg', 'tilt counted as a fall (deg)'),
                          ('stance_height_set_down_m', 'centre of mass above its sand bodies '
                                                       'as set down (m)'),
                          ('min_stance_height_m', 'lowest centre of mass above its sand '
                                                  'bodies (m)'),
                          ('max_base_depth_m', 'deepest point of the base in the sand (m)'),
                          ('final_base_speed_mps', 'final base speed (m/s)'),
                          ('unsettled_step_share', 'share of steps whose sand sets did '
                                                   'not settle'),
                          ('max_uncovered_sinkage_m', 'deepest body without plates (m)')):
            if key in outcome:
                rows.append([name, outcome[key]])
        deepest = outcome.get('deepest')
        if deepest:
            rows.append(['deepest body', f'{deepest.get("body")}: {number(deepest.get("sinkage_m"))}'
                         f' m at {number(deepest.get("time_s"))} s'
                         + ('' if deepest.get('has_plates', True) else ' (no plates)')])
    if rows:
        lines.append(table(['', ''], rows))
    notices = summary.get('notices') or []
    if notices:
        lines.append('<p>notices:</p><ul>' + ''.join(f'<li>{esc(n)}</li>' for n in notices)
                     + '</ul>')
    return '\n'.join(lines)


def _metrics(summary):
    rows = [[label(key), summary[key]] for key in KEY_NUMBERS if key in summary]
    markup = table(['run', 'value'], rows)
    scenario = summary.get('metrics') or {}
    if scenario:
        markup += table(["scenario's metrics", 'value'],
                        [[label(name), value] for name, value in scenario.items()])
    generic = summary.get('generic_metrics') or {}
    if generic:  # one row per sand body and leg: folded
        markup += ('<details><summary>metrics of every run (per sand body and leg)</summary>'
                   + table(['metric', 'value'],
                           [[label(name), value] for name, value in generic.items()])
                   + '</details>')
    return markup


def _video(folder):
    if (folder / VIDEO).is_file():
        return (f'<video src="{href(VIDEO)}" controls preload="metadata" width="960">'
                f'your browser does not play <a href="{href(VIDEO)}">{VIDEO}</a></video>')
    return f'<p>no {VIDEO} in this folder (<code>rft-sim run ... --video</code> makes one)</p>'


def _plots(folder):
    images = sorted(folder.glob('*.png'))
    if not images:
        return '<p>no plots in this folder</p>'
    return '\n'.join(f'<figure><img src="{href(p.name)}" alt="{esc(p.stem)}">'
                     f'<figcaption>{esc(p.name)}</figcaption></figure>' for p in images)


def _scene(summary):
    values = summary.get('scene_values') or {}
    markup = ''
    if summary.get('description'):
        markup += f'<p>{esc(summary["description"])}</p>'
    if summary.get('surface'):
        markup += f'<p>sand surface: <code>{esc(number(summary["surface"]))}</code></p>'
    return markup + table(['key', 'value as run'],
                          [[key, number(value)] for key, value in values.items()])


def _file_list(folder):
    files = _files(folder)
    if not files:
        return '<p>no files</p>'
    bag = [f for f in files if f.parts[0] == 'bag']
    lines = ['<ul>']
    if bag:
        lines.append(f'<li><a href="{href("bag")}">bag/</a> (rosbag2: '
                     '<code>ros2 bag info bag</code>)</li>')
    lines += [f'<li><a href="{href(f)}">{esc(f.as_posix())}</a> ({_size(folder / f)})</li>'
              for f in files]
    return '\n'.join(lines + ['</ul>'])


def run_page(folder, summary, extra=()):
    """The page of the run in `folder` (Path) with `summary` (its summary.json content; None
    for a run that raised); extra: (id, heading, html) sections put after the outcome."""
    folder = Path(folder)
    if summary is None:
        return html_page(f'run {folder.name}', [
            *extra, ('files', 'Files', _file_list(folder))])
    title = run_name(summary)
    return html_page(title, [
        ('outcome', 'Outcome', _outcome(summary)),
        *extra,
        ('metrics', 'Key metrics', _metrics(summary)),
        ('video', 'Video', _video(folder)),
        ('plots', 'Plots', _plots(folder)),
        ('scene', 'Scene as run', _scene(summary)),
        ('files', 'Files', _file_list(folder)),
    ])


def write_run_page(folder, summary, extra=()):
    """Write `folder`/report.html (`run_page`); returns its path. Call it again after
    adding files to the folder (a video rendered later) to list them."""
    path = Path(folder) / PAGE
    path.write_text(run_page(folder, summary, extra), encoding='utf-8')
    return path
