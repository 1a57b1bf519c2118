"""MP4 files of RGB frames: H.264 in yuv420p (what browsers play), through PyAV (the `av`
package: FFmpeg's libraries with libx264, in its wheels).

The file is a fragmented MP4 (a fragment per keyframe, one a second), each fragment flushed
to the file as it is finished (not held in FFmpeg's output buffer): every fragment written
is playable on its own, so a run stopped at any point (Ctrl-C, a crash, a kill) leaves a
video of what was rendered up to the last whole second, and one closed normally holds every
frame."""
from fractions import Fraction

#: libx264 settings: constant quality 23 (its default), the 'veryfast' preset (a quarter of
#: 'medium''s CPU for a few per cent more bytes), a keyframe every second, no B-frames
#: (with them the fragmented MP4, which has no edit list, starts its first frame two frames
#: late: the picture of sim time t would show at t + 2 / fps).
CRF = '23'
PRESET = 'veryfast'


class Mp4Writer:
    """Writes (height, width, 3) uint8 RGB frames at `fps` frames per second into `path`
    (width and height even). Use as a context, or `close()` it: the last frames are in the
    file once closed."""

    def __init__(self, path, width, height, fps):
        import av
        if width % 2 or height % 2:
            raise ValueError(f'an H.264 video (yuv420p) needs an even width and height, got '
                             f'{width} x {height}')
        self.path, self.frames = path, 0
        self._av = av
        rate = Fraction(fps).limit_denominator(1001)
        self._container = av.open(str(path), mode='w', format='mp4', options={
            'movflags': 'frag_keyframe+empty_moov+default_base_moof', 'flush_packets': '1'})
        stream = self._container.add_stream('libx264', rate=rate)
        stream.width, stream.height, stream.pix_fmt = width, height, 'yuv420p'
        keyframes = str(max(1, round(float(rate))))
        stream.options = {'crf': CRF, 'preset': PRESET, 'g': keyframes,
                          'keyint_min': keyframes, 'bf': '0'}
        self._stream, self._time_base = stream, 1 / rate

    def write(self, rgb, repeat=1):
        """Append the frame `rgb` `repeat` times."""
        frame = self._av.VideoFrame.from_ndarray(rgb, format='rgb24')
        frame.time_base = self._time_base
        for _ in range(repeat):
            frame.pts = self.frames
            self._container.mux(self._stream.encode(frame))
            self.frames += 1

    def close(self):
        """Encode what the codec holds and finish the file (again: nothing)."""
        if self._container is None:
            return
        try:
            self._container.mux(self._stream.encode(None))
        finally:
            self._container.close()
            self._container = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
