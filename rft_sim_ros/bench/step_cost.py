"""Step cost of the sand simulation against plain MuJoCo, measured in one process and run.

The hexapod walks its tripod gait in both: on RFT sand (the `hexapod` scene: 500 plates per
sand body, 0.8 ms) and on MuJoCo's rigid floor (models/hexapod_rigid_floor.xml, same
robot, timestep and servo targets). Chunks of steps alternate between the two so that
machine noise hits both alike; we report medians of the per-step wall times and the median
of the per-chunk ratios.
"""
import time

import mujoco
import numpy as np

from .. import resources
from ..ros.recording import BagRecorder
from ..scenes.gaits import make_gait
from ..sim.runner import run_scene
from ..scenes.config import load_scene
from ..sim.simulation import Simulation


def _rigid_hexapod(timestep):
    model = mujoco.MjSpec.from_file(str(resources.models_dir() / 'hexapod_rigid_floor.xml')).compile()
    model.opt.timestep = timestep
    return model, mujoco.MjData(model)


def hexapod_step_cost(chunks=9, chunk_steps=1000, overrides=None, settle_steps=2500):
    """Median wall time per step (s) of: the full sand Simulation step (scene control, servo
    commands, RFT, MuJoCo), the sand engine alone (RFT + MuJoCo, targets precomputed), and
    the rigid-floor mj_step of the same robot walking the same targets."""
    sim = Simulation(load_scene('hexapod', overrides or {}))
    dt = sim.timestep
    sim.step(settle_steps)  # dropped, settled, walking
    model, data = _rigid_hexapod(dt)
    gait = make_gait('tripod')
    actuators = np.array([model.actuator(name).id for name in gait.joint_names])
    # the same joints, in the scene's servo order (index arrays in both loops, so that
    # writing the controls costs the same in both)
    servo = sim.interfaces.position_actuators
    order = [gait.joint_names.index(name) for name in sim.servo_joint_names]

    def targets_from(t0):  # gait targets for the coming chunk, computed outside the timing
        return np.array([gait.targets(t0 + i * dt) for i in range(chunk_steps)])

    for row in targets_from(0.0):
        data.ctrl[actuators] = row
        mujoco.mj_step(model, data)
    full, engine_only, rigid = [], [], []
    for _ in range(chunks):
        start = time.perf_counter()
        sim.step(chunk_steps)
        full.append((time.perf_counter() - start) / chunk_steps)
        table = targets_from(sim.time)[:, order]
        ctrl, engine_step = sim.data.ctrl, sim.engine.step
        start = time.perf_counter()
        for i in range(chunk_steps):
            ctrl[servo] = table[i]
            engine_step()
        engine_only.append((time.perf_counter() - start) / chunk_steps)
        table = targets_from(data.time)
        ctrl = data.ctrl
        start = time.perf_counter()
        for i in range(chunk_steps):
            ctrl[actuators] = table[i]
            mujoco.mj_step(model, data)
        rigid.append((time.perf_counter() - start) / chunk_steps)
    full, engine_only, rigid = map(np.array, (full, engine_only, rigid))
    return {
        'timestep_s': dt,
        'plates_total': sim.engine.plates_total,
        'plates_active_last': int(sim.engine.plates_active),
        'chunks': chunks, 'chunk_steps': chunk_steps,
        'sand_step_s': float(np.median(full)),
        'sand_engine_step_s': float(np.median(engine_only)),
        'rigid_step_s': float(np.median(rigid)),
        'ratio_full_to_rigid': float(np.median(full / rigid)),
        'ratio_engine_to_rigid': float(np.median(engine_only / rigid)),
        'real_time_factor_full': float(dt / np.median(full)),
        'real_time_factor_rigid': float(dt / np.median(rigid)),
    }



def hexapod_trial(overrides=None, bag=None):
    """A whole `hexapod` run (drop, settle, gait cycles) timed in two parts of the same run:
    the run's summary, and the wall and sim time (s) of its walk alone, from `settle_time` to
    the end (the paper's 5 s trial is the walk). bag: a new folder to record the run's
    rosbag2 into, as `rft-sim run` does by default (None: no bag, as `--no-bag`)."""
    scene = load_scene('hexapod', overrides or {})
    params = scene.params
    settle = float(params['settle_time'])
    end = settle + float(params['cycles']) / float(params['frequency'])
    marks = []
    recorders = [BagRecorder(bag, scene)] if bag is not None else []
    summary = run_scene(scene, duration=end, progress=False, plots=False, recorders=recorders,
                        schedule=[(t, lambda sim: marks.append((time.perf_counter(), sim.time)))
                                  for t in (settle, end)])
    (wall_start, sim_start), (wall_end, sim_end) = marks
    return summary, {'sim_time_s': sim_end - sim_start, 'wall_time_s': wall_end - wall_start,
                     'real_time_factor': (sim_end - sim_start) / (wall_end - wall_start)}
