"""The painting process of a run's video (`recorder.VideoRecorder`): it paints the frames it
is given (`Frame`) on its copy of the drawn model (`drawn_model.DrawnModel`) and encodes them
into the MP4 (`encoder.Mp4Writer`), while the simulation steps on in its parent.

    python -m rft_sim_ros.render.painting    (started by the recorder, never by hand)

It reads pickled objects on stdin: first (drawn model, VideoSettings, path), then one Frame
at a time, then None, the end. It writes one byte on stdout for each frame painted
(FRAME_DONE) and at the end DONE followed by its pickled answer: the frames written, its
render and encode wall times, the CPU time of the frames and of the whole process (all its
threads, the renderer's too; its start-up included), s; or the error. It runs in a session
of its own (a Ctrl-C at the terminal reaches its parent only: the parent ends the run and
then sends the end, after the frames it gave), ends at the end or when its stdin closes (a
killed parent), and always finishes the file.
"""
import os
import pickle
import sys
import time
from dataclasses import dataclass

import numpy as np

#: What the painter writes on stdout: a frame painted; the end (its answer follows).
FRAME_DONE, DONE = b'.', b'!'


@dataclass
class Frame:
    """One frame to paint, `repeat` times: the pose (qpos, mocap_pos, mocap_quat of the
    simulation), deformable sand when it changed (`stage.Stage.sand_drawing`, else None),
    plates (decorations.Plates or None), legs ((point, force) pairs, m and N, world) and
    the overlay's lines ((label, value) texts)."""
    qpos: np.ndarray
    mocap_pos: np.ndarray
    mocap_quat: np.ndarray
    sand: tuple
    plates: object
    legs: list
    lines: list
    repeat: int


def paint_frames(source, sink):
    """Paint and encode what the binary stream `source` gives (module docstring); answer
    on the binary stream `sink`."""
    result = {'frames': 0, 'render_s': 0.0, 'encode_s': 0.0, 'frames_cpu_s': 0.0}
    painter = writer = None
    try:
        from .encoder import Mp4Writer
        from .frames import FramePainter
        stage, settings, path = pickle.load(source)
        painter = FramePainter(stage, settings)
        writer = Mp4Writer(path, settings.width, settings.height, settings.fps)
        while True:
            try:
                frame = pickle.load(source)
            except EOFError:  # (the parent is gone)
                break
            if frame is None:
                break
            started, cpu = time.perf_counter(), time.process_time()
            stage.pose(frame.qpos, frame.mocap_pos, frame.mocap_quat)
            if frame.sand is not None:
                stage.draw_sand(frame.sand)
            pixels = painter.paint(frame.plates, frame.legs, frame.lines,
                                   sand_changed=frame.sand is not None)
            rendered = time.perf_counter()
            writer.write(pixels, repeat=frame.repeat)
            result['render_s'] += rendered - started
            result['encode_s'] += time.perf_counter() - rendered
            result['frames_cpu_s'] += time.process_time() - cpu
            _send(sink, FRAME_DONE)
    except Exception as error:  # (told to the parent, which raises it)
        result['error'] = ' '.join(str(error).split()) or type(error).__name__
    finally:
        try:
            if writer is not None:
                writer.close()
                result['frames'] = writer.frames
        finally:
            if painter is not None:
                painter.close()
            result['cpu_s'] = time.process_time()
            _send(sink, DONE + pickle.dumps(result))


def _send(sink, data):
    try:
        sink.write(data)
        sink.flush()
    except OSError:  # (the parent is gone)
        pass


def main():
    """The process: stdin and stdout as the module docstring says; what else would be
    printed (a library's warnings) goes to stderr, not into the answers."""
    answers = os.fdopen(os.dup(1), 'wb')
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    paint_frames(sys.stdin.buffer, answers)


if __name__ == '__main__':
    main()
