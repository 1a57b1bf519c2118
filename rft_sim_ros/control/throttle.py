"""Rate-limited log lines: at most one line per key per period, with a count of the rest.

Used for rejected commands: a controller that sends a bad message at 100 Hz gets one line
naming the problem every `period_s` seconds instead of a flood. ROS-free; the node passes
its logger's warning method as `emit`.
"""
import time
from collections import Counter


class ThrottledLog:
    """Emit at most one message per key every `period_s` seconds of `clock`.

    emit: called with the text of each line that passes. clock: returns seconds (default
    wall time, time.monotonic; pass a sim-time source to throttle in sim time).
    A line that passes after suppressed ones ends with how many were suppressed.
    """

    def __init__(self, emit, period_s, clock=time.monotonic):
        if not period_s >= 0.0:
            raise ValueError(f'period_s must be >= 0, got {period_s}')
        self._emit = emit
        self._period = float(period_s)
        self._clock = clock
        self._last = {}
        self._suppressed = Counter()

    def __call__(self, key, message):
        """Log `message` under `key` unless one was logged under `key` within the period.

        Returns True if the line was emitted.
        """
        now = self._clock()
        last = self._last.get(key)
        if last is not None and now - last < self._period:
            self._suppressed[key] += 1
            return False
        suppressed = self._suppressed.pop(key, 0)
        if suppressed:
            message = f'{message} ({suppressed} similar suppressed)'
        self._emit(message)
        self._last[key] = now
        return True
