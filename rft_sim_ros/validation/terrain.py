"""Terrain study (`rft-sim validate --terrain`): the hexapod on slopes, on deformable sand
and across a patch of loose sand; the rail shapes and a dropped plate on deformable sand; the
step cost of each surface against the plane. Writes terrain.md, terrain.json and PNG plots.

Questions (docs/terrain.md): how speed and sinkage change with slope (0, 5, 10, 15 deg, up
and down); whether deformation changes the hexapod's backward motion, speed and sinkage and
the rail shapes' ordering (the paper's experiments: closed C > flat > open C); how deep a
plate dropped again into its own crater goes; what a walk from zeta 3.75 onto zeta 1 does;
and what each surface costs per step.
"""
import json
import time
from pathlib import Path

import numpy as np

from ..scenes.config import load_scene
from ..scenes.scenarios.plate_drop import expected_impact_depth
from ..sim.simulation import Simulation
from . import paper

SLOPES_DEG = (0.0, 5.0, 10.0, 15.0)
#: Deformable bed of the studies: 1 cm cells over 2 m x 2 m.
BED = {'sand.deformable.enabled': True, 'sand.deformable.cell': 0.01,
       'sand.deformable.size': [2.0, 2.0]}
#: The hexapod's walking direction, degrees from world +x towards +y: the paper's crab
#: hexapod walks sideways, along +y (its metrics' "forward"; scenes/scenarios/hexapod.py).
WALK_HEADING_DEG = 90.0
#: A patch of loose sand (zeta 1 of the scene's 3.75) from y = 0.15 m on, across the walk.
LOOSE_PATCH = {'sand.zeta_map.regions': [{'x': [-1.5, 1.5], 'y': [0.15, 3.0],
                                          'factor': 1.0 / 3.75}]}
RAILS = ('closed_c', 'flat', 'open_c')


def _run(scene, overrides, duration=None):
    sim = Simulation(load_scene(scene, overrides))
    duration = duration or sim.scene.duration or sim.scenario.duration()
    sim.step(int(round(duration / sim.timestep)))
    return sim


def _walk(overrides, plates):
    sim = _run('hexapod', {'rft.plates_per_body': plates, **overrides})
    m = sim.scenario.metrics(sim)
    row = {k: m[k] for k in ('forward_distance_m', 'mean_speed_mps', 'mean_sinkage_m',
                             'backward_fraction')}
    row.update(sim.terrain_metrics())
    return row, sim


def slope_study(plates):
    """{(direction, angle deg): walk metrics}; direction 'up' walks up the slope (its
    downhill heading opposite the walking direction, `WALK_HEADING_DEG`)."""
    rows = {}
    for angle in SLOPES_DEG:
        for direction, heading in (('up', WALK_HEADING_DEG + 180.0),
                                   ('down', WALK_HEADING_DEG)):
            if angle == 0 and direction == 'down':
                continue
            rows[(direction, angle)], _ = _walk({
                'sand.surface.type': 'slope', 'sand.surface.angle_deg': angle,
                'sand.surface.downhill_deg': heading}, plates)
    return rows


def deformation_study(plates, rail_plates):
    """Hexapod and rail shapes on rigid and on deformable sand."""
    hexapod = {}
    for label, overrides in (('rigid', {}), ('deformable', BED)):
        hexapod[label], sim = _walk(overrides, plates)
        if label == 'deformable':
            surface = sim.engine.surface
    rails = {}
    for shape in RAILS:
        for label, overrides in (('rigid', {}), ('deformable', BED)):
            sim = _run(f'rail_{shape}', {'rft.plates_per_body': rail_plates, **overrides})
            rails[(shape, label)] = {
                'carriage_displacement_m': sim.scenario.metrics(sim)['carriage_displacement_m'],
                **sim.terrain_metrics()}
    return hexapod, rails, surface


def lift_out(sim, height=0.3, steps=5):
    """Take plate_drop's plate out of the sand: moved to `height` m above the pristine surface,
    at rest, held there without gravity for `steps` steps (deformable sand then commits the
    footprint its plates left), then gravity back on."""
    joint = sim.data.joint('plate_free')
    joint.qpos[2] = sim.scene.surface_height + height
    joint.qvel[:] = 0.0
    gravity = sim.model.opt.gravity[2]
    sim.model.opt.gravity[2] = 0.0
    sim.step(steps)
    sim.model.opt.gravity[2] = gravity


