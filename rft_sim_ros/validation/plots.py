"""PNG plots of the validation sweeps (matplotlib, Agg backend). Each function writes one
file and returns its name."""
import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402  (backend must be chosen first)
import numpy as np  # noqa: E402

from . import paper  # noqa: E402
from .experiments import RAIL_SHAPES  # noqa: E402

_SHAPE_COLOURS = {'flat': 'tab:blue', 'open_c': 'tab:orange', 'closed_c': 'tab:green'}
_SPEED_STYLES = ('-', '--', ':')


def _save(fig, out, name):
    fig.tight_layout()
    fig.savefig(out / name, dpi=100)
    plt.close(fig)
    return name


def _swept_deg(case):
    s = case.series
    return np.degrees(np.abs(s['angle_rad'] - s['angle_rad'][0]))


def rail_displacement_vs_angle(out, rails, speeds):
    """Carriage displacement against intruder rotation, per shape and speed."""
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for shape in RAIL_SHAPES:
        for speed, style in zip(speeds, _SPEED_STYLES):
            case = rails[shape, speed]
            s = case.series
            x = np.abs(s['carriage_x_m'] - s['carriage_x_m'][0])
            ax.plot(_swept_deg(case), 100 * x, style, color=_SHAPE_COLOURS[shape],
                    label=f'{shape}, {speed:g} rad/s')
    ax.set_xlabel('intruder rotation (deg)')
    ax.set_ylabel('carriage displacement (cm)')
    ax.set_title('Rail carriage driven by a rotating intruder')
    ax.legend(fontsize='small', ncol=3)
    return _save(fig, out, 'rail_displacement_vs_angle.png')


def rail_displacement_vs_speed(out, rails, speeds, rails_paper=None):
    """Final carriage displacement against rotation speed, per shape: exact coupling (solid)
    and, where given ({(shape, speed): Case}), the authors' loop (dashed)."""
    fig, ax = plt.subplots(figsize=(8, 4))
    for shape in RAIL_SHAPES:
        ax.plot(speeds, [100 * rails[shape, v].metrics['carriage_displacement_m'] for v in speeds],
                'o-', color=_SHAPE_COLOURS[shape], label=shape)
        if rails_paper:
            ax.plot(speeds, [100 * rails_paper[shape, v].metrics['carriage_displacement_m']
                             for v in speeds], 's--', color=_SHAPE_COLOURS[shape],
                    label=f"{shape}, the authors' loop")
    ax.set_xlabel('rotation speed (rad/s)')
    ax.set_ylabel('carriage displacement after 180 deg (cm)')
    low, high = ax.get_ylim()  # from zero (or below, where a carriage went backward)
    ax.set_ylim(min(0.0, low), 1.15 * high)  # with room above the top series
    ax.margins(x=0.08)
    ax.set_title('Rail carriage: progress after one 180 deg turn, per intruder')
    ax.legend(loc='upper left', bbox_to_anchor=(1.02, 1.0), fontsize='small')
    return _save(fig, out, 'rail_displacement_vs_speed.png')


def torque_vs_angle(out, torque):
    """Servo torque increase (sand minus air) against rotation, per speed."""
    fig, ax = plt.subplots(figsize=(8, 4))
    for (speed, case), style in zip(sorted(torque.items()), _SPEED_STYLES):
        s = case.series
        ax.plot(_swept_deg(case), s['servo_torque_Nm'] - s['air_torque_Nm'], style,
                label=f'{speed:g} rad/s')
    ax.axhline(paper.TORQUE_INCREASE_SIM_NM, color='0.5', linestyle='-.',
               label='RFT-SiM peak (+0.055 N m)')
    ax.set_xlabel('intruder rotation (deg)')
    ax.set_ylabel('servo torque increase in sand (N m)')
    ax.set_title('Rotating intruder: torque the sand adds (sand minus air)', fontsize=11)
    ax.legend(loc='upper left', bbox_to_anchor=(1.01, 1.0), fontsize='small')  # off the data
    return _save(fig, out, 'torque_vs_angle.png')


