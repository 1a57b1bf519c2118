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


def plot_surface(path, surface, window=None):
    """Map of a height grid's change from its pristine surface (deformable sand: footprints
    below, piles above), mm, seen from above; `window` (x0, x1, y0, y1) m crops it."""
    change = 1000.0 * (surface.grid - surface.pristine)
    ny, nx = change.shape
    extent = (surface.origin[0], surface.origin[0] + surface.spacing[0] * (nx - 1),
              surface.origin[1], surface.origin[1] + surface.spacing[1] * (ny - 1))
    limit = max(float(abs(change).max()), 1e-3)
    fig, ax = plt.subplots(figsize=(7, 5))
    image = ax.imshow(change, origin='lower', extent=extent, cmap='RdBu_r', vmin=-limit,
                      vmax=limit)
    fig.colorbar(image, ax=ax, label='surface change (mm): footprints < 0 < piles')
    if window is not None:
        ax.set_xlim(window[0], window[1])
        ax.set_ylim(window[2], window[3])
    ax.set_xlabel('x (m)')
    ax.set_ylabel('y (m)')
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
