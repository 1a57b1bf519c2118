"""Plots a user reads: titled, legends off the data, nothing clipped, labels that do not
overlap, axes from zero where a trend is small. Checked on the figures themselves."""
from types import SimpleNamespace

import matplotlib
import numpy as np
import pytest

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402

from rft_sim_ros.bench import report as bench_report  # noqa: E402
from rft_sim_ros.validation import plots  # noqa: E402


@pytest.fixture
def figures(monkeypatch):
    """The figures the validation plots would save, kept open for inspection."""
    kept = []
    monkeypatch.setattr(plots, '_save', lambda fig, out, name: kept.append(fig) or name)
    yield kept
    for fig in kept:
        plt.close(fig)


def _data_points(ax):
    """(n, 2) display coordinates of every plotted line's points."""
    points = [line.get_transform().transform(line.get_xydata()) for line in ax.get_lines()
              if len(line.get_xydata()) > 1 or line.get_marker() not in ('None', None, '')]
    return np.vstack(points)


def _legend_covers(fig, ax):
    fig.canvas.draw()
    box = ax.get_legend().get_window_extent(fig.canvas.get_renderer())
    x, y = _data_points(ax).T
    return np.any((x > box.x0) & (x < box.x1) & (y > box.y0) & (y < box.y1))


def test_torque_plot_is_titled_and_its_legend_leaves_the_curves_free(figures):
    angle = np.linspace(0.0, np.pi, 181)
    hump = 2.4 * np.sin(angle) ** 2                      # the shape of the measured curves
    torque = {speed: SimpleNamespace(series={'angle_rad': angle, 'servo_torque_Nm': hump + 0.1,
                                             'air_torque_Nm': np.full_like(angle, 0.1)})
              for speed in (0.5, 1.0, 2.0)}
    plots.torque_vs_angle(None, torque)
    fig, = figures
    ax = fig.axes[0]
    assert ax.get_title()
    assert not _legend_covers(fig, ax)


def test_rail_speed_plot_is_titled_and_keeps_its_top_series_inside(figures):
    values = {'flat': 0.1058, 'open_c': 0.0845, 'closed_c': 0.098}
    rails = {(shape, v): SimpleNamespace(metrics={'carriage_displacement_m': value})
             for shape, value in values.items() for v in (0.5, 1.0, 2.0)}
    plots.rail_displacement_vs_speed(None, rails, (0.5, 1.0, 2.0))
    fig, = figures
    ax = fig.axes[0]
    assert ax.get_title()
    assert ax.get_ylim()[0] == 0 and ax.get_ylim()[1] > 1.05 * 100 * max(values.values())
    assert not _legend_covers(fig, ax)


def test_speed_against_payload_starts_at_zero_and_labels_the_derived_point(figures):
    payloads, zetas = (0.0, 1.0, 2.277), (3.75, 5.0)
    hexapod = {(z, p): SimpleNamespace(metrics={'mean_speed_mps': 0.0706 - 0.001 * p})
               for z in zetas for p in payloads}
    plots.hexapod_speed_vs_payload(None, hexapod, zetas, payloads)
    fig, = figures
    ax = fig.axes[0]
    assert ax.get_ylim()[0] == 0                          # 3 % looks like 3 %
    assert any('derived' in text.get_text() for text in ax.get_legend().get_texts())
    assert not _legend_covers(fig, ax)


def test_pareto_labels_do_not_overlap_and_stay_in_their_panel():
    rng = np.random.default_rng(0)
    fig, ax = plt.subplots(figsize=(4.6, 4.0))
    x, y = 10 ** rng.uniform(-2, -1.5, 30), 10 ** rng.uniform(-3, -2.8, 30)  # crowded
    ax.scatter(x, y)
    ax.set_xscale('log')
    ax.set_yscale('log')
    boxes = bench_report._label_without_overlap(
        fig, ax, [(f'{1000 + i}/0.25', xi, yi) for i, (xi, yi) in enumerate(zip(x, y))])
    panel = ax.get_window_extent(fig.canvas.get_renderer())
    assert 3 <= len(boxes) < 30                           # some placed, the crowd left out
    for i, box in enumerate(boxes):
        assert panel.x0 <= box.x0 and box.x1 <= panel.x1
        assert not any(box.overlaps(other) for other in boxes[i + 1:])
    plt.close(fig)


