"""Sim time <-> ROS time (builtin_interfaces/Time and Duration, rosbag2 timestamps).

Sim time is a float in seconds. ROS carries time as integer seconds plus integer nanoseconds
(0 <= nanosec < 1e9) and rosbag2 as integer nanoseconds. The conversion rounds the exact
binary value of the float to the nearest nanosecond (halves away from zero), so it never
depends on the float error of `t * 1e9`.
"""
import math

NS_PER_S = 1_000_000_000


def seconds_to_ns(t):
    """Nearest integer nanoseconds to `t` seconds; raises ValueError if `t` is not finite."""
    t = float(t)
    if not math.isfinite(t):
        raise ValueError(f'time must be finite, got {t} s')
    # |t| = num / den exactly (den a power of two): floor(|t| 1e9 + 1/2) in integers
    num, den = abs(t).as_integer_ratio()
    ns = (2 * num * NS_PER_S + den) // (2 * den)
    return ns if t >= 0 else -ns


def split_ns(ns):
    """(sec, nanosec) of `ns` nanoseconds, with 0 <= nanosec < 1e9 (also for negative ns)."""
    return divmod(int(ns), NS_PER_S)


def ros_time_to_seconds(msg):
    """Seconds (float) of a builtin_interfaces/Time or Duration message (any backend)."""
    return msg.sec + msg.nanosec * 1e-9
