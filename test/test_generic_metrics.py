"""Generic metrics: the per-body sand depth against a plate-by-plate reference on every
kind of surface (the metric stacks all bodies into one product for speed)."""
import numpy as np
import pytest

from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sim.metrics import GenericMetrics
from rft_sim_ros.sim.simulation import Simulation

#: Hexapod on few plates, the two segments of the front left leg with other counts, so that
#: bodies of unequal plate counts share the stacked product.
_HEXAPOD = {'gait': 'none', 'drop_height': 0.0, 'rft.plates_per_body': 60,
            'rft.plates': {'L1_mid': 23, 'L1_dactyl': 97}}

_SURFACES = {
    'plane': {'sand.surface_height': 0.01},
    'slope': {'sand.surface.type': 'slope', 'sand.surface.angle_deg': 12.0,
              'sand.surface.downhill_deg': 35.0},
    'grid': {'sand.surface.type': 'grid', 'sand.surface.size': [1.0, 0.8],
             'sand.surface.height_range': [-0.02, 0.03]},
    'deformable': {'sand.deformable.enabled': True, 'sand.deformable.size': [0.8, 0.8]},
}


def _reference_depths(sim):
    """(sand bodies,) m: each plate rotated into the world on its own, its depth below the
    surface at its own (x, y); the body's deepest, 0 if none is below (the engine's first
    bodies are the sand bodies; the others' plates follow)."""
    engine, data = sim.engine, sim.data
    depths = []
    assert engine.body_names[:len(sim.sand_bodies)] == sim.sand_bodies
    for b, body in enumerate(engine.body_ids[:len(sim.sand_bodies)]):
        local = engine.local_pos[engine.plate_start[b]:engine.plate_start[b + 1]]
        world = np.array([data.xmat[body].reshape(3, 3) @ p + data.xpos[body] for p in local])
        below = engine.surface.height(world[:, 0], world[:, 1]) - world[:, 2]
        depths.append(max(below.max(), 0.0))
    return np.array(depths)


@pytest.mark.parametrize('surface', sorted(_SURFACES))
def test_depths_are_the_deepest_plate_of_each_body_below_the_local_surface(surface, tmp_path):
    overrides = dict(_SURFACES[surface])
    if surface == 'grid':
        x, y = np.meshgrid(np.linspace(0, 4, 33), np.linspace(0, 3, 25))
        np.save(tmp_path / 'dunes.npy', np.sin(x) * np.cos(y))
        overrides['sand.surface.file'] = str(tmp_path / 'dunes.npy')
    sim = Simulation(load_scene('hexapod', {**_HEXAPOD, **overrides}))
    metrics = GenericMetrics(sim)
    in_sand = set()
    for _ in range(6):
        sim.step(100)
        depths = metrics.depths(sim.data)
        np.testing.assert_allclose(depths, _reference_depths(sim), rtol=0, atol=1e-15)
        in_sand |= set(np.flatnonzero(depths > 0))
    assert len(in_sand) >= 6  # the feet are in the sand, the case the metric is about
    assert (depths >= 0).all()
