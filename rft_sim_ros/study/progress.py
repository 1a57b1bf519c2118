"""A study's progress line on a terminal: runs done / failed / remaining and the time left;
silent when the stream is not a TTY (piped, in CI, in a log file)."""
import sys
import time


def _clock(seconds):
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    return f'{hours}:{rest // 60:02d}:{rest % 60:02d}' if hours else f'{rest // 60}:{rest % 60:02d}'


class StudyProgress:
    """update(done, failed) after each finished run; close() at the end. `total`: runs this
    session runs (resumed runs are not counted), so the estimate uses this session's pace."""

    def __init__(self, total, stream=sys.stderr, enabled=True):
        self.total, self.stream = total, stream
        self.enabled = enabled and hasattr(stream, 'isatty') and stream.isatty()
        self.started = time.monotonic()
        self.update(0, 0)

    def line(self, done, failed):
        remaining = self.total - done
        elapsed = time.monotonic() - self.started
        eta = f'{_clock(elapsed / done * remaining)} left' if done else 'time left: ...'
        filled = 30 * done // self.total if self.total else 30
        return (f'[{"#" * filled}{"." * (30 - filled)}] {done}/{self.total} done, '
                f'{failed} failed, {remaining} remaining, {eta}')

    def update(self, done, failed):
        if self.enabled:
            self.stream.write('\r' + self.line(done, failed) + '\x1b[K')
            self.stream.flush()

    def close(self):
        if self.enabled:
            self.stream.write('\n')
            self.stream.flush()
