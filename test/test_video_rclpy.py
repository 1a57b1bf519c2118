"""The simulator node's video (`video_path`): recorded through the same recorder as
`rft-sim run --video`, finished when the node stops on a signal; an existing file refused.

Runs the node's executable where ROS 2 Jazzy is sourced (rclpy) and frames can be rendered;
skipped with the reason everywhere else. A plate dropped on sand in small frames.
"""
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy', reason='ROS 2 Jazzy (rclpy) is not installed here')
av = pytest.importorskip('av')

from rft_sim_ros.render.gl import offscreen_problem  # noqa: E402
from test_node_rclpy import _wait_for_output  # noqa: E402

OFFSCREEN = offscreen_problem()

pytestmark = [pytest.mark.ros,
              pytest.mark.skipif(OFFSCREEN is not None, reason=OFFSCREEN or '')]

#: A DDS domain of this test process (no other ROS graph mixes in).
DOMAIN_ID = int(os.environ.get('ROS_DOMAIN_ID') or 101 + os.getpid() % 100)
WIDTH, HEIGHT, FPS = 160, 120, 20
SMALL = ['rft.plates_per_body=64', f'video.width={WIDTH}', f'video.height={HEIGHT}',
         f'video.fps={FPS}']


def _node(*parameters):
    """The simulator's executable with `parameters` ('name:=value'), on this test's domain."""
    arguments = [part for parameter in parameters for part in ('-p', parameter)]
    return subprocess.Popen([sys.executable, '-m', 'rft_sim_ros.ros.node', '--ros-args',
                             *arguments],
                            env=dict(os.environ, ROS_DOMAIN_ID=str(DOMAIN_ID),
                                     PYTHONUNBUFFERED='1'),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_the_node_records_its_video_and_finishes_it_when_stopped_with_ctrl_c(tmp_path):
    video = tmp_path / 'node.mp4'
    overrides = '[' + ', '.join(f"'{value}'" for value in SMALL) + ']'
    node = _node('scene:=plate_drop', f'video_path:={video}', 'real_time_factor:=0.0',
                 f'scene_overrides:={overrides}')
    try:
        logged = _wait_for_output(node, 'publishing every', timeout=300.0)
        time.sleep(4.0)  # simulating and recording as fast as it can
        node.send_signal(signal.SIGINT)
        _, stderr = node.communicate(timeout=120)
    finally:
        if node.poll() is None:
            node.kill()
            node.communicate()
    stderr = ''.join(logged) + stderr
    assert node.returncode == 0 and 'Traceback' not in stderr, stderr
    said = [line for line in stderr.splitlines() if 'video_path:' in line]
    assert len(said) == 1 and f'frames in {video}' in said[0], stderr
    written = int(said[0].split('video_path: ')[1].split()[0])
    with av.open(str(video)) as container:
        stream = container.streams.video[0]
        assert (stream.codec_context.name, stream.width, stream.height) == ('h264', WIDTH,
                                                                            HEIGHT)
        frames = [frame.to_ndarray(format='rgb24') for frame in container.decode(video=0)]
    assert len(frames) == written >= 5  # the frames of the time it ran, each one finished
    assert np.asarray(frames[-1], float).std() > 10  # drawn: sky, sand, the plate


def test_a_video_path_that_exists_is_refused_before_anything_runs(tmp_path):
    video = tmp_path / 'taken.mp4'
    video.write_bytes(b'a video of another run')
    node = _node('scene:=plate_drop', f'video_path:={video}')
    _, stderr = node.communicate(timeout=300)
    assert node.returncode == 1, stderr
    assert 'cannot start' in stderr and 'exists' in stderr and 'Traceback' not in stderr
    assert video.read_bytes() == b'a video of another run'
