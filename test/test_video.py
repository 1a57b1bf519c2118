"""Videos of runs (rft_sim_ros/render): a run's MP4 written and decodable (frames, size,
H.264 in yuv420p), its frames showing the robot; the same video rendered again from the
run's bag; a run stopped early leaving a playable video; `rft-sim view` under Xvfb with a
screenshot of its window; one clear line where no frame or window can be made.

Frames are small and runs short (a plate dropped for a fraction of a second)."""
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from rft_sim_ros.render.gl import offscreen_problem
from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sim.runner import run_scene
from test_cli import _as_in_a_terminal

av = pytest.importorskip('av')

OFFSCREEN = offscreen_problem()
needs_rendering = pytest.mark.skipif(OFFSCREEN is not None, reason=OFFSCREEN or '')

WIDTH, HEIGHT, FPS = 160, 120, 20
SMALL = {'rft.plates_per_body': 64, 'video.width': WIDTH, 'video.height': HEIGHT,
         'video.fps': FPS, 'video.plates': False}


def _scene(**more):
    return load_scene('plate_drop', {**SMALL, **more})


def _decode(path):
    """(codec name, pix_fmt, (width, height), [RGB frames])."""
    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        frames = [frame.to_ndarray(format='rgb24') for frame in container.decode(video=0)]
        return (stream.codec_context.name, stream.codec_context.pix_fmt,
                (stream.width, stream.height), frames)


def _run_with_video(out, scene, duration, bag=False, stop=None):
    from rft_sim_ros.render.recorder import VideoRecorder
    recorders = [VideoRecorder(out / 'video.mp4', scene)]
    if bag:
        from rft_sim_ros.ros.recording import BagRecorder
        recorders.append(BagRecorder(out / 'bag', scene))
    summary = run_scene(scene, out, duration=duration, recorders=recorders, progress=False,
                        plots=False, stop=stop)
    return summary, recorders[0]


def _robot_hidden_frame(scene, time_s):
    """A frame of the scene's simulation at `time_s` with the robot's geoms hidden: what the
    camera sees of the sand and sky alone."""
    from rft_sim_ros.render.frames import FramePainter, VideoSettings
    from rft_sim_ros.render.recorder import overlay
    from rft_sim_ros.render.stage import Stage
    from rft_sim_ros.sim.simulation import Simulation
    sim = Simulation(scene)
    sim.step(int(round(time_s / sim.timestep)))
    stage = Stage(sim, WIDTH, HEIGHT)
    moving = stage.model.body_weldid[stage.model.geom_bodyid] != 0
    stage.model.geom_rgba[moving, 3] = 0.0
    painter = FramePainter(stage, VideoSettings.from_scene(scene))
    try:
        return painter.paint(lines=overlay(sim.time, sim.zeta)).copy()
    finally:
        painter.close()


@needs_rendering
def test_a_run_with_video_writes_a_decodable_h264_of_its_frames_showing_the_robot(tmp_path):
    scene = _scene()
    summary, recorder = _run_with_video(tmp_path, scene, duration=0.3)
    codec, pix_fmt, size, frames = _decode(tmp_path / 'video.mp4')
    assert (codec, pix_fmt, size) == ('h264', 'yuv420p', (WIDTH, HEIGHT))
    assert len(frames) == recorder.frames == round(0.3 * FPS) + 1  # t = 0, 0.05, ..., 0.3
    with av.open(str(tmp_path / 'video.mp4')) as container:  # each at its sim time
        times = [frame.time for frame in container.decode(video=0)]
    assert times == pytest.approx([k / FPS for k in range(len(frames))])
    assert summary['sim_time_s'] == pytest.approx(0.3)
    last = frames[-1].astype(float)
    assert last.std() > 10  # not blank: sky, sand, the plate
    empty = _robot_hidden_frame(scene, 0.3).astype(float)
    differs = np.abs(last - empty).max(axis=2) > 40  # pixels where the plate is
    assert 0.002 < differs.mean() < 0.5, differs.mean()
    rows, columns = np.nonzero(differs)  # the followed plate is in the middle of the frame
    assert abs(rows.mean() - HEIGHT / 2) < HEIGHT / 4
    assert abs(columns.mean() - WIDTH / 2) < WIDTH / 4


