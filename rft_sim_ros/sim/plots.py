"""Plots of a headless run (PNG, matplotlib's Agg backend, no display): the run's figure
(`plot_run`) and the map of a deformed bed (`plot_surface`).

The run's figure, against sim time, from the time series (sim/series.py) and the summary:
  first row    base position x, y, z (m; the sand surface's level dotted when it is a plane)
               | base roll, pitch, yaw (deg)
  second row   vertical sand force per foot (N) | sinkage per foot below the surface (mm),
               a colour per leg in both, the legs' legend right of the row
  then         per leg, its joints' angles (deg; slide joints mm) above their torques (N m;
               slide joints N), up to three legs a row, each leg's legend right of its
               panels (joints that move several legs, such as a spine's, under 'other
               joints'); none for a robot without joints
Every legend lies outside the axes. A landing's spike (a drop's impact: 95 N on a hexapod
walking at 0-20 N a foot) would squash the gait's forces, so when the largest force is over
CLIP_RATIO times the FORCE_QUANTILE of all of them, the force axis stops at FORCE_HEADROOM
times that quantile and the panel says the peak it leaves off ('landing peak 95 N at 0.12 s,
off the axis'). Scheduled changes (--set-at) are dashed lines on every panel, the times the
outcome saw the robot go down (a fall, upside down, a collapse, sinking: sim/ways_down.py)
red lines; all named in the legend of the first panel
and in the title, which names the robot and the scene (labels.run_name).
"""
import math
import os
import textwrap

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402  (backend must be chosen first)
import numpy as np  # noqa: E402

from .labels import run_name  # noqa: E402
from .ways_down import DOWN  # noqa: E402
from .series import joint_columns  # noqa: E402

#: The force axis's clipping (module docstring): quantile of the forces, ratio of the peak
#: to it that clips, and the axis's top as a multiple of it.
FORCE_QUANTILE, CLIP_RATIO, FORCE_HEADROOM = 0.95, 3.0, 1.5
#: The least range of an angle axis, deg (below it, noise would fill the panel).
LEAST_ANGLE_DEG = 2.0
#: Legs side by side in the joints' rows; the figure's grid columns (a multiple of 2 and
#: of every count of legs a row).
LEGS_PER_ROW, GRID_COLUMNS = 3, 6
#: The most characters a line of the figure's title holds (its 15 in width); a longer one (an
#: outcome's words) is wrapped, not cut off at the figure's edges.
TITLE_WIDTH = 150
#: Where a legend goes: right of its axes, outside.
OUTSIDE = dict(loc='upper left', bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0,
               fontsize='small')


def force_axis(forces):
    """(low, high) N of the force axis when its largest force is a spike over CLIP_RATIO x
    the FORCE_QUANTILE of |forces| (module docstring); None: the whole range is shown."""
    values = np.abs(np.asarray(forces, dtype=float))
    values = values[np.isfinite(values)]
    if not values.size:
        return None
    typical = float(np.quantile(values, FORCE_QUANTILE))
    if typical <= 0 or values.max() <= CLIP_RATIO * typical:
        return None
    top = FORCE_HEADROOM * typical
    low = min(0.0, float(np.nanmin(np.asarray(forces, dtype=float))))
    return max(low, -top), top


def _at_least(axis, span):
    """Widen `axis`'s y range to at least `span` about its middle, so that float noise (a
    plate's roll of 1e-16 deg) is not drawn as a signal."""
    low, high = axis.get_ylim()
    if high - low < span:
        middle = 0.5 * (low + high)
        axis.set_ylim(middle - 0.5 * span, middle + 0.5 * span)


def _column(series, name):
    return np.array([row[name] for row in series], dtype=float)


def _leg_colours(legs):
    cmap = plt.get_cmap('tab10' if len(legs) <= 10 else 'tab20')
    return {leg: cmap(i % cmap.N) for i, leg in enumerate(legs)}


def _short_names(joints):
    """Legend names of one leg's joints: their common prefix up to an underscore dropped
    (fl_hip_joint, fl_knee_joint -> hip_joint, knee_joint)."""
    if len(joints) < 2:
        return list(joints)
    common = len(os.path.commonprefix(list(joints)))
    cut = max((joints[0].rfind(sep, 0, common) + 1 for sep in '_-.'), default=0)
    names = [j[cut:] for j in joints]
    return names if all(names) else list(joints)