def test_a_study_plot_labels_mapping_values_by_what_sets_them_apart(monkeypatch, tmp_path):
    from rft_sim_ros.study.plots import category_labels, plot_study
    surfaces = [{'type': 'plane'}, {'type': 'slope', 'angle_deg': 10.0},
                {'type': 'grid', 'file': '/data/terrain/dunes_' + 'x' * 60 + '.npy',
                 'size': [2.0, 2.0]}]
    labels = category_labels(surfaces)
    assert labels[:2] == ['type=plane', 'type=slope,\nangle_deg=10.0']
    assert labels[2].startswith('type=grid, file=') and labels[2].endswith('...')
    assert max(len(line) for label in labels for line in label.split('\n')) <= 22
    # entries the same in every value are left out; values that would read alike numbered
    assert category_labels([{'a': 1, 'b': {'c': 2}}, {'a': 1, 'b': {'c': 3}}]) == ['b.c=2',
                                                                                  'b.c=3']
    assert category_labels(['x' * 100 + 'A', 'x' * 100 + 'B'])[0].startswith('(1) ')
    assert category_labels([0.5, 'heavy', [1, 2]]) == ['0.5', 'heavy', '[1, 2]']
    kept = []
    monkeypatch.setattr(plt, 'close', kept.append)
    study = SimpleNamespace(keys=['sand.surface'], metrics=['mean_speed_mps'])
    order = [surfaces[2], surfaces[0], surfaces[1]]       # the study's order, kept on the axis
    rows = [{'sand.surface': s, 'mean_speed_mps': v, 'stable': True}
            for s, v in zip(order + order[::-1], [0.05, 0.07, 0.06, 0.061, 0.071, 0.052])]
    plot_study(tmp_path, study, rows)
    fig = kept[0]
    ax = fig.axes[0]
    fig.canvas.draw()
    ticks = ax.get_xticklabels()
    assert [t.get_text() for t in ticks] == category_labels(order)
    renderer = fig.canvas.get_renderer()
    boxes = [t.get_window_extent(renderer) for t in ticks]
    figure_box = fig.bbox
    for box in boxes:                                     # inside the saved figure
        assert box.x0 >= figure_box.x0 - 1 and box.y0 >= figure_box.y0 - 1
    plt.close(fig)


def test_a_study_plot_names_its_axes_with_units_and_colours_the_second_key(monkeypatch,
                                                                           tmp_path):
    from rft_sim_ros.study.plots import plot_study
    kept = []
    monkeypatch.setattr(plt, 'close', kept.append)
    study = SimpleNamespace(keys=['zeta', 'payload'], metrics=['forward_distance_m'])
    rows = [{'zeta': z, 'payload': p, 'forward_distance_m': 0.1 * z - 0.05 * p,
             'stable': (z, p) != (5.0, 2.0)}
            for z in (1.0, 3.75, 5.0) for p in (0.0, 1.0, 2.0)]
    names = plot_study(tmp_path, study, rows)
    assert names == ['forward_distance_m_vs_zeta.png', 'forward_distance_m_vs_payload.png']
    against_zeta, against_payload = kept
    ax = against_zeta.axes[0]
    assert ax.get_xlabel() == 'sand stiffness zeta (N/cm³)'
    assert ax.get_ylabel() == 'forward distance (m)'
    legend = ax.get_legend()
    assert legend.get_title().get_text().startswith('payload (kg)')
    entries = [t.get_text() for t in legend.get_texts()]
    assert entries == ['0.0', '1.0', '2.0', 'not stable']
    lines = {line.get_label(): line for line in ax.get_lines()}
    colours = [lines[entry].get_color() for entry in entries[:3]]
    assert len(set(colours)) == 3                         # one colour per payload
    # each payload's line joins its own runs: payload 2 has no stable run at zeta 5
    assert list(lines['2.0'].get_xdata()) == [1.0, 3.75]
    assert list(lines['0.0'].get_ydata()) == pytest.approx([0.1, 0.375, 0.5])
    against_zeta.canvas.draw()
    renderer = against_zeta.canvas.get_renderer()
    box = legend.get_window_extent(renderer)
    assert not box.overlaps(ax.get_window_extent(renderer))     # beside the axes
    assert against_zeta.bbox.contains(box.x1, box.y0)           # and inside the image
    assert against_payload.axes[0].get_legend().get_title().get_text().startswith(
        'sand stiffness zeta')
    monkeypatch.undo()
    for fig in kept:
        plt.close(fig)