@needs_rendering
def test_the_video_rendered_from_the_runs_bag_matches_the_runs_own(tmp_path):
    from rft_sim_ros.render.frames import VideoSettings
    from rft_sim_ros.ros.bag_video import render_bag
    from rft_sim_ros.sim.simulation import Simulation
    scene = _scene(drop_height=0.05)
    _run_with_video(tmp_path, scene, duration=0.25, bag=True)
    frames = render_bag(tmp_path / 'bag', Simulation(scene), tmp_path / 'again.mp4',
                        VideoSettings.from_scene(scene))
    _, _, _, live = _decode(tmp_path / 'video.mp4')
    _, _, _, again = _decode(tmp_path / 'again.mp4')
    assert frames == len(again) == len(live)
    for a, b in zip(live, again):  # the same poses, up to the codec's noise
        assert np.abs(a.astype(float) - b.astype(float)).mean() < 2.0


@needs_rendering
def test_the_cli_renders_a_run_folder_again_from_its_summary_and_bag(tmp_path, capsys):
    from rft_sim_ros.cli import main
    out = tmp_path / 'run'
    assert main(['run', 'plate_drop', '--duration', '0.1', '--out', str(out), '--quiet',
                 '--video', *[f'--set={k}={v}' for k, v in SMALL.items()]]) == 0
    assert (out / 'video.mp4').is_file()
    assert main(['render', str(out)]) == 2  # the video is there: not replaced unasked
    assert 'exists' in capsys.readouterr().err
    assert main(['render', str(out), '--out', str(tmp_path / 'again.mp4')]) == 0
    assert len(_decode(tmp_path / 'again.mp4')[3]) == len(_decode(out / 'video.mp4')[3])
    assert main(['render', str(out / 'bag')]) == 2  # a bag alone needs its scene
    assert '--scene' in capsys.readouterr().err


class _StopAfter:
    """A stop request set once `is_set` has been asked `count` times."""

    def __init__(self, count):
        self.count, self.reason = count, 'test'

    def is_set(self):
        self.count -= 1
        return self.count < 0


@needs_rendering
def test_a_run_stopped_early_leaves_a_playable_video_of_what_was_rendered(tmp_path):
    summary, recorder = _run_with_video(tmp_path, _scene(), duration=5.0, stop=_StopAfter(12))
    assert summary['interrupted'] is True
    codec, _, _, frames = _decode(tmp_path / 'video.mp4')
    assert codec == 'h264' and len(frames) == recorder.frames
    assert 1 <= len(frames) <= round(summary['sim_time_s'] * FPS) + 1


@needs_rendering
def test_ctrl_c_ends_a_cli_run_with_its_whole_video(tmp_path):
    """SIGINT to the run's process group, as a terminal's Ctrl-C sends it (the video's
    painting process gets it too): the run stops, status 130, and the video holds every
    frame of the sim time it ran."""
    import json
    import math
    out = tmp_path / 'run'
    child = subprocess.Popen([sys.executable, '-m', 'rft_sim_ros', 'run', 'plate_drop',
                              '--video', '--duration', '600', '--out', str(out), '--quiet',
                              *[f'--set={k}={v}' for k, v in SMALL.items()]],
                             env={**os.environ, 'PYTHONPATH': os.getcwd()},
                             start_new_session=True, stderr=subprocess.PIPE, text=True,
                             preexec_fn=_as_in_a_terminal)
    try:
        deadline = time.monotonic() + 180
        while _playable_frames(out / 'video.mp4') < FPS:  # a second of video written
            assert child.poll() is None and time.monotonic() < deadline, child.stderr.read()
            time.sleep(0.5)
        os.killpg(child.pid, signal.SIGINT)
        _, stderr = child.communicate(timeout=120)
    finally:
        if child.poll() is None:
            os.killpg(child.pid, signal.SIGKILL)
            child.communicate()
    assert child.returncode == 130 and 'Traceback' not in stderr, stderr
    summary = json.loads((out / 'summary.json').read_text())
    assert summary['interrupted'] is True
    codec, _, _, frames = _decode(out / 'video.mp4')
    assert codec == 'h264'
    assert len(frames) == math.floor(summary['sim_time_s'] * FPS + 1e-6) + 1