def plate_redrop(duration=1.0):
    """plate_drop's plate on rigid and on deformable sand: dropped, lifted out (`lift_out`),
    dropped again from the same height over its crater. {label: row}: depths of the plate's
    bottom below the pristine surface at the end of each drop (m), the crater floor's depth
    below it under the plate's centre, the estimate for the second drop (the crater's depth
    plus the impact depth of a drop from drop_height + that depth onto the floor), and the
    deformable sand's metrics (crater and pile volume, net volume change)."""
    rows = {}
    for label, overrides in (('rigid', {}), ('deformable', BED)):
        sim = Simulation(load_scene('plate_drop', overrides))
        plate, level, steps = sim.scenario, sim.scene.surface_height, int(duration / sim.timestep)

        def depth():
            return float(level - (sim.data.body('plate').xpos[2] - plate.thickness / 2))
        sim.step(steps)
        first = depth()
        lift_out(sim)
        x, y = sim.data.body('plate').xpos[:2]
        floor = float(level - sim.engine.surface.height(np.array([x]), np.array([y]))[0])
        plate.initialize(sim)
        sim.data.joint('plate_free').qvel[:] = 0.0
        sim.step(steps)
        rows[label] = {'first_depth_m': first, 'crater_floor_m': floor, 'second_depth_m': depth(),
                       'second_estimate_m': floor + float(expected_impact_depth(
                           plate.mass, plate.side ** 2, sim.zeta, plate.drop_height + floor,
                           -sim.model.opt.gravity[2])),
                       **sim.terrain_metrics()}
    return rows


def zeta_crossing(plates):
    """Hexapod on zeta 3.75, on zeta 1, and from 3.75 onto 1 at y = 0.15 m (`LOOSE_PATCH`):
    walk metrics and the speed before and after the base crosses y = 0.15 m."""
    rows = {}
    for label, overrides in (('zeta 3.75', {}), ('zeta 1', {'zeta': 1.0}),
                             ('3.75 -> 1 at y = 0.15 m', LOOSE_PATCH)):
        row, sim = _walk(overrides, plates)
        s = sim.scenario.series()
        t, y = s['time_s'], s['y_m']
        cross = np.flatnonzero(y >= 0.15)
        if cross.size and 0 < cross[0] < len(t) - 1:
            c = cross[0]
            row['speed_before_mps'] = float((y[c] - y[0]) / (t[c] - t[0]))
            row['speed_after_mps'] = float((y[-1] - y[c]) / (t[-1] - t[c]))
        rows[label] = row
    return rows


def cost_cases(flat_grid):
    """Step-cost configurations: (label, overrides); 'plane' is the reference. flat_grid:
    a .npy of zeros (a height grid on the grid path with the plane's physics)."""
    return (
        ('plane', {}),
        ('slope 0 deg (slope path, same physics)', {'sand.surface.type': 'slope'}),
        ('height grid 2 m x 2 m at 1 cm, flat (grid path, same physics)', {
            'sand.surface.type': 'grid', 'sand.surface.file': str(flat_grid),
            'sand.surface.size': [2.0, 2.0]}),
        ('slope 10 deg', {'sand.surface.type': 'slope', 'sand.surface.angle_deg': 10.0}),
        ('deformable 2 m x 2 m, 1 cm', BED),
        ('deformable 8 m x 8 m, 1 cm', {**BED, 'sand.deformable.size': [8.0, 8.0]}),
    )


