"""`rft-sim` and `python -m rft_sim_ros`: the CLI behind a guard for Ctrl-C during start-up.

Importing the CLI loads numpy, MuJoCo and the scene code (about half a second, longer on a
cold machine). A KeyboardInterrupt raised inside those imports can end in a traceback, or be
swallowed by a library's catch-all and lost. So while they load, this module (standard
library only) only notes a Ctrl-C; once they are loaded, a noted Ctrl-C ends the command the
way the CLI ends any interrupt: one line, exit status 130 (128 + SIGINT), nothing run. A
SIGINT the caller ignores (a background job) stays ignored.

Before those imports the native thread pools (BLAS, OpenMP) are set to one thread, unless
the environment says otherwise (`native_threads`).
"""
import os
import signal
import sys
import time

from .native_threads import unset


def main(argv=None):
    """Load the CLI with Ctrl-C deferred, then run `rft_sim_ros.cli.main(argv)`, telling it
    when the command began (before these imports: a run's time "in all")."""
    started = time.perf_counter()
    os.environ.update(unset())
    noted = []
    previous = signal.getsignal(signal.SIGINT)
    if previous is not signal.SIG_IGN:
        signal.signal(signal.SIGINT, lambda signum, frame: noted.append(signum))
    from .cli import main as cli_main
    signal.signal(signal.SIGINT, previous)
    if noted:
        print('\nrft-sim: interrupted', file=sys.stderr)
        return 128 + signal.SIGINT
    return cli_main(argv, started)


if __name__ == '__main__':
    sys.exit(main())
