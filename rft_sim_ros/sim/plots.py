"""Plots of a headless run's time series (PNG, matplotlib's Agg backend, no display)."""
import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402  (backend must be chosen first)


def plot_timeseries(path, series, scene, schedule=()):
    """Base position, ground forces per leg and plates in the sand against sim time;
    `schedule`: the summary's applied changes ({'time_s', key: value}), marked on every panel
    and named in the title."""
    time = [row['time_s'] for row in series]
    leg_columns = [c for c in series[0] if c.endswith('_force_z_N')]
    fig, axes = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    for column, label in (('base_x_m', 'x'), ('base_y_m', 'y'), ('base_z_m', 'z')):
        axes[0].plot(time, [row[column] for row in series], label=label)
    axes[0].axhline(scene.surface_height, color='0.6', linestyle=':', label='sand surface')
    axes[0].set_ylabel('base position (m)')
    axes[0].legend(loc='best', fontsize='small')
    for column in leg_columns:
        axes[1].plot(time, [row[column] for row in series], label=column[:-len('_force_z_N')])
    axes[1].set_ylabel('vertical sand force (N)')
    if leg_columns:
        axes[1].legend(loc='best', fontsize='small', ncol=3)
    axes[2].plot(time, [row['plates_active'] for row in series])
    axes[2].set_ylabel('plates in sand (leading)')
    axes[2].set_xlabel('sim time (s)')
    changes = [change for change in schedule if change.get('applied')]
    for change in changes:
        for axis in axes:
            axis.axvline(change['time_s'], color='0.3', linestyle='--', linewidth=0.8)
    zeta = f'zeta = {scene.zeta:g} N/cm$^3$' + ''.join(
        f', {value:g} from {change["time_s"]:g} s' for change in changes
        for key, value in change.items() if key == 'zeta')
    fig.suptitle(f'{scene.name}: {zeta}, dt = {scene.timestep * 1e3:g} ms')
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
