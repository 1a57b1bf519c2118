"""report.html of a run and of a study (sim/page.py, study/page.py), read back with
html.parser: its sections, the video element when the folder has a video.mp4, the plots,
the links, and every user text escaped; and opened in headless Chromium, whose screenshot
must show a page."""
import json
import shutil
import subprocess
from html.parser import HTMLParser
from types import SimpleNamespace

import matplotlib
import numpy as np
import pytest

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402

from rft_sim_ros.sim.page import write_run_page  # noqa: E402
from rft_sim_ros.study.page import write_study_page  # noqa: E402

HOSTILE = '<script>alert("x")</script> & <b>'


class Page(HTMLParser):
    """What a page holds: section ids in order, the attributes of each element by tag, its
    text."""

    def __init__(self, text):
        super().__init__()
        self.sections, self.elements, self.text = [], {}, []
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        self.elements.setdefault(tag, []).append(attrs)
        if tag == 'section':
            self.sections.append(attrs['id'])

    def handle_data(self, data):
        self.text.append(data)

    @property
    def words(self):
        return ' '.join(self.text)

    def links(self):
        return [a['href'] for a in self.elements.get('a', [])]


def _png(path):
    fig, ax = plt.subplots(figsize=(3, 2))
    ax.plot([0, 1, 2], [0, 1, 0])
    fig.savefig(path)
    plt.close(fig)


def _summary(**changes):
    summary = {
        'scene': 'hexapod', 'description': f'a walk {HOSTILE}', 'zeta': 3.75,
        'timestep_s': 0.0008, 'sim_time_s': 6.0, 'wall_time_s': 20.0,
        'real_time_factor': 0.3, 'stable': True, 'interrupted': False, 'reason': None,
        'notices': [f'leg {HOSTILE} has no plates'],
        'metrics': {'forward_distance_m': 0.35},
        'generic_metrics': {'max_sinkage_m_L1_dactyl': 0.07, 'stable': True},
        'scene_values': {'zeta': 3.75, 'params.payload': 0.0, 'name': HOSTILE},
        'surface': {'type': 'plane', 'height_m': 0.0},
        'robot_model': {'name': 'hexapod', 'file': '/pkg/models/hexapod.xml'},
        'scene_config': {'model': 'hexapod.xml', 'scenario': 'hexapod'},
    }
    summary.update(changes)
    return summary


def _run_folder(folder, video=True):
    folder.mkdir(parents=True, exist_ok=True)
    (folder / 'summary.json').write_text('{}')
    (folder / 'timeseries.csv').write_text('time_s\n0\n')
    _png(folder / 'timeseries.png')
    (folder / 'bag').mkdir()
    (folder / 'bag' / 'bag_0.mcap').write_bytes(b'\0' * 10)
    (folder / 'bag' / 'metadata.yaml').write_text('{}')
    if video:
        (folder / 'video.mp4').write_bytes(b'\0' * 10)
    return folder


def test_a_run_page_has_its_sections_video_plots_and_links(tmp_path):
    folder = _run_folder(tmp_path / 'run one')            # (a space: links are encoded)
    page = write_run_page(folder, _summary())
    assert page == folder / 'report.html'
    parsed = Page(page.read_text())
    assert parsed.sections == ['outcome', 'metrics', 'video', 'plots', 'scene', 'files']
    video, = parsed.elements['video']
    assert video['src'] == 'video.mp4' and 'controls' in video
    assert [img['src'] for img in parsed.elements['img']] == ['timeseries.png']
    assert {'summary.json', 'timeseries.csv', 'bag', 'bag/bag_0.mcap', 'bag/metadata.yaml',
            'video.mp4', 'timeseries.png'} <= set(parsed.links())
    words = parsed.words
    assert 'hexapod.xml in scene hexapod' in words
    assert 'forward distance (m)' in words and 'sand stiffness zeta (N/cm³)' in words
    assert 'stable' in words


def test_a_run_page_escapes_what_users_wrote(tmp_path):
    folder = _run_folder(tmp_path / 'run')
    (folder / f'notes {HOSTILE}.txt'.replace('/', '_')).write_text('x')
    text = write_run_page(folder, _summary()).read_text()
    assert '<script>' not in text and '<b>' not in text
    parsed = Page(text)
    assert 'script' not in parsed.elements and 'b' not in parsed.elements
    assert parsed.words.count(HOSTILE) >= 3             # description, notice, scene value
    assert not any(link.startswith(('http', '//', 'javascript')) for link in parsed.links())


def test_a_run_page_without_a_video_says_so(tmp_path):
    folder = _run_folder(tmp_path / 'run', video=False)
    parsed = Page(write_run_page(folder, _summary()).read_text())
    assert 'video' not in parsed.elements and 'no video.mp4 in this folder' in parsed.words


def test_a_fall_is_the_first_thing_the_page_says(tmp_path):
    words = 'fell at t = 0.80 s: base turned 95 deg; lying on the sand'
    folder = _run_folder(tmp_path / 'run')
    summary = _summary(outcome={'fell': True, 'fell_at_s': 0.8, 'words': words,
                                'max_tilt_deg': 95.0, 'deepest': {
                                    'body': 'base_link', 'sinkage_m': 0.05, 'time_s': 1.0,
                                    'has_plates': False}})
    parsed = Page(write_run_page(folder, summary).read_text())
    outcome = parsed.words.split('Key metrics')[0]
    assert words in outcome and 'fell at (s)' in outcome
    assert 'base_link: 0.05 m at 1 s (no plates)' in outcome


