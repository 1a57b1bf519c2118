"""The run's figure (sim/plots.plot_run) read back from its matplotlib objects: what each
panel shows and says, legends clear of every panel, a landing's spike kept from squashing
the gait's forces, the fall marked, the title naming the robot and the scene."""
import math

import matplotlib
import numpy as np
import pytest

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402

from rft_sim_ros.sim import plots  # noqa: E402
from rft_sim_ros.sim.series import joint_columns, roll_pitch_yaw  # noqa: E402

#: Leg names as a hexapod from a ROS package gives them (auto legs: the limbs' first links).
LEGS = [f'{side}_{place}_leg_coxa_link' for side in ('left', 'right')
        for place in ('front', 'middle', 'rear')]
LANDING_N, GAIT_N = 95.0, 20.0


def _summary(outcome=None, joints=True, model='/ws/src/my_hexapod/urdf/hexapod.urdf.xacro',
             name='my_hexapod', scene='hexapod', scenario='external'):
    owners = {}
    if joints:
        owners = {f'{leg}_{part}_joint': leg for leg in LEGS for part in ('hip', 'knee')}
        owners['spine_joint'] = None
    summary = {'scene': scene, 'zeta': 3.75, 'timestep_s': 0.001, 'stable': True,
               'reason': None, 'schedule': [], 'legs': {leg: [leg] for leg in LEGS},
               'joint_legs': owners, 'robot_model': {'name': name, 'file': model},
               'surface': {'type': 'plane', 'height_m': 0.0},
               'scene_config': {'model': model, 'scenario': scenario}}
    if outcome is not None:
        summary['outcome'] = outcome
    return summary


def _series(summary, seconds=3.0, rate=100):
    rows = []
    for t in np.arange(0.0, seconds, 1.0 / rate):
        row = {'time_s': t, 'base_x_m': 0.05 * t, 'base_y_m': 0.0, 'base_z_m': 0.1,
               'base_roll_rad': 0.01, 'base_pitch_rad': 0.02, 'base_yaw_rad': 0.1 * t,
               'base_speed_mps': 0.05, 'plates_active': 100}
        for i, leg in enumerate(LEGS):
            gait = GAIT_N * max(0.0, math.sin(2 * math.pi * t + i * math.pi / 3))
            row[f'force_z_N_{leg}'] = LANDING_N if 0.10 <= t < 0.13 else gait
            row[f'sinkage_m_{leg}'] = 0.004 * max(0.0, math.sin(2 * math.pi * t))
        for joint, leg in summary['joint_legs'].items():
            angle, torque = joint_columns(joint, True)
            row[angle], row[torque] = 0.3 * math.sin(2 * math.pi * t), 0.5
        rows.append(row)
    return rows


def _draw(tmp_path, summary, series=None):
    """plot_run(summary, series) -> its Figure, drawn, kept open for inspection."""
    kept = []
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(plots.plt, 'close', kept.append)
        plots.plot_run(tmp_path / 'run.png', series or _series(summary), summary)
    assert (tmp_path / 'run.png').stat().st_size > 10_000
    fig, = kept
    fig.canvas.draw()
    return fig


@pytest.fixture
def figure(tmp_path):
    yield lambda summary, series=None: _draw(tmp_path, summary, series)
    plt.close('all')


FALL = 'fell at t = 0.80 s: base turned 95 deg; lying on the sand'


@pytest.fixture(scope='module')
def hexapod_figure(tmp_path_factory):
    """A six-legged robot's figure (long leg names, a landing spike, a fall), drawn once
    (a figure of 28 panels costs seconds)."""
    fig = _draw(tmp_path_factory.mktemp('figure'), _summary(outcome={
        'fell': True, 'fell_at_s': 0.8, 'words': FALL, 'max_tilt_deg': 95.0}))
    yield fig
    plt.close(fig)


def _axes(fig):
    """Every visible Axes of the figure, its subfigures' included."""
    found = list(fig.axes)
    for sub in fig.subfigs:
        found += _axes(sub)
    return [ax for ax in found if ax.get_visible()]


