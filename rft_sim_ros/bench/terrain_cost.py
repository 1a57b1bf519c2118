"""Step cost of the sand surfaces (docs/terrain.md): the hexapod's engine step (sand +
MuJoCo) on a slope, a height grid and deformable sand against the same hexapod on the plane,
and optionally the plane against an older checkout of the code (e.g. the code before the
terrain work).

    python -m rft_sim_ros.bench.terrain_cost [--out DIR] [--rounds 5] [--baseline CODE_DIR]

Every case runs in its own worker process (`engine_step_worker.py`: one hexapod walking on
one surface); the cases take turns, one gait cycle each, for `rounds` rounds, each round
starting with the next case, so machine noise and the order of turns hit all alike. The
grids and beds are laid along the stretch the hexapod walks in those rounds, and a case whose
bodies leave it stops the benchmark: beyond a grid the ground is another (`laid_along_walk`).
Reported: the median CPU time per engine step of each case, and its ratio to the plane as
the median of the per-round ratios (a ratio taken within one round). The workers
of the code under test import this package; the baseline worker imports CODE_DIR's (a
`git worktree add` checkout) with the same interpreter. Writes terrain_cost.json and
terrain_cost.md into DIR (default bench/results).
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from .. import resources
from ..sand.surface import Slope
from ..sim.runner import machine_info

WORKER = Path(__file__).with_name('engine_step_worker.py')
#: The package root of the code under test.
CODE = Path(__file__).resolve().parents[2]
BASELINE = 'plane, baseline code'
#: The world axis the hexapod walks along, toward + (0: x, 1: y): the crab hexapod walks
#: sideways along +y, its body long along x.
WALK_AXIS = 1
#: Upper bound of the hexapod's walking speed along `WALK_AXIS` (m/s; it walks 7.1 cm/s on
#: the plane at 500 plates per leg segment), and the extent along `WALK_AXIS` of its sand
#: bodies' spheres when measuring starts (m, `engine_step_worker.WALKING_S`: y -0.479 ..
#: 0.491; across the walk, x -0.350 .. 0.350, centred on x = 0).
WALK_SPEED_BOUND = 0.1
START_EXTENT = (-0.49, 0.50)
#: Side of the surfaces measured (m): grids 2 m x 2 m at 1 cm; the target's deformable bed
#: of 1 cm cells over 2 m x 2 m (longer along the walk where a run walks further).
SIDE = 2.0
CELL = 0.01


def laid_along_walk(rounds):
    """Centre and size (m, world [x, y]) of the rectangle the surfaces measured cover: `SIDE`
    wide across the walk, centred on it (the sand bodies start centred across it), and along
    `WALK_AXIS` over the stretch the hexapod walks in `rounds` rounds (two gait cycles of 1 s
    each per round: one run, one timed), with a cell to spare at each end: `SIDE` long, or
    longer for a longer walk. The workers report where the bodies went
    (`check_on_surface`)."""
    low = START_EXTENT[0] - CELL
    high = START_EXTENT[1] + WALK_SPEED_BOUND * 2.0 * rounds + CELL
    centre, size = [0.0, 0.0], [SIDE, SIDE]
    centre[WALK_AXIS] = 0.5 * (low + high)
    size[WALK_AXIS] = max(SIDE, CELL * float(np.ceil((high - low) / CELL)))
    return centre, size


def check_on_surface(label, extent, centre, size):
    """Raise where a case's sand bodies (their spheres' extent, m, world [[x low, x high],
    [y low, y high]], over all its timed cycles) left the surface laid along the walk
    (centre and size from `laid_along_walk`): the step cost measured would be partly that
    of the ground beyond it."""
    for axis, name in enumerate('xy'):
        low, high = centre[axis] - 0.5 * size[axis], centre[axis] + 0.5 * size[axis]
        if extent[axis][0] < low or extent[axis][1] > high:
            raise RuntimeError(f'{label}: the hexapod walked beyond the surface measured '
                               f'(bodies at {name} {extent[axis][0]:.2f} .. '
                               f'{extent[axis][1]:.2f} m, surface {low:.2f} .. {high:.2f} m): '
                               'raise WALK_SPEED_BOUND or START_EXTENT')


def _nodes(centre, size):
    """World x and y (m) of the grids' nodes: `size` (m, [x, y]) at `CELL`, centred on
    `centre` (m, world [x, y])."""
    return tuple(c + np.linspace(-0.5 * s, 0.5 * s, int(round(s / CELL)) + 1)
                 for c, s in zip(centre, size))


def rippled_heights(x, y):
    """Heights (m, [iy, ix]) at world nodes x, y (m): ripples of +-1 cm, 0.25 m wavelength."""
    return 0.01 * np.sin(2 * np.pi * x / 0.25)[None, :] * np.cos(2 * np.pi * y / 0.25)[:, None]


def grid_files(folder, centre=(0.0, 0.0), size=(SIDE, SIDE)):
    """Three height grids (.npy, m) of `size` (m, [x, y]) at 1 cm centred on `centre` (m,
    world [x, y]) in `folder`: flat at 0 (the plane's physics on the grid path), rippled
    (`rippled_heights`), and the 10 deg slope of the slope case sampled at the nodes (the
    slope's physics on the grid path: bilinear interpolation of a plane is that plane)."""
    x, y = _nodes(centre, size)
    flat, rippled = Path(folder) / 'flat_grid.npy', Path(folder) / 'rippled_grid.npy'
    sloped = Path(folder) / 'sloped_grid.npy'
    np.save(flat, np.zeros((y.size, x.size)))
    np.save(rippled, rippled_heights(x, y))
    np.save(sloped, Slope(0.0, angle_deg=10.0).height(*np.meshgrid(x, y)))
    return flat, rippled, sloped


def hfield_model(folder, centre=(0.0, 0.0), size=(SIDE, SIDE)):
    """The hexapod's MJCF with an <hfield> geom 'terrain' in its world body holding the
    rippled grid of `grid_files` (heights -1 .. +1 cm; `size`, m, [x, y], centred on
    `centre`, m, world [x, y]), written to `folder`; returns its path. (The hexapod model
    itself has no hfield.)"""
    models = resources.models_dir()
    heights = rippled_heights(*_nodes(centre, size))
    low, high = heights.min(), heights.max()
    elevation = ' '.join(f'{value:.6f}' for value in ((heights - low) / (high - low)).ravel())
    xml = (models / 'hexapod.xml').read_text()
    xml = xml.replace('meshdir="assets"', f'meshdir="{models / "assets"}"', 1)
    xml = xml.replace('<asset>', f'<asset><hfield name="ripples" nrow="{heights.shape[0]}" '
                                 f'ncol="{heights.shape[1]}" size="{0.5 * size[0]} '
                                 f'{0.5 * size[1]} {high - low} 0.01" '
                                 f'elevation="{elevation}"/>', 1)
    xml = xml.replace('<worldbody>', '<worldbody><geom name="terrain" type="hfield" '
                                     f'hfield="ripples" pos="{centre[0]} {centre[1]} {low}"/>',
                      1)
    path = Path(folder) / 'hexapod_hfield.xml'
    path.write_text(xml)
    return path


def cases(folder, rounds=5):
    """(label, scene overrides, laid along the walk) of the surfaces measured, their grids
    and beds laid along the walk of `rounds` rounds (`laid_along_walk`); 'plane' is the
    reference."""
    centre, extent = laid_along_walk(rounds)
    flat, rippled, sloped = grid_files(folder, centre, extent)
    size = f'{extent[0]:g} m x {extent[1]:g} m'
    grid = {'sand.surface.type': 'grid', 'sand.surface.size': extent,
            'sand.surface.center': centre}
    bed = {'sand.deformable.enabled': True, 'sand.deformable.cell': CELL,
           'sand.deformable.size': extent, 'sand.deformable.center': centre}
    return (
        ('plane', {}, False),
        ('slope 0 deg (slope path, the plane\'s physics)', {'sand.surface.type': 'slope'}, False),
        ('slope 10 deg', {'sand.surface.type': 'slope', 'sand.surface.angle_deg': 10.0}, False),
        (f'height grid {size} at 1 cm, flat (grid path, the plane\'s physics)',
         {**grid, 'sand.surface.file': str(flat)}, True),
        (f'height grid {size} at 1 cm, the 10 deg slope (the slope\'s physics)',
         {**grid, 'sand.surface.file': str(sloped)}, True),
        (f'height grid {size} at 1 cm, rippled +-1 cm',
         {**grid, 'sand.surface.file': str(rippled)}, True),
        ('the model\'s own hfield, the same ripples', {
            'model': str(hfield_model(folder, centre, extent)), 'sand.surface.type': 'hfield',
            'sand.surface.geom': 'terrain'}, True),
        (f'deformable {size}, 1 cm', bed, True),
        ('deformable 8 m x 8 m, 1 cm', {**bed, 'sand.deformable.size': [8.0, 8.0]}, True),
    )


class Worker:
    """A worker process (see engine_step_worker.py) measuring one case with the code in
    `code` (a folder holding the rft_sim_ros package)."""

    def __init__(self, code, overrides, cwd):
        env = dict(os.environ, PYTHONPATH=str(code))
        self.process = subprocess.Popen(
            [sys.executable, '-P', str(WORKER), json.dumps(overrides)], cwd=cwd, env=env,
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        self.info = self._answer()
        expected = Path(code).resolve() / 'rft_sim_ros' / '__init__.py'
        if Path(self.info['package']).resolve() != expected:
            self.close()
            raise RuntimeError(f'engine step worker imported {self.info["package"]}, not the '
                               f'package in {code}')

    def _answer(self):
        line = self.process.stdout.readline()
        if not line:
            raise RuntimeError(f'engine step worker exited with {self.process.wait()}')
        return json.loads(line)

    def chunk(self):
        """CPU time per engine step (s) over one gait cycle; `extent` becomes the extent (m,
        world [[x low, x high], [y low, y high]]) of the sand bodies' spheres in all the
        worker's cycles so far."""
        self.process.stdin.write('chunk\n')
        self.process.stdin.flush()
        answer = self._answer()
        self.extent = answer['extent_m']
        return answer['step_s']

    def close(self):
        self.process.stdin.close()
        self.process.wait()


def surface_costs(rounds=5, baseline=None, processes=1, log=print):
    """Median engine-step CPU time per case and its ratio to the plane (median of per-round
    ratios); with `baseline` (a code folder), the plane of that code as one more case. With
    `processes` > 1 each case runs in that many worker processes and a round's sample of a
    case is their mean: the same code reads up to about 2 % apart in two processes, for the
    life of each (where its compiled code and arrays landed), and the mean evens that out."""
    centre, size = laid_along_walk(rounds)
    with tempfile.TemporaryDirectory() as folder:
        measured = cases(folder, rounds)
        plan = [(label, CODE, overrides) for label, overrides, _ in measured]
        laid = {label for label, _, on_surface in measured if on_surface}
        if baseline is not None:
            plan.insert(0, (BASELINE, Path(baseline).resolve(), {}))
        workers = {}
        try:
            for label, code, overrides in plan:
                log(f'starting: {label}')
                workers[label] = [Worker(code, overrides, folder) for _ in range(processes)]
            samples = {label: [] for label in workers}
            turns = list(workers.items())
            for r in range(rounds):
                log(f'round {r + 1}/{rounds}')
                shift = r % len(turns)  # each round starts with the next case: no case
                for label, group in turns[shift:] + turns[:shift]:  # always goes first
                    samples[label].append(float(np.mean([w.chunk() for w in group])))
                    if label in laid:
                        for worker in group:
                            check_on_surface(label, worker.extent, centre, size)
        finally:
            for group in workers.values():
                for worker in group:
                    worker.close()
    plane = np.array(samples['plane'])
    result = {}
    for label, values in samples.items():
        values = np.array(values)
        result[label] = {'step_s': float(np.median(values)),
                         'ratio_to_plane': float(np.median(values / plane)),
                         'samples_s': values.tolist(),
                         'bodies_m': {name: [min(w.extent[axis][0] for w in workers[label]),
                                             max(w.extent[axis][1] for w in workers[label])]
                                      for axis, name in enumerate('xy')}}
    return result


def commit(code):
    """The git commit checked out in the folder `code` (its short hash, with '+changes'
    where the work tree differs from it), or None outside a git checkout: which code a
    report measured, without recording paths of the machine it ran on."""
    def git(*args):
        return subprocess.run(['git', '-C', str(code), *args], capture_output=True,
                              text=True).stdout.strip()
    try:
        head = git('rev-parse', '--short', 'HEAD')
        changed = head and git('status', '--porcelain', '--untracked-files=no')
    except OSError:  # no git on the machine
        return None
    return head + '+changes' * bool(changed) or None


def markdown(results):
    machine = results['machine']
    surface = results['surface_m']
    lines = ['# Step cost of the sand surfaces', '',
             f'Machine: {machine["cpu"]}, {machine["cores"]} cores (shared); Python '
             f'{machine["python"]}, MuJoCo {machine["mujoco"]}, numpy {machine["numpy"]}. '
             'Hexapod walking (500 plates per leg segment, 0.8 ms): CPU time per engine step '
             f'(sand + MuJoCo), {results.get("processes", 1)} worker process(es) per case (a '
             'round\'s sample: their mean), the cases taking turns one gait '
             f'cycle each over {results["rounds"]} rounds; medians, and ratios to the plane as '
             'the median of per-round ratios. Produced by `python -m '
             'rft_sim_ros.bench.terrain_cost`. Grids and beds are laid along the walk '
             f'(+{"xy"[WALK_AXIS]}), x {surface["x"][0]:.2f} .. {surface["x"][1]:.2f} m, '
             f'y {surface["y"][0]:.2f} .. {surface["y"][1]:.2f} m; the last columns give '
             "the ranges the sand bodies' spheres covered.", '',
             '| surface | us/step | vs plane | bodies at x (m) | bodies at y (m) |',
             '|---|---|---|---|---|']
    for label, row in results['cases'].items():
        (x_low, x_high), (y_low, y_high) = row['bodies_m']['x'], row['bodies_m']['y']
        lines.append(f'| {label} | {row["step_s"] * 1e6:.1f} | {row["ratio_to_plane"]:.3f} '
                     f'| {x_low:.2f} .. {x_high:.2f} | {y_low:.2f} .. {y_high:.2f} |')
    if results.get('code'):
        lines += ['', f'Code measured: {results["code"]}.']
    if results.get('baseline'):
        lines += ['', f'Baseline code: {results["baseline"]}.']
    return '\n'.join(lines) + '\n'


def main(argv=None):
    parser = argparse.ArgumentParser(prog='python -m rft_sim_ros.bench.terrain_cost',
                                     description=__doc__.split('\n\n')[0])
    parser.add_argument('--out', default='bench/results', help='output folder')
    parser.add_argument('--rounds', type=int, default=5, help='gait cycles per case')
    parser.add_argument('--processes', type=int, default=1,
                        help='worker processes per case (their mean per round)')
    parser.add_argument('--baseline', help='a folder holding an older rft_sim_ros to compare '
                                           'the plane with (e.g. a git worktree)')
    parser.add_argument('--baseline-label', default='', help='what the baseline is (report)')
    args = parser.parse_args(argv)
    log = lambda line: print(f'terrain_cost: {line}', file=sys.stderr)  # noqa: E731
    centre, size = laid_along_walk(args.rounds)
    results = {'machine': machine_info(), 'rounds': args.rounds,
               'load_before': os.getloadavg()[0],
               'processes': args.processes,
               'surface_m': {name: [c - 0.5 * s, c + 0.5 * s]
                             for name, c, s in zip('xy', centre, size)},
               'cases': surface_costs(args.rounds, args.baseline, args.processes, log),
               'load_after': os.getloadavg()[0],
               'code': commit(CODE),
               'baseline': args.baseline and (args.baseline_label or commit(args.baseline)
                                              or Path(args.baseline).name)}
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / 'terrain_cost.json').write_text(json.dumps(results, indent=2) + '\n')
    (out / 'terrain_cost.md').write_text(markdown(results))
    print(f'wrote {out / "terrain_cost.md"}', file=sys.stderr)


if __name__ == '__main__':
    main()