def hexapod_position_vs_time(out, hexapod, zeta):
    """Base position (x forward, z height) during the walk at `zeta`, per payload."""
    fig, (ax_x, ax_z) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    for (z, payload), case in sorted(hexapod.items()):
        if z != zeta or payload not in paper.PAYLOADS_KG:
            continue
        s = case.series
        t = s['time_s'] - s['time_s'][0]
        ax_x.plot(t, 100 * (s['x_m'] - s['x_m'][0]), label=f'payload {payload:g} kg')
        ax_z.plot(t, 100 * s['z_m'], label=f'payload {payload:g} kg')
    ax_x.set_ylabel('forward position (cm)')
    ax_z.set_ylabel('base_link height (cm)')
    ax_z.set_xlabel('time since the gait started (s)')
    ax_x.set_title(f'Hexapod, alternating tripod at 1 cycle/s, zeta = {zeta:g} N/cm$^3$')
    ax_x.legend(fontsize='small')
    return _save(fig, out, 'hexapod_position_vs_time.png')


def hexapod_sinkage_vs_zeta(out, hexapod, zetas, payloads):
    """Mean stance sinkage against zeta, per payload."""
    fig, ax = plt.subplots(figsize=(6, 4))
    for payload in payloads:
        ax.plot(zetas, [100 * hexapod[z, payload].metrics['mean_sinkage_m'] for z in zetas],
                'o-', label=f'payload {payload:g} kg')
    ax.axvspan(*paper.SINKAGE_MATCH_ZETA, color='0.85',
               label='zeta matching measured sinkage (paper)')
    ax.axvline(3.75, color='0.5', linestyle=':', label='calibrated zeta 3.75')
    ax.set_xlabel('zeta (N/cm$^3$)')
    ax.set_ylabel('mean stance sinkage of the foot tips (cm)')
    ax.legend(fontsize='small')
    return _save(fig, out, 'hexapod_sinkage_vs_zeta.png')


def hexapod_speed_vs_payload(out, hexapod, zetas, payloads, hexapod_paper=None):
    """Mean walking speed against payload, per zeta: exact coupling (solid) and, where given
    ({(zeta, payload): Case}), the authors' loop (dashed, same colour)."""
    fig, ax = plt.subplots(figsize=(9, 4))
    for zeta in zetas:
        line, = ax.plot(payloads, [100 * hexapod[zeta, p].metrics['mean_speed_mps']
                                   for p in payloads], 'o-', label=f'zeta {zeta:g} N/cm$^3$')
        if hexapod_paper:
            ax.plot(payloads, [100 * hexapod_paper[zeta, p].metrics['mean_speed_mps']
                               for p in payloads], 's--', color=line.get_color(),
                    label=f"zeta {zeta:g}, the authors' loop")
    ax.plot([0.0], [100 * paper.HEXAPOD_SPEED_EXPERIMENT_MPS], 'k*', markersize=10,
            label='experiment, no payload: derived, not printed\n'
                  '(paper: its low-friction model within 1.2 mm/s = 1.85 %)')
    low, high = ax.get_ylim()  # from zero (or below, where a robot walked backward):
    ax.set_ylim(min(0.0, low), 1.2 * high)  # a 3 % trend looks like 3 %
    ax.set_xlabel('payload (kg)')
    ax.set_ylabel('mean speed over 5 cycles (cm/s)')
    ax.set_title('Hexapod: walking speed against payload')
    ax.legend(loc='upper left', bbox_to_anchor=(1.02, 1.0), fontsize='small')
    return _save(fig, out, 'hexapod_speed_vs_payload.png')


def articulated_leg(out, legs):
    """Carriage position against time at zeta 3.75, and travel per step against zeta."""
    fig, (ax_t, ax_z) = plt.subplots(1, 2, figsize=(10, 4))
    reference = legs.get(3.75) or legs[max(legs)]
    s = reference.series
    ax_t.plot(s['time_s'], 100 * (s['carriage_x_m'] - s['carriage_x_m'][0]))
    ax_t.set_xlabel('time (s)')
    ax_t.set_ylabel('carriage position (cm)')
    ax_t.set_title('Articulated leg, zeta 3.75, 3 steps')
    zetas = sorted(legs)
    ax_z.plot(zetas, [100 * legs[z].metrics['carriage_displacement_per_step_m'] for z in zetas],
              'o-', label='ours')
    ax_z.axhline(100 * paper.LEG_STEP_SIM_M, color='tab:orange', linestyle='--',
                 label='RFT-SiM simulation (zeta 3.75)')
    ax_z.axhline(100 * paper.LEG_STEP_EXPERIMENT_M, color='k', linestyle=':',
                 label='experiment')
    ax_z.set_xlabel('zeta (N/cm$^3$)')
    ax_z.set_ylabel('carriage travel per step (cm)')
    ax_z.legend(fontsize='small')
    return _save(fig, out, 'articulated_leg.png')