def _panel(fig, title):
    return next(ax for ax in _axes(fig) if ax.get_title().startswith(title))


def _legends(fig):
    return [ax.get_legend() for ax in _axes(fig) if ax.get_legend() is not None]


def test_panels_name_what_they_show_with_units(hexapod_figure):
    fig = hexapod_figure
    titles = [ax.get_title() for ax in _axes(fig)]
    labels = {ax.get_title().split(' (')[0]: ax.get_ylabel() for ax in _axes(fig)}
    assert labels['base position'] == 'position (m)'
    assert labels['base attitude'] == 'angle (deg)'
    assert labels['vertical sand force per foot'] == 'force (N)'
    assert labels['foot sinkage below the sand surface'] == 'sinkage (mm)'
    for leg in LEGS:  # a panel pair per leg, angles in degrees
        assert labels[f'leg {leg}: joint positions'] == 'angle (deg)'
        assert labels[f'leg {leg}: joint torques'] == 'torque (N m)'
    assert 'other joints: joint positions' in titles       # the spine: no leg of its own
    assert not any('plates' in text for ax in _axes(fig)
                   for text in (ax.get_title(), ax.get_ylabel()))
    attitude = _panel(fig, 'base attitude')
    assert [line.get_label() for line in attitude.get_lines()][:3] == ['roll', 'pitch', 'yaw']
    assert np.allclose(attitude.get_lines()[0].get_ydata(), math.degrees(0.01))
    sinkage = _panel(fig, 'foot sinkage')
    assert max(max(line.get_ydata()) for line in sinkage.get_lines()) == pytest.approx(4.0)
    hip = _panel(fig, f'leg {LEGS[0]}: joint positions')
    assert [t.get_text() for t in hip.get_legend().get_texts()] == ['hip_joint', 'knee_joint']


def test_legends_lie_outside_every_panel(hexapod_figure):
    fig = hexapod_figure
    renderer = fig.canvas.get_renderer()
    boxes = [ax.get_window_extent(renderer) for ax in _axes(fig)]
    legends = _legends(fig)
    assert len(legends) >= 3 + len(LEGS)
    for legend in legends:
        box = legend.get_window_extent(renderer)
        assert not any(box.overlaps(panel) for panel in boxes), legend.get_texts()[0]
        assert fig.bbox.contains(box.x0, box.y0) and fig.bbox.contains(box.x1, box.y1)
    leg_names = [t.get_text() for t in _panel(fig, 'foot sinkage').get_legend().get_texts()]
    assert leg_names == LEGS


def test_a_landing_spike_leaves_the_gaits_forces_readable(hexapod_figure):
    force = _panel(hexapod_figure, 'vertical sand force per foot')
    low, high = force.get_ylim()
    assert GAIT_N < high < 0.5 * LANDING_N and low <= 0.0
    assert 'landing peak 95 N at 0.10 s, off the axis' in force.get_title()


def test_forces_without_a_spike_show_their_whole_range(figure):
    summary = _summary()
    series = _series(summary)
    for row in series:
        for leg in LEGS:
            row[f'force_z_N_{leg}'] = min(row[f'force_z_N_{leg}'], GAIT_N)
    force = _panel(figure(summary, series), 'vertical sand force per foot')
    assert force.get_ylim()[1] >= GAIT_N and 'peak' not in force.get_title()


def test_a_plate_drops_570_N_landing_is_clipped_over_its_resting_weight():
    t = np.arange(0.0, 2.0, 0.01)
    force = np.where(t < 0.05, 570.0 * np.sin(np.pi * t / 0.05), 9.81)
    low, high = plots.force_axis(force)
    assert low == 0.0 and 9.81 < high < 20.0


def test_the_fall_is_marked_on_every_time_panel(hexapod_figure):
    fig = hexapod_figure
    for ax in _axes(fig):
        marks = [line for line in ax.get_lines() if line.get_color() == 'red']
        assert len(marks) == 1 and list(marks[0].get_xdata()) == [0.8, 0.8], ax.get_title()
    position = _panel(fig, 'base position')
    assert 'fell at 0.80 s' in [t.get_text() for t in position.get_legend().get_texts()]
    assert FALL in fig.get_suptitle()


