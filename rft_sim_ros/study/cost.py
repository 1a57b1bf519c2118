"""Which runs to hand out first: the dearest.

A pool that hands out runs in the order they are listed can end a study, a validation or a
sweep with one long run on one worker while the others idle (e.g. a converged reference run
listed last). Handing out the runs with the largest expected cost first (the
longest-processing-time-first rule) keeps the wall time within 4/3 of the best possible
schedule. Outcomes carry their index, so results and their order do not change.
"""
from ..sim.runner import run_duration


def run_cost(scene, duration=None):
    """Expected relative cost of running `scene` (SceneConfig) for `duration` s (None: the
    scene's): its steps times its plates (the sand step dominates; how many plates will be
    in the sand is not known before the run). A scene whose plates come from a density
    counts one plate per sand body (its plate count needs the model)."""
    steps = run_duration(scene, duration) / scene.timestep
    if scene.plates_by_body:
        plates = sum(scene.plates_by_body.values())
    else:
        plates = (scene.plates_per_body or 1) * max(1, len(scene.sand_bodies))
    return steps * plates


def dearest_first(costs):
    """Indices of `costs` from the largest cost to the smallest (ties in listed order)."""
    return sorted(range(len(costs)), key=lambda i: -costs[i])
