"""What a run's video costs: a scene run with its bag, without and with `--video`, on this
machine (wall and CPU seconds, their ratios, and per frame the CPU, rendering and encoding).

    python -m rft_sim_ros.bench.video_cost [SCENE] [DURATION_S] [REPEATS] [KEY=VALUE ...]

Each run is made REPEATS times (3), alternating without and with, and the medians are given.
CPU time counts every thread of both processes (the run's and its video painter's, whose
renderer, Mesa's llvmpipe, renders on several threads): on a machine shared with other work
it says more than the wall time. `frame_cpu_ms` is the painter's CPU per frame, rendering
and encoding (its start-up left out): the cost of a frame as if alone on the machine.
"""
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path


def _run(scene, out, duration, video):
    from ..render.recorder import VideoRecorder
    from ..ros.recording import BagRecorder
    from ..sim.runner import run_scene
    recorders = [BagRecorder(out / 'bag', scene)]
    if video:
        recorder = VideoRecorder(out / 'video.mp4', scene)
        recorders.append(recorder)
    cpu = time.process_time()
    summary = run_scene(scene, out, duration=duration, recorders=recorders, progress=False,
                        plots=False)
    cpu = time.process_time() - cpu
    result = {'wall_s': summary['wall_time_s'], 'cpu_s': cpu,
              'sim_time_s': summary['sim_time_s']}
    if video:
        frames = recorder.frames
        result.update(cpu_s=cpu + recorder.painter_cpu_s, frames=frames,
                      waited_s=recorder.waited_s,
                      frame_cpu_ms=1e3 * recorder.frames_cpu_s / frames,
                      render_ms_per_frame=1e3 * recorder.render_s / frames,
                      encode_ms_per_frame=1e3 * recorder.encode_s / frames)
    return result


def video_cost(scene_name='hexapod', duration=6.0, repeats=3, width=640, height=480,
               overrides=None):
    """Medians of `repeats` runs of the scene, `duration` s with its bag, without and with
    its video at `width` x `height` (and the scene values `overrides`, e.g. video.fps):
    {'without': {...}, 'with': {...}, 'wall_ratio', 'cpu_ratio', 'runs': every run}."""
    from ..scenes.config import load_scene
    overrides = {'video.width': width, 'video.height': height, **(overrides or {})}
    scene = load_scene(scene_name, overrides)
    runs = {'without': [], 'with': []}
    with tempfile.TemporaryDirectory() as folder:
        for repeat in range(repeats):
            for label in ('without', 'with'):
                out = Path(folder) / f'{label}{repeat}'
                runs[label].append(_run(scene, out, duration, label == 'with'))
    medians = {label: {key: statistics.median(run[key] for run in results)
                       for key in results[0]} for label, results in runs.items()}
    return {**medians, 'scene': scene_name, 'duration_s': duration, 'size': [width, height],
            'fps': scene.values['video.fps'],
            'wall_ratio': medians['with']['wall_s'] / medians['without']['wall_s'],
            'cpu_ratio': medians['with']['cpu_s'] / medians['without']['cpu_s'],
            'runs': runs}


if __name__ == '__main__':
    import os
    from ..scenes.config import parse_assignment
    from ..sim.runner import machine_info
    arguments = sys.argv[1:]
    result = video_cost(arguments[0] if arguments else 'hexapod',
                        float(arguments[1]) if len(arguments) > 1 else 6.0,
                        int(arguments[2]) if len(arguments) > 2 else 3,
                        overrides=dict(parse_assignment(text) for text in arguments[3:]))
    print(json.dumps({**result, 'cpu': machine_info()['cpu'],
                      'load_average': os.getloadavg()}, indent=2))