def test_the_title_names_the_robot_and_the_scene():
    from rft_sim_ros.sim.labels import run_name
    menagerie = _summary(model='/home/u/mujoco_menagerie/unitree_go2/scene.xml',
                         name='go2 scene', scene='unitree_go2')
    assert run_name(menagerie) == 'go2 scene (unitree_go2/scene.xml)'
    assert run_name(_summary()) == 'my_hexapod (hexapod.urdf.xacro)'
    bundled = _summary(model='/pkg/models/hexapod.xml', name='hexapod', scene='hexapod',
                       scenario='hexapod')
    assert run_name(bundled) == 'hexapod.xml in scene hexapod'
    drop = _summary(model='/pkg/models/plate.xml', name='plate', scene='plate_drop',
                    scenario='plate_drop')
    assert run_name(drop) == 'plate.xml in scene plate_drop'


def _no_fall_marked(fig):
    return not any(line.get_color() == 'red' for ax in _axes(fig) for line in ax.get_lines())


def test_the_figure_title_has_the_robot_zeta_and_timestep_and_no_fall(figure):
    summary = _summary(model='/home/u/mujoco_menagerie/unitree_go2/scene.xml',
                       name='go2 scene', scene='unitree_go2',
                       outcome={'fell': False, 'fell_at_s': None, 'words': 'stayed upright'})
    summary['schedule'] = [{'time_s': 1.5, 'zeta': 1.0, 'applied': True},
                           {'time_s': 99.0, 'zeta': 2.0, 'applied': False}]
    fig = figure(summary)
    title = fig.get_suptitle()
    assert title.startswith('go2 scene (unitree_go2/scene.xml)\n') and 'scene:' not in title
    assert 'zeta = 3.75 N/cm$^3$, 1 from 1.5 s, dt = 1 ms' in title and '99' not in title
    assert 'stayed upright' in title and _no_fall_marked(fig)
    position = _panel(fig, 'base position')
    assert 'zeta = 1 from 1.5 s' in [t.get_text() for t in position.get_legend().get_texts()]


def test_a_robot_without_joints_or_outcome_gets_the_four_base_and_foot_panels(figure):
    fig = figure(_summary(joints=False))                 # (no `outcome`: an older summary)
    assert len(_axes(fig)) == 4 and _no_fall_marked(fig)


def test_roll_pitch_yaw_of_a_quaternion():
    half = math.radians(30) / 2
    assert roll_pitch_yaw([math.cos(half), math.sin(half), 0, 0]) == pytest.approx(
        (math.radians(30), 0, 0))
    assert roll_pitch_yaw([math.cos(half), 0, math.sin(half), 0]) == pytest.approx(
        (0, math.radians(30), 0))
    assert roll_pitch_yaw([math.cos(half), 0, 0, math.sin(half)]) == pytest.approx(
        (0, 0, math.radians(30)))


def test_a_long_outcome_is_wrapped_inside_the_figure(figure):
    """An outcome of several findings (the main job's: the deepest point, frozen plates) is
    wrapped onto lines the title's width holds, all of it inside the figure."""
    words = ('upright: base turned at most 3 deg; deepest: R2_dactyl 10.7 cm below the '
             'surface at t = 1.80 s; in 40 % of steps the implicit solve froze plates whose '
             'leading/trailing sets cycled (at rest, or turning slowly in the sand): they took '
             'a linear response through their speed, not RFT\'s switch')
    fig = figure(_summary(outcome={'fell': False, 'fell_at_s': None, 'words': words}))
    title = fig._suptitle
    assert ' '.join(title.get_text().split()).endswith(' '.join(words.split()))
    assert max(len(line) for line in title.get_text().splitlines()) <= plots.TITLE_WIDTH
    box = title.get_window_extent(fig.canvas.get_renderer())
    assert 0 <= box.x0 and box.x1 <= fig.bbox.width
