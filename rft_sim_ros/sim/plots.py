"""Plots of a headless run's time series (PNG, matplotlib's Agg backend, no display)."""
import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402  (backend must be chosen first)


def plot_timeseries(path, series, scene):
    """Base position, ground forces per leg and plates in the sand against sim time."""
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
    fig.suptitle(f'{scene.name}: zeta = {scene.zeta:g} N/cm$^3$, dt = {scene.timestep * 1e3:g} ms')
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
