"""What a run's video costs: a scene run with its bag, without and with `--video`, on this
machine (wall and CPU seconds, the ratio, and per frame the rendering and the encoding).

    python -m rft_sim_ros.bench.video_cost [SCENE] [DURATION_S]

CPU time counts every thread of the process (Mesa's llvmpipe renders on several), so on a
machine shared with other work it says more than the wall time.
"""
import json
import sys
import tempfile
import time
from pathlib import Path


def video_cost(scene_name='hexapod', duration=6.0, width=640, height=480, fps=30.0):
    """{'without': {...}, 'with': {...}, 'wall_ratio', 'cpu_ratio', 'frames',
    'render_ms_per_frame', 'encode_ms_per_frame'}: the scene run `duration` s with its bag,
    then again with its video at `width` x `height`, `fps`."""
    from ..render.recorder import VideoRecorder
    from ..ros.recording import BagRecorder
    from ..scenes.config import load_scene
    from ..sim.runner import run_scene
    scene = load_scene(scene_name, {'video.width': width, 'video.height': height,
                                    'video.fps': fps})
    results = {}
    with tempfile.TemporaryDirectory() as folder:
        for label in ('without', 'with'):
            out = Path(folder) / label
            recorders = [BagRecorder(out / 'bag', scene)]
            if label == 'with':
                video = VideoRecorder(out / 'video.mp4', scene)
                recorders.append(video)
            cpu = time.process_time()
            summary = run_scene(scene, out, duration=duration, recorders=recorders,
                                progress=False, plots=False)
            results[label] = {'wall_s': summary['wall_time_s'],
                              'cpu_s': time.process_time() - cpu,
                              'recording_s': summary['recording_time_s']}
    frames = video.frames
    return {**results, 'scene': scene_name, 'duration_s': duration,
            'size': [width, height], 'fps': fps, 'frames': frames,
            'wall_ratio': results['with']['wall_s'] / results['without']['wall_s'],
            'cpu_ratio': results['with']['cpu_s'] / results['without']['cpu_s'],
            'render_ms_per_frame': 1e3 * video.render_s / frames,
            'encode_ms_per_frame': 1e3 * video.encode_s / frames}


if __name__ == '__main__':
    from ..sim.runner import machine_info
    arguments = sys.argv[1:]
    result = video_cost(arguments[0] if arguments else 'hexapod',
                        float(arguments[1]) if len(arguments) > 1 else 6.0)
    print(json.dumps({**result, 'cpu': machine_info()['cpu']}, indent=2))
