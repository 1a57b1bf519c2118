"""The explicit low-velocity treatments, compiled: the RFT force as gathered ('none'), or
smoothed per plate by the paper's exponential moving average ('ema'), summed into each
slot's wrench (`smoothed_wrenches`); `mujoco_terms.scatter_wrenches` then applies them.

Conventions: plates are columns of the gathered table and force (`gather`, `layout`);
forces N, world axes, on the body; wrenches [force; torque about the body's centre of
mass], N and N m.
"""
from numba import njit

from ..kernel_cache import forget_stale
from .layout import LEVER


@njit(cache=True, error_model='numpy')
def smoothed_wrenches(k, slots, out_plate, out_slot, table, force, alpha, step,
                      ema_force, ema_step, applied, wrench):
    """Explicit RFT with the paper's per-plate exponential moving average (RFT-SiM eq. 6):
    F_s = alpha F + (1 - alpha) F_s(previous step) for a plate that was in the sand on the
    previous step, F_s = F otherwise (its history is dropped when it leaves the sand).
    alpha = 1 applies the raw RFT force. Plates: columns :k of the gathered table and force
    (`gather._gather_plates`). Writes applied[:, :k] = F_s (N, world, on the body).
    ema_force (N, 3), ema_step (N,) hold each plate's last smoothed force and the step index
    it was computed at. Writes wrench[:S] as in `implicit_solve._implicit_step`.
    """
    wrench[:slots, :] = 0.0
    for j in range(k):
        p = out_plate[j]
        for a in range(3):
            applied[a, j] = force[a, j]
            if ema_step[p] == step - 1:
                applied[a, j] = alpha * force[a, j] + (1.0 - alpha) * ema_force[p, a]
            ema_force[p, a] = applied[a, j]
        ema_step[p] = step
        fx, fy, fz = applied[0, j], applied[1, j], applied[2, j]
        rx, ry, rz = table[LEVER, j], table[LEVER + 1, j], table[LEVER + 2, j]
        s = out_slot[j]
        wrench[s, 0] += fx
        wrench[s, 1] += fy
        wrench[s, 2] += fz
        wrench[s, 3] += ry * fz - rz * fy
        wrench[s, 4] += rz * fx - rx * fz
        wrench[s, 5] += rx * fy - ry * fx


forget_stale(globals())  # (kernel_cache: drops kernels compiled from older sources)
