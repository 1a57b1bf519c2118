"""The compiled kernels of the built-in gaits (numba, cached): the foot path of a gait cycle
(`foot_path`), the lateral legs' inverse kinematics (`leg_inverse`, `leg_kinematics`), and
the targets of the hexapod's tripod (`tripod_targets`, `gaits`) and the quadruped's trot
(`trot_targets`, `quadruped`) at a time. A module of their own, which the gaits do not
import: they call them by name through `prebuilt.kernel` (`kernel_names.FOOT_PATH` ...), so
that a run whose kernels are prebuilt does not import numba. SI units (m, rad), base_link
frame."""
import numpy as np
from numba import njit

from ..kernel_cache import forget_stale


@njit(cache=True)
def foot_path(phi, beta, length, height):
    """Foot offsets (ds, dz), m, along the walking direction and up, at phases phi (1-D, in
    [0, 1)) of a gait cycle with stance fraction beta, stroke `length` and lift `height`: in
    stance the foot moves back at constant speed from +length/2 to -length/2; in swing it
    returns on a cubic Hermite curve whose end slopes match the stance speed, lifted by
    height sin^2(pi s)."""
    ds = np.empty(phi.shape[0])
    dz = np.empty(phi.shape[0])
    slope = -length * (1.0 - beta) / beta  # stance velocity, per unit swing fraction
    for i in range(phi.shape[0]):
        if phi[i] < beta:
            ds[i] = length * (0.5 - phi[i] / beta)
            dz[i] = 0.0
        else:
            s = (phi[i] - beta) / (1.0 - beta)
            # cubic Hermite from -length/2 to +length/2 with end slopes `slope`
            ds[i] = (length * (s * s * (3.0 - 2.0 * s) - 0.5)
                     + slope * s * (1.0 - s) * (1.0 - 2.0 * s))
            dz[i] = height * np.sin(np.pi * s) ** 2
    return ds, dz


@njit(cache=True)
def tripod_targets(cycles, offsets, scale, beta, length, height, neutral, knee_xyz, side,
                    mid_length, dactyl_length, dactyl_droop):
    """The tripod gait's (`gaits.TripodGait`) knee and ankle targets (rad), interleaved per
    leg, `cycles` gait cycles after the start for legs at phase `offsets` (cycles) with
    stroke and lift times `scale`: the foot path, then the legs' inverse kinematics."""
    phases = np.empty(offsets.shape[0])
    for i in range(offsets.shape[0]):
        phases[i] = (cycles + offsets[i]) % 1.0  # in [0, 1), as np.mod
    ds, dz = foot_path(phases, beta, scale * length, scale * height)
    feet_y = np.empty((1, ds.shape[0]))
    feet_z = np.empty((1, ds.shape[0]))
    for i in range(ds.shape[0]):
        feet_y[0, i] = neutral[i, 1] + ds[i]
        feet_z[0, i] = neutral[i, 2] + dz[i]
    knee, ankle = leg_inverse(feet_y, feet_z, knee_xyz, side, mid_length, dactyl_length,
                              dactyl_droop)
    out = np.empty(2 * ds.shape[0])
    for i in range(ds.shape[0]):
        out[2 * i], out[2 * i + 1] = knee[0, i], ankle[0, i]
    return out


@njit(cache=True)
def leg_inverse(foot_y, foot_z, knee_xyz, side, mid_length, dactyl_length, dactyl_droop):
    """`leg_kinematics.LateralLegs.inverse` for (M, N) foot targets (m; N legs): knee and
    ankle angles (rad). Targets out of reach are clipped to the edge of the workspace."""
    knee = np.empty(foot_y.shape)
    ankle = np.empty(foot_y.shape)
    for m in range(foot_y.shape[0]):
        for i in range(foot_y.shape[1]):
            out = side[i] * (foot_y[m, i] - knee_xyz[i, 1])  # outward from the knee axis
            up = foot_z[m, i] - knee_xyz[i, 2]
            cos_bend = ((out * out + up * up - mid_length ** 2 - dactyl_length ** 2)
                        / (2.0 * mid_length * dactyl_length))
            bend = -np.arccos(min(max(cos_bend, -1.0), 1.0))  # dactyl below the mid line
            knee[m, i] = np.arctan2(up, out) - np.arctan2(
                dactyl_length * np.sin(bend), mid_length + dactyl_length * np.cos(bend))
            ankle[m, i] = bend + dactyl_droop
    return knee, ankle


@njit(cache=True)
def trot_targets(cycles, offsets, scale, beta, length, height, neutral_x, neutral_z, l1, l2):
    """The trot's (`quadruped.TrotGait`) joint targets (rad, per leg abduction 0, hip
    pitch, knee) `cycles` trot cycles after the start, for legs at phase `offsets` with
    stroke and lift times `scale`: the foot path, then the legs' inverse kinematics
    (`quadruped.leg_inverse`; the path is checked to be reachable beforehand)."""
    phases = np.empty(offsets.shape[0])
    for i in range(offsets.shape[0]):
        phases[i] = (cycles + offsets[i]) % 1.0
    dx, dz = foot_path(phases, beta, scale * length, scale * height)
    out = np.zeros(3 * offsets.shape[0])
    for i in range(offsets.shape[0]):
        x, z = neutral_x + dx[i], neutral_z + dz[i]
        knee = -np.arccos(min(max((x * x + z * z - l1 * l1 - l2 * l2) / (2 * l1 * l2), -1.0),
                              1.0))
        out[3 * i + 1] = np.arctan2(-x, -z) + np.arctan2(l2 * np.sin(-knee),
                                                          l1 + l2 * np.cos(knee))
        out[3 * i + 2] = knee
    return out


forget_stale(globals())  # (kernel_cache: drops kernels compiled from older sources)
