"""Write a benchmark's results: bench.json, bench.md (tables) and PNG plots."""
import json
import math

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402  (backend must be chosen first)
from matplotlib.ticker import FormatStrFormatter, LogLocator  # noqa: E402


def _us(seconds):
    return f'{seconds * 1e6:.1f}'


def _err(value):
    return 'inf' if not math.isfinite(value) else f'{value:.2%}'


def _load(values):
    """A load average (1, 5, 15 min) as text, or 'unknown'."""
    return 'unknown' if not values else ', '.join(f'{value:.2f}' for value in values)


def machine_line(machine, load_at_end=None):
    """Where a benchmark was measured (`sim.runner.machine_info`): CPU, cores, versions and
    the load average at its start (and end, when given), and which kernels ran
    (`prebuilt.state`), as one line of markdown."""
    end = '' if load_at_end is None else f'; at the end: {_load(load_at_end)}'
    kernels = machine.get('kernels', 'kernels: not recorded')
    return (f'Machine: {machine["cpu"]}, {machine["cores"]} cores; Python {machine["python"]}, '
            f'MuJoCo {machine["mujoco"]}, numpy {machine["numpy"]}. Load average (1, 5, 15 '
            f'min) at the start: {_load(machine.get("load_average"))}{end}. '
            f'{kernels[:1].upper()}{kernels[1:]}. On a shared '
            'machine wall times grow with the load; compare figures taken at similar loads.')


