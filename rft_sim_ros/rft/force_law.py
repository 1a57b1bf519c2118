"""3D granular Resistive Force Theory on plates: the numpy reference implementation.

Treers et al. 2021 3D RFT over the Li et al. 2013 generic coefficients with the
leading-edge hypothesis and zeta scaling. This module is the readable reference that the
tests check against analytic values; the engine uses the compiled `kernel` module, which a
property test holds to this one.

Frames and units: every array is in one common frame whose z axis points up against gravity
(the world frame; horizontal sand surface at z = surface_height). SI units in and out:
positions m, normals unitless (outward, unit length), areas m^2, velocities m/s, forces N
acting ON the body. zeta is in N/cm^3 (the paper's unit) and converted once via
`rft_sim_ros.units`.

Per plate j with depth z = surface_height - p_z > 0 and leading (n . v > TANGENTIAL |v|):
    e2 = horizontal projection of n, normalised (of v when the plate is nearly horizontal;
         the other one where that vanishes),
    e1 = e2 x E3, v1 = (v.e1) e1, v23 = v - v1  (v the unit velocity),
    beta = atan2(n_z, n.e2) + pi/2,  gamma = -atan2(v23_z, v23.e2),
    F = zeta z A ( -f1(|v1|) alpha_Y sign(v.e1) e1 - f23(|v23|) alpha_x e2
                   + f23(|v23|) alpha_z E3 ).
Optional dynamic term (after Agarwal et al. 2021): a stress lambda rho (v.n)^2 on leading
plates, along -n, added for fast intrusion (> ~0.2 m/s); off by default.
"""
from dataclasses import dataclass

import numpy as np

from ..units import validated_zeta, zeta_to_si
from . import coefficients as co

#: A plate whose outward normal has |n_z| at least this is treated as horizontal (Treers).
HORIZONTAL_NZ = 1.0 - 1e-3

#: The leading rule, one for this reference, the compiled law and the engine: a plate leads
#: only if n . v exceeds TANGENTIAL x a speed scale (here and in the compiled law the plate's
#: speed |v|; in the engine its body's origin speed + radius x angular speed, which bounds
#: every plate's). A plate sliding in its own plane (n . v = 0 up to rounding, e.g. the end
#: faces of a blade turning about its long axis) then stays trailing, instead of flipping to
#: a full RFT force on the rounding's sign.
TANGENTIAL = 1e-12

#: Normals whose length differs from 1 by more than this are refused: a plate's normal is a
#: direction, and the flat-plate switch and the cos 2 beta form assume unit length.
NORMAL_LENGTH_TOLERANCE = 1e-6


@dataclass(frozen=True)
class DynamicTerm:
    """Inertial (dynamic RFT) stress lambda * rho * (v . n)^2 on leading plates in the sand.

    lam: dimensionless shape factor; density: bulk density of the medium, kg/m^3.
    """
    lam: float = 1.0
    density: float = 1600.0