@needs_rendering
def test_a_killed_run_leaves_the_fragments_written_playable(tmp_path):
    """SIGKILL: nothing is closed, yet every whole fragment (a second of video) plays."""
    script = (
        'import sys\n'
        'from rft_sim_ros.render.recorder import VideoRecorder\n'
        'from rft_sim_ros.scenes.config import load_scene\n'
        'from rft_sim_ros.sim.runner import run_scene\n'
        f'scene = load_scene("plate_drop", {SMALL!r})\n'
        'run_scene(scene, None, duration=600, progress=False,\n'
        '          recorders=[VideoRecorder(sys.argv[1], scene)])\n')
    video = tmp_path / 'video.mp4'
    child = subprocess.Popen([sys.executable, '-c', script, str(video)],
                             env={**os.environ, 'PYTHONPATH': os.getcwd()})
    deadline = time.monotonic() + 180
    while _playable_frames(video) < 2 * FPS:  # two whole fragments written
        assert child.poll() is None and time.monotonic() < deadline
        time.sleep(0.5)
    child.send_signal(signal.SIGKILL)
    child.wait()
    codec, _, size, frames = _decode(video)
    assert codec == 'h264' and size == (WIDTH, HEIGHT) and len(frames) >= 2 * FPS


def _playable_frames(path):
    """Frames of the MP4 `path` that decode now (0: none yet, or not readable yet)."""
    try:
        return len(_decode(path)[3])
    except (OSError, av.error.FFmpegError, IndexError):
        return 0


def test_no_rendering_is_said_in_one_line_before_anything_runs(tmp_path):
    """EGL without a vendor library (glvnd told to look elsewhere): as a machine without
    Mesa's EGL."""
    env = {**os.environ, 'MUJOCO_GL': 'egl', '__EGL_VENDOR_LIBRARY_FILENAMES': '/nonesuch.json'}
    result = subprocess.run([sys.executable, '-m', 'rft_sim_ros', 'run', 'plate_drop',
                             '--video', '--out', str(tmp_path / 'run')],
                            env=env, capture_output=True, text=True)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and 'cannot render' in lines[0] and 'apt-get install' in lines[0]
    assert not (tmp_path / 'run').exists()  # nothing written


def test_view_without_a_display_says_so_in_one_line():
    env = {k: v for k, v in os.environ.items() if k not in ('DISPLAY', 'WAYLAND_DISPLAY')}
    result = subprocess.run([sys.executable, '-m', 'rft_sim_ros', 'view', 'plate_drop'],
                            env=env, capture_output=True, text=True)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and 'no display' in lines[0]


@pytest.fixture
def xvfb():
    """DISPLAY of a fresh Xvfb (a real X server) for the test; skips where Xvfb is missing."""
    binary = shutil.which('Xvfb')
    if binary is None:
        pytest.skip('Xvfb is not installed (apt-get install xvfb)')
    display = f':{90 + os.getpid() % 500}'
    server = subprocess.Popen([binary, display, '-screen', '0', '1600x1200x24', '-nolisten',
                               'tcp'], stderr=subprocess.DEVNULL)
    socket = f'/tmp/.X11-unix/X{display[1:]}'
    deadline = time.monotonic() + 20
    while not os.path.exists(socket):
        assert server.poll() is None and time.monotonic() < deadline, 'Xvfb did not start'
        time.sleep(0.05)
    yield display
    server.terminate()
    server.wait()


def _screenshot(display, size=(1600, 1200)):
    """The X screen `display` as an (height, width, 3) float RGB array (FFmpeg's x11grab),
    or None where the screen could not be read this time (a window being mapped)."""
    try:
        with av.open(f'{display}.0', format='x11grab',
                     options={'video_size': f'{size[0]}x{size[1]}'}) as screen:
            return next(screen.decode(video=0)).to_ndarray(format='rgb24').astype(float)
    except av.error.FFmpegError:
        return None