def test_a_study_page_links_each_runs_page_and_shows_its_plots(tmp_path):
    from rft_sim_ros.study.plots import plot_study
    study = SimpleNamespace(scene='hexapod', keys=('zeta', 'payload'),
                            metrics=('forward_distance_m',), source={'description': HOSTILE})
    rows = []
    for i, (zeta, payload) in enumerate([(1.0, 0.0), (1.0, 1.0), (3.75, 0.0), (3.75, 1.0)]):
        run_id = f'{i:03d}'
        stable = i != 3
        summary = _summary(zeta=zeta) if stable else None
        (tmp_path / 'runs' / run_id).mkdir(parents=True)
        (tmp_path / 'runs' / run_id / 'summary.json').write_text(json.dumps({
            'study_run': {'run_id': run_id, 'varied': {'zeta': zeta, 'payload': payload},
                          'repeat': 0, 'stable': stable,
                          'reason': None if stable else 'error: RuntimeError: boom'},
            'summary': summary}))
        rows.append({'run_id': run_id, 'repeat': 0, 'zeta': zeta, 'payload': payload,
                     'forward_distance_m': 0.3 - 0.1 * payload if stable else None,
                     'wall_time_s': 10.0, 'stable': stable,
                     'reason': '' if stable else 'error: RuntimeError: boom'})
    (tmp_path / 'results.csv').write_text('run_id\n')
    plots = plot_study(tmp_path, study, rows)
    plt.close('all')
    parsed = Page(write_study_page(tmp_path, study, rows, plots).read_text())
    assert parsed.sections == ['overview', 'table', 'plots', 'files']
    runs = [link for link in parsed.links() if link.startswith('runs/')]
    assert runs == [f'runs/{i:03d}/report.html' for i in range(4)]
    for link in runs:
        run_page = Page((tmp_path / link).read_text())
        assert 'study-run' in run_page.sections and '../../report.html' in run_page.links()
    assert 'error: RuntimeError: boom' in Page((tmp_path / runs[3]).read_text()).words
    assert sorted(img['src'] for img in parsed.elements['img']) == sorted(
        f'plots/{name}' for name in plots)
    assert 'sand stiffness zeta (N/cm³)' in parsed.words and 'payload (kg)' in parsed.words
    assert '<script>' not in (tmp_path / 'report.html').read_text()
    assert 'results.csv' in parsed.links()


CHROMIUM = shutil.which('chromium') or shutil.which('chromium-browser')


#: The colours of the test's video (its every frame) and plot, told apart in the screenshot.
VIDEO_RGB, PLOT_RGB = (20, 200, 60), (230, 0, 230)


def _pixels_of(shot, rgb, tolerance=40):
    """How many pixels of the screenshot (floats in [0, 1]) have the colour `rgb` (0-255)."""
    return int((np.abs(shot * 255 - np.array(rgb)) < tolerance).all(axis=2).sum())


@pytest.mark.skipif(CHROMIUM is None, reason='chromium is not installed (apt-get install '
                                              'chromium): the page is not opened in a browser')
def test_headless_chromium_shows_the_page_with_its_video_and_plots(tmp_path):
    """The page opened in headless Chromium, a real H.264 video (every frame green) and a
    plot (magenta) in its folder: the screenshot shows the video's frame and the plot."""
    av = pytest.importorskip('av')  # (the video is written with the package's encoder)
    del av
    from rft_sim_ros.render.encoder import Mp4Writer
    folder = _run_folder(tmp_path / 'run', video=False)
    with Mp4Writer(folder / 'video.mp4', 320, 240, 25) as video:
        video.write(np.tile(np.array(VIDEO_RGB, np.uint8), (240, 320, 1)), repeat=25)
    plt.imsave(folder / 'timeseries.png', np.tile(np.array(PLOT_RGB, np.uint8), (200, 300, 1)))
    page = write_run_page(folder, _summary())
    shot = tmp_path / 'shot.png'
    flags = [CHROMIUM, '--headless', '--no-sandbox', '--disable-gpu',
             '--disable-background-networking', '--disable-component-update',
             '--disable-sync', '--no-first-run', f'--user-data-dir={tmp_path / "profile"}',
             '--window-size=1000,2400']  # (the video fills the page's width)
    url = page.resolve().as_uri()                         # a file URL: nothing fetched
    for _ in range(3):  # (headless Chromium decodes media apart from its virtual time: the
        # first frame is sometimes not painted yet when the screenshot is taken)
        subprocess.run([*flags, '--virtual-time-budget=10000', f'--screenshot={shot}', url],
                       check=True, timeout=120, capture_output=True)
        if _pixels_of(plt.imread(shot)[..., :3], VIDEO_RGB) > 0.3 * 320 * 240:
            break
    dom = subprocess.run([*flags, '--dump-dom', url], check=True, timeout=120,
                         capture_output=True, text=True).stdout
    parsed = Page(dom)                                    # what the browser made of it
    assert parsed.sections == ['outcome', 'metrics', 'video', 'plots', 'scene', 'files']
    assert parsed.elements['video'][0]['src'] == 'video.mp4'
    assert parsed.elements['img'][0]['src'] == 'timeseries.png'
    pixels = plt.imread(shot)[..., :3]
    assert pixels.shape[:2] == (2400, 1000)
    assert _pixels_of(pixels, VIDEO_RGB) > 0.3 * 320 * 240   # the video's frame, decoded
    assert _pixels_of(pixels, PLOT_RGB) > 0.3 * 300 * 200    # the plot
    ink = np.any(pixels < 0.9, axis=2)                    # not blank: text, tables, a plot
    assert 0.01 < ink.mean() < 0.9
