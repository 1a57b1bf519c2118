"""Step cost of the sand surfaces (docs/terrain.md): the hexapod's engine step (sand +
MuJoCo) on a slope, a height grid and deformable sand against the same hexapod on the plane,
and optionally the plane against an older checkout of the code (e.g. the code before the
terrain work).

    python -m rft_sim_ros.bench.terrain_cost [--out DIR] [--rounds 5] [--baseline CODE_DIR]

Every case runs in its own worker process (`engine_step_worker.py`: one hexapod walking on
one surface); the cases take turns, one gait cycle each, for `rounds` rounds, each round
starting with the next case, so machine noise and the order of turns hit all alike. Reported: the median CPU time per engine step of each case, and its ratio to
the plane as the median of the per-round ratios (a ratio taken within one round). The workers
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
#: Deformable bed of the targets: 1 cm cells over 2 m x 2 m.
BED = {'sand.deformable.enabled': True, 'sand.deformable.cell': 0.01,
       'sand.deformable.size': [2.0, 2.0]}


def rippled_heights():
    """A 2 m x 2 m height grid at 1 cm (m, [iy, ix]): ripples of +-1 cm, 0.25 m wavelength."""
    x = np.linspace(-1.0, 1.0, 201)
    return 0.01 * np.sin(2 * np.pi * x / 0.25)[None, :] * np.cos(2 * np.pi * x / 0.25)[:, None]


def grid_files(folder):
    """Three 2 m x 2 m height grids at 1 cm (.npy, m) in `folder`: flat at 0 (the plane's
    physics on the grid path), rippled (`rippled_heights`), and the 10 deg slope of the
    slope case sampled at the nodes (the slope's physics on the grid path: bilinear
    interpolation of a plane is that plane)."""
    flat, rippled = Path(folder) / 'flat_grid.npy', Path(folder) / 'rippled_grid.npy'
    sloped = Path(folder) / 'sloped_grid.npy'
    np.save(flat, np.zeros((201, 201)))
    np.save(rippled, rippled_heights())
    x = np.linspace(-1.0, 1.0, 201)
    np.save(sloped, Slope(0.0, angle_deg=10.0).height(*np.meshgrid(x, x)))
    return flat, rippled, sloped


def hfield_model(folder):
    """The hexapod's MJCF with an <hfield> geom 'terrain' in its world body holding the
    rippled grid (2 m x 2 m centred on the origin, heights -1 .. +1 cm), written to
    `folder`; returns its path. (The hexapod model itself has no hfield.)"""
    models = resources.models_dir()
    heights = rippled_heights()
    low, high = heights.min(), heights.max()
    elevation = ' '.join(f'{value:.6f}' for value in ((heights - low) / (high - low)).ravel())
    xml = (models / 'hexapod.xml').read_text()
    xml = xml.replace('meshdir="assets"', f'meshdir="{models / "assets"}"', 1)
    xml = xml.replace('<asset>', f'<asset><hfield name="ripples" nrow="{heights.shape[0]}" '
                                 f'ncol="{heights.shape[1]}" size="1 1 {high - low} 0.01" '
                                 f'elevation="{elevation}"/>', 1)
    xml = xml.replace('<worldbody>', '<worldbody><geom name="terrain" type="hfield" '
                                     f'hfield="ripples" pos="0 0 {low}"/>', 1)
    path = Path(folder) / 'hexapod_hfield.xml'
    path.write_text(xml)
    return path


def cases(folder):
    """(label, scene overrides) of the surfaces measured; 'plane' is the reference."""
    flat, rippled, sloped = grid_files(folder)
    grid = {'sand.surface.type': 'grid', 'sand.surface.size': [2.0, 2.0]}
    return (
        ('plane', {}),
        ('slope 0 deg (slope path, the plane\'s physics)', {'sand.surface.type': 'slope'}),
        ('slope 10 deg', {'sand.surface.type': 'slope', 'sand.surface.angle_deg': 10.0}),
        ('height grid 2 m at 1 cm, flat (grid path, the plane\'s physics)',
         {**grid, 'sand.surface.file': str(flat)}),
        ('height grid 2 m at 1 cm, the 10 deg slope (the slope\'s physics)',
         {**grid, 'sand.surface.file': str(sloped)}),
        ('height grid 2 m at 1 cm, rippled +-1 cm', {**grid, 'sand.surface.file': str(rippled)}),
        ('the model\'s own hfield, the same ripples', {
            'model': str(hfield_model(folder)), 'sand.surface.type': 'hfield',
            'sand.surface.geom': 'terrain'}),
        ('deformable 2 m x 2 m, 1 cm', BED),
        ('deformable 8 m x 8 m, 1 cm', {**BED, 'sand.deformable.size': [8.0, 8.0]}),
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

    def _answer(self):
        line = self.process.stdout.readline()
        if not line:
            raise RuntimeError(f'engine step worker exited with {self.process.wait()}')
        return json.loads(line)

    def chunk(self):
        """CPU time per engine step (s) over one gait cycle."""
        self.process.stdin.write('chunk\n')
        self.process.stdin.flush()
        return self._answer()['step_s']

    def close(self):
        self.process.stdin.close()
        self.process.wait()


def surface_costs(rounds=5, baseline=None, processes=1, log=print):
    """Median engine-step CPU time per case and its ratio to the plane (median of per-round
    ratios); with `baseline` (a code folder), the plane of that code as one more case. With
    `processes` > 1 each case runs in that many worker processes and a round's sample of a
    case is their mean: the same code reads up to about 2 % apart in two processes, for the
    life of each (where its compiled code and arrays landed), and the mean evens that out."""
    with tempfile.TemporaryDirectory() as folder:
        plan = [(label, CODE, overrides) for label, overrides in cases(folder)]
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
                         'package': workers[label][0].info['package']}
    return result


def markdown(results):
    machine = results['machine']
    lines = ['# Step cost of the sand surfaces', '',
             f'Machine: {machine["cpu"]}, {machine["cores"]} cores (shared); Python '
             f'{machine["python"]}, MuJoCo {machine["mujoco"]}, numpy {machine["numpy"]}. '
             'Hexapod walking (500 plates per leg segment, 0.8 ms): CPU time per engine step '
             f'(sand + MuJoCo), {results.get("processes", 1)} worker process(es) per case (a '
             'round\'s sample: their mean), the cases taking turns one gait '
             f'cycle each over {results["rounds"]} rounds; medians, and ratios to the plane as '
             'the median of per-round ratios. Produced by `python -m '
             'rft_sim_ros.bench.terrain_cost`.', '',
             '| surface | us/step | vs plane |', '|---|---|---|']
    for label, row in results['cases'].items():
        lines.append(f'| {label} | {row["step_s"] * 1e6:.1f} | {row["ratio_to_plane"]:.3f} |')
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
    results = {'machine': machine_info(), 'rounds': args.rounds,
               'load_before': os.getloadavg()[0],
               'processes': args.processes,
               'cases': surface_costs(args.rounds, args.baseline, args.processes, log),
               'load_after': os.getloadavg()[0],
               'baseline': args.baseline_label or args.baseline}
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / 'terrain_cost.json').write_text(json.dumps(results, indent=2) + '\n')
    (out / 'terrain_cost.md').write_text(markdown(results))
    print(f'wrote {out / "terrain_cost.md"}', file=sys.stderr)


if __name__ == '__main__':
    main()