def test_view_opens_a_window_showing_the_scene_under_xvfb(xvfb):
    env = {**os.environ, 'DISPLAY': xvfb, 'PYTHONPATH': os.getcwd()}
    viewer = subprocess.Popen([sys.executable, '-m', 'rft_sim_ros', 'view', 'plate_drop',
                               '--set', 'rft.plates_per_body=64', '--duration', '600'],
                              env=env, stderr=subprocess.PIPE, text=True)
    sand = np.array([0.87, 0.76, 0.55]) * 255  # (lit, textured, seen through: near it)
    try:
        deadline = time.monotonic() + 240  # (the simulation is built first, then the window)
        while True:  # until the window shows the sand (the UI panels come first)
            assert viewer.poll() is None, viewer.communicate()[1]
            shot = _screenshot(xvfb)
            near_sand = 0.0 if shot is None else (np.abs(shot - sand) < 60).all(axis=2).mean()
            if near_sand > 0.05:
                break
            assert time.monotonic() < deadline, f'no sand in the window ({near_sand:.3f})'
            time.sleep(1.0)
        window = shot[(np.abs(shot - sand) < 60).all(axis=2).any(axis=1)]  # rows with sand
        assert window.std() > 10  # not a flat fill: the checker, the plate, the panels
    finally:
        viewer.send_signal(signal.SIGTERM)
        viewer.wait(timeout=30)


def test_deformable_sand_is_drawn_with_the_hole_a_body_stands_in_and_its_colour():
    """A plate resting in deformable sand has made no footprint yet (it is made when the
    plate leaves), but it is drawn standing in its hole, the hole coloured as dug."""
    from rft_sim_ros.render.stage import Stage
    from rft_sim_ros.sim.simulation import Simulation
    sim = Simulation(_scene(**{'sand.deformable.enabled': True, 'sand.deformable.size':
                               [0.4, 0.4]}))
    sim.step(int(round(0.4 / sim.timestep)))
    bed = sim.engine.surface
    assert bed.nodes_under_bodies > 0 and np.array_equal(bed.grid, bed.pristine)
    seen = bed.heights_as_seen()
    geom = sim.model.geom('plate_geom')
    plate_bottom = sim.data.geom_xpos[geom.id, 2] - geom.size[2]
    dug = seen < bed.pristine - 1e-4
    assert dug.sum() == pytest.approx(bed.nodes_under_bodies, rel=0.3)
    assert seen[dug].min() == pytest.approx(plate_bottom, abs=2e-3)
    stage = Stage(sim, WIDTH, HEIGHT)
    model = stage.model
    hfield = model.hfield('rft_bed')
    start, rows, columns = int(model.hfield_adr[hfield.id]), *seen.shape
    drawn = model.hfield_data[start:start + rows * columns].reshape(rows, columns)
    import mujoco
    geom = np.flatnonzero((model.geom_type == mujoco.mjtGeom.mjGEOM_HFIELD)
                          & (model.geom_dataid == hfield.id))[0]
    low = model.geom_pos[geom, 2]
    drawn_heights = low + model.hfield_size[hfield.id, 2] * drawn
    assert np.abs(drawn_heights - seen).max() < 1e-5  # the hole as the bed has it
    texture = model.texture('rft_bed')
    start = int(model.tex_adr[texture.id])
    rgb = model.tex_data[start:start + rows * columns * 3].reshape(rows, columns, 3)[::-1]
    assert (rgb[dug][:, 2] > rgb[dug][:, 0]).all()  # dug: blue over red
    assert (rgb[~dug][:, 0] > rgb[~dug][:, 2]).all()  # the rest: sand


def test_the_sand_keeps_its_colour_in_a_model_whose_geoms_default_to_another():
    """test/robots/biped gives every geom a colour in its <default>: the sand drawn in it
    has the sand's colour and opacity still (it had the robot's grey, opaque)."""
    from pathlib import Path
    import mujoco
    from rft_sim_ros.render.stage import SAND_RGB, Stage
    from rft_sim_ros.sim.simulation import Simulation
    biped = Path(__file__).parent / 'robots' / 'biped' / 'biped.xml'
    stage = Stage(Simulation(load_scene(biped, {'robot.keyframe': 'stand'})), sand_alpha=0.4)
    model = stage.model
    sand = np.flatnonzero((model.geom_type == mujoco.mjtGeom.mjGEOM_PLANE)
                          & (model.geom_matid >= 0))
    assert len(sand) == 1
    assert model.geom_rgba[sand[0]] == pytest.approx([*SAND_RGB, 0.4])
