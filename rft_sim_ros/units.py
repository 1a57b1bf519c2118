"""Unit conventions shared by the whole package.

Everything in code and messages is SI (ROS REP 103) except the sand stiffness zeta, which
keeps the unit of the RFT literature, N/cm^3, at every interface (scene YAML, CLI, ROS
parameter, summary.json). It is converted to SI here and nowhere else.
"""
import math
import numbers

#: 1 N/cm^3 expressed in N/m^3.
N_PER_CM3_IN_SI = 1.0e6

#: Largest zeta accepted (N/cm^3). Published media span 0.1 (very loose) to ~6 (packed sand).
ZETA_MAX_N_PER_CM3 = 100.0


def zeta_to_si(zeta_n_per_cm3):
    """Convert zeta from N/cm^3 (the paper's unit) to N/m^3."""
    return zeta_n_per_cm3 * N_PER_CM3_IN_SI


def zeta_problem(zeta_n_per_cm3):
    """Return why `zeta_n_per_cm3` is not an acceptable zeta, or None if it is.

    zeta must be a finite real number with 0 < zeta <= ZETA_MAX_N_PER_CM3 (N/cm^3).
    """
    if isinstance(zeta_n_per_cm3, bool) or not isinstance(zeta_n_per_cm3, numbers.Real):
        return f'zeta must be a number in N/cm^3, got {zeta_n_per_cm3!r}'
    value = float(zeta_n_per_cm3)
    if not math.isfinite(value):
        return f'zeta must be finite, got {value}'
    if value <= 0.0:
        return f'zeta must be > 0 N/cm^3, got {value}'
    if value > ZETA_MAX_N_PER_CM3:
        return f'zeta must be <= {ZETA_MAX_N_PER_CM3:g} N/cm^3, got {value}'
    return None


def validated_zeta(zeta_n_per_cm3):
    """Return zeta as a float in N/cm^3, or raise ValueError saying what is wrong with it."""
    problem = zeta_problem(zeta_n_per_cm3)
    if problem:
        raise ValueError(problem)
    return float(zeta_n_per_cm3)
