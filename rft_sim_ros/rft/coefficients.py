"""Empirical coefficients of granular RFT: Li et al. 2013 (2D) and Treers et al. 2021 (3D).

Angles (radians), as in Li 2013 and Treers 2021:
  beta  - attack angle of the plate: 0 for a horizontal plate whose outward normal points
          down, pi/2 for a vertical plate;
  gamma - intrusion angle of the velocity in the (e2, E3) plane: +pi/2 straight down,
          -pi/2 straight up, 0 horizontal along e2.

alpha_x, alpha_z are stresses per unit depth for zeta = 1 (dimensionless here; multiply by
zeta in N/cm^3). The generic coefficients sum to 1, so a horizontal plate pushed straight
down feels alpha_z = 1: zeta is the vertical stress per unit depth.
"""
from dataclasses import dataclass

import numpy as np

#: Li et al. 2013 (Science 339:1408) generic coefficients.
A00 = 0.206
A10 = 0.169
B11 = 0.212
B01 = 0.358
BM11 = 0.055
C11 = -0.124
C01 = 0.253
CM11 = 0.007
D10 = 0.088

#: Treers 2021 "simplest form": alpha_Y = alpha_x(beta=0, gamma=0) = C11 + C01 + C-11.
ALPHA_Y = C11 + C01 + CM11


def alpha_z(beta, gamma):
    """Vertical RFT coefficient alpha_z(beta, gamma) for zeta = 1 (Li 2013 Fourier fit)."""
    return (A00 + A10 * np.cos(2 * beta) + B11 * np.sin(2 * beta + gamma)
            + B01 * np.sin(gamma) + BM11 * np.sin(-2 * beta + gamma))


def alpha_x(beta, gamma):
    """Horizontal RFT coefficient alpha_x(beta, gamma) for zeta = 1 (Li 2013 Fourier fit).

    Positive alpha_x resists motion along +e2 (the force is -alpha_x e2).
    """
    return (C11 * np.cos(2 * beta + gamma) + C01 * np.cos(gamma)
            + CM11 * np.cos(-2 * beta + gamma) + D10 * np.sin(2 * beta))


# Treers 2021 fits of the velocity-decomposition scaling factors f1(vt), f23(vn).
_F1_A1, _F1_A2, _F1_A3 = 0.440850096954369, 3.62263982880971, 1.60910808139526
_F23_B1, _F23_B2, _F23_B3 = 1.99392673405210, 1.61146827229181, 0.973746396532650


@dataclass(frozen=True)
class Normalisation:
    """Normalisers a4, b4 of the Treers scaling factors f1 and f23.

    `treers` (default): f1(1) = f23(1) = 1, so zeta keeps its calibrated meaning.
    `rft_sim`: the RFT-SiM code's values (f1(1) = 2.03, f23(1) = 1.348), whose vertical
    stress on a horizontal plate is 1.35 zeta; kept to reproduce that code.
    """
    name: str
    a4: float
    b4: float


NORMALISATIONS = {
    'treers': Normalisation('treers', a4=0.832324700111401, b4=5.81083560370960),
    'rft_sim': Normalisation('rft_sim', a4=0.41, b4=4.31),
}


def normalisation(name):
    """The Normalisation called `name` ('treers' or 'rft_sim'); ValueError otherwise."""
    try:
        return NORMALISATIONS[name]
    except KeyError:
        raise ValueError(f'unknown RFT normalisation {name!r}; '
                         f'choose one of {sorted(NORMALISATIONS)}') from None


def f1(vt, norm):
    """Scaling of the lateral (e1) force with the tangential speed fraction vt in [0, 1]."""
    return _F1_A1 * (np.tanh(_F1_A2 * vt - _F1_A3) + np.tanh(_F1_A3)) / norm.a4


def f23(vn, norm):
    """Scaling of the (e2, E3) force with the in-plane speed fraction vn in [0, 1]."""
    return _F23_B1 * (np.arctanh(_F23_B2 * vn - _F23_B3) + np.arctanh(_F23_B3)) / norm.b4