def step_costs(out, rounds=3, window_s=(1.0, 4.0), chunk=250):
    """Median CPU time of this process per hexapod step (s; CPU time, so that other load
    on the machine does not count) over the walk window, per `cost_cases` label, the cases
    interleaved over `rounds` rounds (one process, one run)."""
    flat_grid = Path(out).resolve() / 'flat_grid.npy'
    np.save(flat_grid, np.zeros((201, 201)))
    cases = cost_cases(flat_grid)
    samples = {label: [] for label, _ in cases}
    for _ in range(rounds):
        for label, overrides in cases:
            sim = Simulation(load_scene('hexapod', overrides))
            sim.step(int(round(window_s[0] / sim.timestep)))
            total = int(round((window_s[1] - window_s[0]) / sim.timestep))
            for _ in range(total // chunk):
                started = time.process_time()
                sim.step(chunk)
                samples[label].append((time.process_time() - started) / chunk)
    flat_grid.unlink()
    return {label: float(np.median(v)) for label, v in samples.items()}


def run_terrain(out_dir, quick=False, log=print):
    """Run the terrain study into `out_dir`; returns the results dict."""
    from ..sim.runner import machine_info
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    plates, rail_plates = (150, 200) if quick else (500, 500)
    started = time.perf_counter()
    log('slopes')
    slopes = slope_study(plates)
    log('deformation')
    hexapod, rails, surface = deformation_study(plates, rail_plates)
    plate = plate_redrop()
    log('zeta crossing')
    crossing = zeta_crossing(plates)
    log('step cost')
    costs = step_costs(out, rounds=1 if quick else 3)
    results = {'slopes': {f'{d} {a:g}': r for (d, a), r in slopes.items()},
               'deformation_hexapod': hexapod,
               'deformation_rails': {f'{s} {lab}': r for (s, lab), r in rails.items()},
               'plate_redrop': plate,
               'zeta_crossing': crossing, 'step_cost_s': costs,
               'plates_per_body': plates, 'rail_plates': rail_plates,
               'wall_s': time.perf_counter() - started, 'machine': machine_info()}
    (out / 'terrain.json').write_text(json.dumps(results, indent=1))
    _plots(out, slopes, surface)
    (out / 'terrain.md').write_text(_report(results, slopes, rails))
    return results


def _plots(out, slopes, surface):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.5))
    for direction, sign in (('up', 1), ('down', -1)):
        angles = [a for (d, a) in slopes if d == direction or a == 0]
        rows = [slopes[('up', 0.0)] if a == 0 else slopes[(direction, a)] for a in angles]
        axes[0].plot(angles, [100 * r['mean_speed_mps'] for r in rows], 'o-',
                     label=f'walking {direction}hill')
        axes[1].plot(angles, [100 * r['mean_sinkage_m'] for r in rows], 'o-',
                     label=f'walking {direction}hill')
    axes[0].set_ylabel('mean speed (cm/s)')
    axes[1].set_ylabel('mean stance sinkage (cm)')
    for ax in axes:
        ax.set_xlabel('slope (deg)')
        ax.legend()
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / 'terrain_slopes.png', dpi=120)
    plt.close(fig)
    from ..sim.plots import plot_surface
    plot_surface(out / 'terrain_hexapod_footprints.png', surface, window=(-0.4, 0.8, -0.4, 0.4))