def markdown(results):
    """The benchmark as a markdown report."""
    lines = ['# rft_sim_ros benchmark', '',
             machine_line(results['machine'], results.get('load_average_at_end', [])), '',
             'One process, one core. Times are medians of repeated chunks; ratios are taken '
             'within one run.', '']
    cost = results.get('step_cost')
    if cost:
        lines += ['## Hexapod step cost against plain MuJoCo', '',
                  f'Hexapod on RFT sand, {cost["plates_total"]} plates (500 per sand body), '
                  f'dt {cost["timestep_s"] * 1e3:g} ms, walking; the same robot on MuJoCo\'s '
                  'rigid floor with the same servo targets.', '',
                  '| step | wall per step (us) | real-time factor | ratio to rigid |',
                  '|---|---|---|---|',
                  f'| rigid-floor mj_step | {_us(cost["rigid_step_s"])} | '
                  f'{cost["real_time_factor_rigid"]:.0f} | 1 |',
                  f'| RFT engine step (sand + MuJoCo) | {_us(cost["sand_engine_step_s"])} | '
                  f'{cost["timestep_s"] / cost["sand_engine_step_s"]:.1f} | '
                  f'{cost["ratio_engine_to_rigid"]:.2f} |',
                  f'| full simulation step (+ gait, servo commands, checks) | '
                  f'{_us(cost["sand_step_s"])} | {cost["real_time_factor_full"]:.1f} | '
                  f'{cost["ratio_full_to_rigid"]:.2f} |', '']
    trial = results.get('trial')
    if trial:
        walk = trial['walk']
        factors = trial['walk_real_time_factors']
        lines += [f'Full `hexapod` run ({trial["sim_time_s"]:g} s of sim time: 1 s drop and '
                  f'settle, then the walk): {trial["wall_time_s"]:.2f} s wall, real-time factor '
                  f'**{trial["real_time_factor"]:.1f}**. Its walk alone ({walk["sim_time_s"]:g} '
                  f's, the paper\'s trial): {walk["wall_time_s"]:.2f} s wall, real-time factor '
                  f'**{walk["real_time_factor"]:.1f}** (the paper: 0.04). Of {len(factors)} '
                  f'runs, the one with the median walk (their walks\' real-time factors: '
                  f'{", ".join(f"{f:.1f}" for f in factors)}).', '']
    bag = results.get('trial_with_bag')
    if bag:
        lines += [f'The same run as `rft-sim run hexapod` makes it by default, with its rosbag2 '
                  f'(alternating with the runs above, medians): real-time factor '
                  f'**{bag["real_time_factor"]:.1f}** with the bag against '
                  f'{bag["real_time_factor_without"]:.1f} without (`--no-bag`); recording is '
                  f'{100 * bag["recording_fraction"]:.1f} % of the run\'s wall time (runs: '
                  f'{", ".join(f"{f:.1f}" for f in bag["real_time_factors"])}).', '']
    start = results.get('startup')
    if start:
        lines += ['## Start-up (import + model + plates + kernels)', '',
                  f'Cold (empty numba cache): {start["cold"]["total_s"]:.2f} s; warm (cached): '
                  f'median {start["warm_total_median_s"]:.2f} s.', '']
    scaling = results.get('scaling')
    if scaling:
        lines += ['## Cost against plates', '',
                  '| plates on the slab | plates in the sand | step in sand (us) | '
                  'step above sand (us) |', '|---|---|---|---|']
        lines += [f'| {r["plates_total"]} | {r["plates_in_sand"]} | {_us(r["step_s_in_sand"])} '
                  f'| {_us(r["step_s_above_sand"])} |' for r in scaling['rows']]
        lines += ['', f'Linear fit: {scaling["seconds_per_plate_in_sand"] * 1e9:.1f} ns per plate '
                  f'in the sand + {_us(scaling["fixed_step_s"])} us, R^2 = '
                  f'{scaling["linear_fit_r2"]:.4f}.', '']
    idle = results.get('idle_plates')
    if idle:
        lines += [f'Hexapod with its {len(idle["idle_bodies"])} bodies that never reach the sand '
                  f'also carrying plates ({", ".join(map(str, idle["idle_plates_total"]))} idle '
                  f'plates): step {", ".join(_us(s) for s in idle["step_s"])} us, ratio '
                  f'{idle["ratio_last_to_first"]:.3f} when they double.', '']
    sweeps = results.get('speed_against_error')
    if sweeps:
        lines += ['## Speed against error', '',
                  'Error: relative difference of the scene\'s main metric from a converged '
                  'reference (finest plates, smallest timestep). Bold: on the Pareto front; '
                  '(default) marks the scene\'s default settings.', '']
        for sweep in sweeps:
            ref = sweep['reference']
            lines += [f'### {sweep["scene"]} (`{sweep["metric"]}`; reference {ref["plates_per_body"]} '
                      f'plates/body, dt {ref["timestep_s"] * 1e3:g} ms: {ref["metric"]:.5g})', '',
                      '| plates/body | dt (ms) | wall s per sim s | metric | error |',
                      '|---|---|---|---|---|']
            for r in sweep['rows']:
                mark = ' (default)' if r['default'] else ''
                cells = [f'{r["plates_per_body"]}{mark}', f'{r["timestep_s"] * 1e3:g}',
                         f'{r["wall_s_per_sim_s"]:.3f}',
                         'unstable' if r['metric'] is None else f'{r["metric"]:.5g}',
                         _err(r['relative_error'])]
                if r['on_front']:
                    cells = [f'**{c}**' for c in cells]
                lines.append('| ' + ' | '.join(cells) + ' |')
            lines.append('')
    return '\n'.join(lines) + '\n'


