"""What a Ctrl-C leaves behind when it ends a command (`rft-sim`, the ROS executables)."""
import gc
import sys
import traceback


def release_quietly(interrupt):
    """Free what the exception `interrupt` (a KeyboardInterrupt, or a shutdown a signal
    caused) holds, its traceback's frames, at once, with the errors of the destructors this
    runs ignored. A signal can land between two lines of a constructor (llvmlite's, inside a
    numba compile), and that object's destructor then fails on the attribute it never got: a
    traceback of no use to a user who asked to stop. Other errors are not affected: the hook
    is restored before returning."""
    hook = sys.unraisablehook
    sys.unraisablehook = lambda unraisable: None
    try:
        traceback.clear_frames(interrupt.__traceback__)
        interrupt.__traceback__ = None
        gc.collect()  # (frames in reference cycles)
    finally:
        sys.unraisablehook = hook