def _report(r, slopes, rails):
    lines = ['# Terrain study', '',
             f'Hexapod (4.04 kg, tripod gait 1 Hz, 5 cycles, zeta 3.75, '
             f'{r["plates_per_body"]} plates per leg segment); rails at 1 rad/s '
             f'({r["rail_plates"]} plates). Run: `rft-sim validate --terrain` '
             f'({r["wall_s"]:.0f} s; {r["machine"].get("cpu", "")}).', '',
             '## Slopes (depth vertical below the local surface)', '',
             '| walking | slope (deg) | forward (m) | speed (cm/s) | sinkage (cm) | '
             'backward fraction |',
             '|---|---|---|---|---|---|']
    for (direction, angle), row in slopes.items():
        lines.append(f'| {direction}hill | {angle:g} | {row["forward_distance_m"]:.3f} | '
                     f'{100 * row["mean_speed_mps"]:.2f} | {100 * row["mean_sinkage_m"]:.2f} | '
                     f'{row["backward_fraction"]:.3f} |')
    lines += ['', '![slopes](terrain_slopes.png)', '',
              '## Deformable sand (1 cm cells, 2 m x 2 m, repose 30 deg)', '',
              '| hexapod | forward (m) | speed (cm/s) | sinkage (cm) | backward fraction | '
              'max footprint (cm) | volume change (m^3) |', '|---|---|---|---|---|---|---|']
    for label, row in r['deformation_hexapod'].items():
        lines.append(f'| {label} | {row["forward_distance_m"]:.3f} | '
                     f'{100 * row["mean_speed_mps"]:.2f} | {100 * row["mean_sinkage_m"]:.2f} | '
                     f'{row["backward_fraction"]:.3f} | '
                     f'{100 * row.get("max_footprint_depth_m", 0.0):.2f} | '
                     f'{row.get("sand_volume_change_m3", 0.0):.2e} |')
    lines += ['', f'Paper: backward fraction in its simulated example '
              f'{paper.HEXAPOD_BACKWARD_FRACTION_SIM:.2f}; experiment speed '
              f'{100 * paper.HEXAPOD_SPEED_EXPERIMENT_MPS:.1f} cm/s; its simulation '
              f'underestimated the distance per step by '
              f'{100 * paper.HEXAPOD_STEP_UNDERESTIMATE[0]:.0f}-'
              f'{100 * paper.HEXAPOD_STEP_UNDERESTIMATE[1]:.0f} %.', '',
              '![footprints](terrain_hexapod_footprints.png)', '',
              '| rail shape | rigid: carriage (cm) | deformable: carriage (cm) |', '|---|---|---|']
    for shape in RAILS:
        lines.append(f'| {shape} | '
                     f'{100 * rails[(shape, "rigid")]["carriage_displacement_m"]:.2f} | '
                     f'{100 * rails[(shape, "deformable")]["carriage_displacement_m"]:.2f} |')
    order = {label: ' > '.join(sorted(RAILS, key=lambda s: -rails[(s, label)][
        'carriage_displacement_m'])) for label in ('rigid', 'deformable')}
    lines += ['', f'Order, rigid: {order["rigid"]}; deformable: {order["deformable"]}; '
              "the paper's experiments: closed_c > flat > open_c (open C "
              f'{100 * paper.OPEN_C_VS_FLAT_EXPERIMENT:+.0f} % of flat; its simulation '
              f'{100 * paper.OPEN_C_VS_FLAT_SIM:+.0f} %).', '',
              '| plate dropped twice (plate_drop) | first drop (mm) | crater floor (mm) | '
              'second drop (mm) | estimate (mm) | crater / pile (cm^3) | volume change (m^3) |',
              '|---|---|---|---|---|---|---|']
    for label, row in r['plate_redrop'].items():
        lines.append(f'| {label} sand | {1e3 * row["first_depth_m"]:.2f} | '
                     f'{1e3 * row["crater_floor_m"]:.2f} | {1e3 * row["second_depth_m"]:.2f} | '
                     f'{1e3 * row["second_estimate_m"]:.2f} | '
                     f'{1e6 * row.get("sand_displaced_m3", 0.0):.1f} / '
                     f'{1e6 * row.get("sand_piled_m3", 0.0):.1f} | '
                     f'{row.get("sand_volume_change_m3", 0.0):.1e} |')
    lines += ['', 'Depths below the pristine surface. The plate is lifted out between the '
              'drops (deformable sand commits a footprint when its body leaves it); the '
              'second drop starts from the same height and meets the crater floor, so it '
              'ends about the crater depth plus a fresh impact depth deeper (the estimate, '
              'for a flat-floored crater: the grid\'s crater walls slope over one cell, '
              'so the plate\'s rim meets sand higher than the floor and stops it sooner); '
              'on rigid sand both drops are the same.', '',
              '## Packed to loose sand', '',
              '| hexapod | forward (m) | speed (cm/s) | before y = 0.15 m | after | sinkage (cm) |',
              '|---|---|---|---|---|---|']
    for label, row in r['zeta_crossing'].items():
        before = row.get('speed_before_mps')
        after = row.get('speed_after_mps')
        lines.append(f'| {label} | {row["forward_distance_m"]:.3f} | '
                     f'{100 * row["mean_speed_mps"]:.2f} | '
                     f'{"" if before is None else f"{100 * before:.2f}"} | '
                     f'{"" if after is None else f"{100 * after:.2f}"} | '
                     f'{100 * row["mean_sinkage_m"]:.2f} |')
    cost = r['step_cost_s']
    plane = cost['plane']
    lines += ['', '## Step cost (hexapod walking, 500 plates per segment: median CPU time '
              'per step, one run, cases interleaved)', '', '| surface | us/step | vs plane |',
              '|---|---|---|']
    for label, value in cost.items():
        lines.append(f'| {label} | {value * 1e6:.1f} | {value / plane:.3f} |')
    lines += ['', 'A quick figure from one process: whole simulation steps (the gait and the '
              'recorded state included) from 1 s to 4 s, the first steps of the walk with them. '
              'The targets are judged by `python -m rft_sim_ros.bench.terrain_cost` (the engine '
              'step alone over whole gait cycles of the steady walk, each case in its own '
              'process, seven rounds; bench/results/terrain_cost.md).']
    return '\n'.join(lines) + '\n'