def plot_pareto(path, sweeps):
    """One panel per scene: relative error against wall time per simulated second; labels
    (plates per body / dt in ms) on the default and the front first, then on the others
    where they do not overlap one already placed."""
    columns = 4
    rows = math.ceil(len(sweeps) / columns)
    fig, axes = plt.subplots(rows, columns, figsize=(4.6 * columns, 4.0 * rows), squeeze=False)
    floor = 1e-6
    for ax, sweep in zip(axes.flat, sweeps):
        points = [(r, r['wall_s_per_sim_s'], max(r['relative_error'], floor))
                  for r in sweep['rows'] if math.isfinite(r['relative_error'])]
        for r, x, y in points:
            ax.scatter(x, y, s=70 if r['default'] else 25, marker='*' if r['default'] else 'o',
                       color='tab:red' if r['on_front'] else 'tab:gray', zorder=3)
        front = sorted((x, y) for r, x, y in points if r['on_front'])
        if front:
            ax.step(*zip(*front), where='post', color='tab:red', linewidth=1)
        ax.set_xscale('log')
        ax.set_yscale('log')
        ax.margins(x=0.15, y=0.15)
        ax.xaxis.set_minor_locator(LogLocator(subs=(2.0, 5.0)))  # a short span: 1-2-5 labels
        ax.xaxis.set_minor_formatter(FormatStrFormatter('%g'))
        ax.tick_params(labelsize=7)
        floored = any(r['relative_error'] < floor for r, _, _ in points)
        ax.set_title(f'{sweep["scene"]}' + (f' (errors < {floor:g} shown at {floor:g})'
                                             if floored else ''), fontsize=9)
        ax.set_xlabel('wall s per sim s', fontsize=8)
        ax.set_ylabel('relative error', fontsize=8)
        ranked = sorted(points, key=lambda p: (not p[0]['default'], not p[0]['on_front']))
        _label_without_overlap(fig, ax, [(f'{r["plates_per_body"]}/{r["timestep_s"] * 1e3:g}',
                                          x, y) for r, x, y in ranked])
    for ax in list(axes.flat)[len(sweeps):]:
        ax.axis('off')
    fig.suptitle('Speed against error (labels: plates per body / dt in ms; star: default; '
                 'red: Pareto front)', fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


#: Where a point's label may go, in points from the point (tried in this order).
_LABEL_OFFSETS = ((4, 4), (4, -11), (-6, 6), (-6, -12))


def _label_without_overlap(fig, ax, labels):
    """Annotate (text, x, y) in order, each at the first offset where it overlaps neither
    a label already placed nor the panel's edge; a label with no such place is left out.
    Returns the placed labels' boxes (display coordinates)."""
    fig.canvas.draw()  # final limits and transforms
    renderer = fig.canvas.get_renderer()
    panel = ax.get_window_extent(renderer)
    placed = []
    for text, x, y in labels:
        for dx, dy in _LABEL_OFFSETS:
            label = ax.annotate(text, (x, y), xytext=(dx, dy), textcoords='offset points',
                                fontsize=7, ha='left' if dx > 0 else 'right')
            box = label.get_window_extent(renderer).expanded(1.05, 1.1)
            inside = (panel.x0 <= box.x0 and box.x1 <= panel.x1
                      and panel.y0 <= box.y0 and box.y1 <= panel.y1)
            if inside and not any(box.overlaps(other) for other in placed):
                placed.append(box)
                break
            label.remove()
    return placed


def plot_scaling(path, scaling):
    """Step cost against plates in the sand, and with the slab above the sand."""
    rows = scaling['rows']
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot([r['plates_in_sand'] for r in rows], [r['step_s_in_sand'] * 1e6 for r in rows],
            'o-', label='slab in the sand')
    ax.plot([r['plates_in_sand'] for r in rows], [r['step_s_above_sand'] * 1e6 for r in rows],
            's--', label='same slab above the sand')
    ax.set_xlabel('plates in the sand')
    ax.set_ylabel('wall time per step (us)')
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def write(out, results):
    """bench.json, bench.md and the plots under `out` (a Path)."""
    out.mkdir(parents=True, exist_ok=True)
    (out / 'bench.json').write_text(json.dumps(results, indent=2, default=str))
    (out / 'bench.md').write_text(markdown(results))
    if results.get('speed_against_error'):
        plot_pareto(out / 'pareto.png', results['speed_against_error'])
    if results.get('scaling'):
        plot_scaling(out / 'scaling.png', results['scaling'])