def _joint_groups(series, summary):
    """[(title, [(joint, angle column, torque column, hinge)])] per leg, then 'other
    joints', for the joints the series holds."""
    owners = summary.get('joint_legs') or {}
    groups = {leg: [] for leg in summary.get('legs') or {}}
    for joint, leg in owners.items():
        for hinge in (True, False):
            position, effort = joint_columns(joint, hinge)
            if position in series[0]:
                groups.setdefault(leg if leg in groups else None, []).append(
                    (joint, position, effort, hinge))
    return [('other joints' if leg is None else f'leg {leg}', joints)
            for leg, joints in groups.items() if joints]


def _time_marks(axes, summary):
    """Scheduled changes and the robot going down (`DOWN`) as vertical lines on every time
    axis; returns the title's words for them."""
    words = []
    for change in (c for c in summary.get('schedule') or () if c.get('applied')):
        setting = ', '.join(f'{k} = {v:g}' for k, v in change.items()
                            if k not in ('time_s', 'applied'))
        for i, axis in enumerate(axes):
            axis.axvline(change['time_s'], color='0.3', linestyle='--', linewidth=0.8,
                         label=f'{setting} from {change["time_s"]:g} s' if i == 0 else None)
    outcome = summary.get('outcome') or {}
    for _, key, said in DOWN:
        at = outcome.get(key)
        if at is not None:
            for i, axis in enumerate(axes):
                axis.axvline(at, color='red', linewidth=1.2,
                             label=f'{said} at {at:.2f} s' if i == 0 else None)
    if outcome.get('words'):
        words.append(str(outcome['words']))
    elif not summary.get('stable', True) and summary.get('reason'):
        words.append(f'not stable: {summary["reason"]}')
    return words