def plate_forces(positions, normals, areas, velocities, zeta, surface_height=0.0,
                 normalisation='treers', dynamic=None):
    """RFT force on each plate, in newtons, acting on the body.

    positions: (N, 3) plate centroids, m. normals: (N, 3) outward unit normals.
    areas: (N,) m^2. velocities: (N, 3) plate velocities, m/s. zeta: N/cm^3.
    surface_height: z of the horizontal sand surface, m (depth is measured from it), or the
    surface's z above each plate, (N,) m.
    normalisation: 'treers' (f1(1) = f23(1) = 1) or 'rft_sim' (the RFT-SiM code's values).
    dynamic: a DynamicTerm to add the rate-dependent stress, or None (rate independent).
    Returns (N, 3) forces, N. Plates above the surface, trailing or sliding in their own
    plane (n . v <= TANGENTIAL |v|) feel zero. Raises ValueError for normals that are not
    unit vectors (within NORMAL_LENGTH_TOLERANCE), values that are not finite, negative
    areas, and arrays of different plate counts.
    """
    positions = _finite('positions', positions).reshape(-1, 3)
    normals = unit_normals(normals)
    velocities = _finite('velocities', velocities).reshape(-1, 3)
    areas = _finite('areas', areas).reshape(-1)
    if not len(positions) == len(normals) == len(velocities) == len(areas):
        raise ValueError(f'one position, normal, velocity and area per plate: got '
                         f'{len(positions)}, {len(normals)}, {len(velocities)} and '
                         f'{len(areas)}')
    if np.any(areas < 0.0):
        raise ValueError(f'areas must be >= 0 m^2: area {int(np.argmax(areas < 0.0))} is '
                         f'{areas[np.argmax(areas < 0.0)]:g}')
    if not np.all(np.isfinite(surface_height)):
        raise ValueError(f'surface_height must be finite (m), got {surface_height!r}')
    norm = co.normalisation(normalisation)
    zeta_si = zeta_to_si(validated_zeta(zeta))

    forces = np.zeros_like(positions)
    depth = surface_height - positions[:, 2]
    speed = np.linalg.norm(velocities, axis=1)
    active = ((depth > 0.0) & (np.einsum('ij,ij->i', normals, velocities) > TANGENTIAL * speed)
              & (speed > 0.0))
    if not np.any(active):
        return forces
    n = normals[active]
    v = velocities[active] / speed[active, None]

    e2 = _e2_directions(n, v)
    e1 = np.cross(e2, np.array([0.0, 0.0, 1.0]))
    v_e1 = np.einsum('ij,ij->i', v, e1)
    v23 = v - v_e1[:, None] * e1
    vt = np.minimum(np.abs(v_e1), 1.0)
    vn = np.minimum(np.linalg.norm(v23, axis=1), 1.0)

    beta = np.arctan2(n[:, 2], np.einsum('ij,ij->i', n, e2)) + np.pi / 2
    gamma = -np.arctan2(v23[:, 2], np.einsum('ij,ij->i', v23, e2))
    f1 = co.f1(vt, norm)
    f23 = co.f23(vn, norm)
    unit_stress = (-(f1 * co.ALPHA_Y * np.sign(v_e1))[:, None] * e1
                   - (f23 * co.alpha_x(beta, gamma))[:, None] * e2)
    unit_stress[:, 2] += f23 * co.alpha_z(beta, gamma)
    scale = zeta_si * depth[active] * areas[active]
    forces[active] = scale[:, None] * unit_stress
    if dynamic is not None:
        vn_speed = np.einsum('ij,ij->i', velocities[active], n)
        stress = dynamic.lam * dynamic.density * vn_speed ** 2
        forces[active] -= (stress * areas[active])[:, None] * n
    return forces


def _finite(name, values):
    """`values` as a float array, checked to hold only finite numbers (ValueError naming the
    first that is not: a NaN position would silently feel no force)."""
    values = np.asarray(values, dtype=float)
    bad = ~np.isfinite(values)
    if np.any(bad):
        index = tuple(int(i) for i in np.unravel_index(int(np.argmax(bad)), values.shape))
        raise ValueError(f'{name} must be finite: {name}{list(index)} is '
                         f'{float(values[index])}')
    return values


def unit_normals(normals):
    """`normals` as an (N, 3) float array, checked to be unit vectors (ValueError naming the
    first that is not: RFT's angles are those of a direction, so a scaled normal would give
    another force, not a scaled one)."""
    normals = np.asarray(normals, dtype=float).reshape(-1, 3)
    error = np.abs(np.linalg.norm(normals, axis=1) - 1.0)
    bad = ~(error <= NORMAL_LENGTH_TOLERANCE)  # NaN included
    if np.any(bad):
        j = int(np.argmax(bad))
        raise ValueError(f'normals must be unit vectors: normal {j} {normals[j].tolist()} has '
                         f'length {np.linalg.norm(normals[j]):.9g}')
    return normals


def _e2_directions(n, v):
    """Unit horizontal direction e2 per plate: the horizontal part of the normal or, for a
    nearly horizontal plate, of the velocity (Treers). Where that vanishes the other one is
    used, and +x only when both vanish (a horizontal plate moving vertically, where the
    force does not depend on e2); so the law turns with the scene about the vertical."""
    horizontal_n = n.copy()
    horizontal_n[:, 2] = 0.0
    horizontal_v = v.copy()
    horizontal_v[:, 2] = 0.0
    flat = np.abs(n[:, 2]) >= HORIZONTAL_NZ
    first = np.where(flat[:, None], horizontal_v, horizontal_n)
    second = np.where(flat[:, None], horizontal_n, horizontal_v)
    length = np.linalg.norm(first, axis=1)
    use_second = length < 1e-12
    first[use_second] = second[use_second]
    length[use_second] = np.linalg.norm(second[use_second], axis=1)
    undefined = length < 1e-12
    first[undefined] = (1.0, 0.0, 0.0)
    length[undefined] = 1.0
    return first / length[:, None]