def plot_run(path, series, summary):
    """Write the run's figure (module docstring) to `path` (PNG). series: the time-series
    rows (sim/series.py); summary: the run's summary (runner.run_scene)."""
    legs = list(summary.get('legs') or {})
    colours = _leg_colours(legs)
    groups = _joint_groups(series, summary)
    columns = min(LEGS_PER_ROW, len(groups)) if len(groups) != 4 else 2
    leg_rows = math.ceil(len(groups) / columns) if groups else 0
    fig = plt.figure(figsize=(15, 6.5 + 3.6 * leg_rows), layout='constrained')
    # one grid (axes shared across subfigures redraw the figure at every limit change):
    # the first two rows' panels span half of its GRID_COLUMNS, a leg's a share of a row
    grid = fig.add_gridspec(2 + 2 * leg_rows, GRID_COLUMNS,
                            height_ratios=[1.6, 1.6] + [1.0] * (2 * leg_rows))
    half = GRID_COLUMNS // 2
    position = fig.add_subplot(grid[0, :half])
    attitude, force, sinkage = (fig.add_subplot(grid[row, cols], sharex=position)
                                for row, cols in ((0, slice(half, None)), (1, slice(None, half)),
                                                  (1, slice(half, None))))
    time = _column(series, 'time_s')
    for name in ('x', 'y', 'z'):
        position.plot(time, _column(series, f'base_{name}_m'), label=name)
    surface = summary.get('surface') or {}
    if surface.get('type') == 'plane':
        position.axhline(surface['height_m'], color='0.6', linestyle=':', label='sand surface')
    position.set(title='base position', ylabel='position (m)')
    for name in ('roll', 'pitch', 'yaw'):
        if f'base_{name}_rad' in series[0]:
            angle = _column(series, f'base_{name}_rad')
            if name == 'yaw':
                angle = np.unwrap(angle)
            attitude.plot(time, np.degrees(angle), label=name)
    attitude.set(title='base attitude (roll about x, pitch about y, yaw about z)',
                 ylabel='angle (deg)')
    _at_least(attitude, LEAST_ANGLE_DEG)
    forces = []
    for leg in legs:
        values = _column(series, f'force_z_N_{leg}')
        forces.append(values)
        force.plot(time, values, color=colours[leg], linewidth=1.0)
        if f'sinkage_m_{leg}' in series[0]:
            sinkage.plot(time, 1000.0 * _column(series, f'sinkage_m_{leg}'),
                         color=colours[leg], linewidth=1.0, label=leg)
    force.set(title='vertical sand force per foot', ylabel='force (N)')
    limits = force_axis(np.concatenate(forces)) if forces else None
    if limits is not None:
        force.set_ylim(*limits)
        every = np.stack(forces)
        leg, at = np.unravel_index(np.argmax(every), every.shape)
        force.set_title(f'vertical sand force per foot (landing peak {every[leg, at]:.0f} N '
                        f'at {time[at]:.2f} s, off the axis)')
    sinkage.set(title='foot sinkage below the sand surface', ylabel='sinkage (mm)')
    if legs:
        sinkage.legend(title='leg', ncol=1 if len(legs) <= 12 else 2, **OUTSIDE)
    time_axes = [position, attitude, force, sinkage]
    for axis in time_axes:
        axis.grid(alpha=0.3)
    for axis in (force, sinkage):
        axis.set_xlabel('sim time (s)')
    if groups:
        span = GRID_COLUMNS // columns
        for i, (title, joints) in enumerate(groups):
            row, col = divmod(i, columns)
            cells = slice(col * span, (col + 1) * span)
            angle_ax = fig.add_subplot(grid[2 + 2 * row, cells], sharex=position)
            torque_ax = fig.add_subplot(grid[3 + 2 * row, cells], sharex=position)
            for (joint, angle_col, torque_col, hinge), short in zip(
                    joints, _short_names([j[0] for j in joints])):
                scale = np.degrees(1.0) if hinge else 1000.0
                angle_ax.plot(time, scale * _column(series, angle_col), label=short)
                torque_ax.plot(time, _column(series, torque_col))
            _at_least(angle_ax, LEAST_ANGLE_DEG)
            hinges = {j[3] for j in joints}
            angle_ax.set(title=f'{title}: joint positions',
                         ylabel=' / '.join(['angle (deg)'] * (True in hinges)
                                           + ['position (mm)'] * (False in hinges)))
            torque_ax.set(title=f'{title}: joint torques',
                          ylabel=' / '.join(['torque (N m)'] * (True in hinges)
                                            + ['force (N)'] * (False in hinges)))
            torque_ax.set_xlabel('sim time (s)')
            angle_ax.legend(**OUTSIDE)
            time_axes += [angle_ax, torque_ax]
            for axis in (angle_ax, torque_ax):
                axis.grid(alpha=0.3)
    words = _time_marks(time_axes, summary)
    if position.get_legend_handles_labels()[0]:
        position.legend(**OUTSIDE)
    attitude.legend(**OUTSIDE)
    changes = ''.join(f', {change["zeta"]:g} from {change["time_s"]:g} s'
                      for change in summary.get('schedule') or ()
                      if change.get('applied') and 'zeta' in change)
    lines = [run_name(summary),
             f'zeta = {summary.get("zeta", float("nan")):g} N/cm$^3${changes}, '
             f'dt = {summary.get("timestep_s", float("nan")) * 1e3:g} ms', *words]
    fig.suptitle('\n'.join(textwrap.fill(line, TITLE_WIDTH) for line in lines))
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_surface(path, surface, window=None):
    """Map of a height grid's change from its pristine surface (deformable sand: footprints
    below, piles above), mm, seen from above; `window` (x0, x1, y0, y1) m crops it."""
    change = 1000.0 * (surface.grid - surface.pristine)
    ny, nx = change.shape
    extent = (surface.origin[0], surface.origin[0] + surface.spacing[0] * (nx - 1),
              surface.origin[1], surface.origin[1] + surface.spacing[1] * (ny - 1))
    limit = max(float(abs(change).max()), 1e-3)
    fig, ax = plt.subplots(figsize=(7, 5))
    image = ax.imshow(change, origin='lower', extent=extent, cmap='RdBu_r', vmin=-limit,
                      vmax=limit)
    fig.colorbar(image, ax=ax, label='surface change (mm): footprints < 0 < piles')
    if window is not None:
        ax.set_xlim(window[0], window[1])
        ax.set_ylim(window[2], window[3])
    ax.set_xlabel('x (m)')
    ax.set_ylabel('y (m)')
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
