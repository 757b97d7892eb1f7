"""
Electromagnetic losses of the motor: copper (with its AC resistance) and stator iron.

The rotor's eddy-current losses (magnets, sleeve, solid core) and the PWM
ripple current are in :mod:`.rotor_losses`; oil friction lives in
:mod:`.correlations`. The laws of the per-step kernel are compiled
(:func:`~.compiled.jit`): the motor's losses kernel calls them; they take
floats or arrays.
"""

from typing import Optional

import numpy as np

from .compiled import jit
from .validity import check, ValidityLog
from ..units import C_TO_K

T_REF_COPPER_K = C_TO_K + 20.0  # reference of the phase resistance


@jit
def copper_resistance(r_20C_ohm, tempco_1_K, T_K):
    """
    Return a copper resistance (ohm) at ``T_K``: R_20 [1 + a (T - 20 degC)].

    Linear law, accurate to about 1 % from -50 to 200 degC for annealed copper
    (a = 0.00393 1/K).

    >>> round(float(copper_resistance(0.060, 0.00393, 373.15)), 5)
    0.07886
    """
    return r_20C_ohm * (1.0 + tempco_1_K * (T_K - T_REF_COPPER_K))


@jit
def electrical_frequency(speed_rad_s, pole_pairs: int):
    """
    Return the electrical frequency (Hz) of a machine at mechanical speed ``speed_rad_s``.

    >>> round(float(electrical_frequency(2 * np.pi * 10000 / 60, 4)), 2)    # 10 000 r/min
    666.67
    """
    return pole_pairs * np.abs(speed_rad_s) / (2.0 * np.pi)


@jit
def steinmetz_loss_density(frequency_Hz, flux_density_T, hysteresis_coeff: float,
                           exponent: float, eddy_coeff: float):
    """
    Return iron loss per kg (W/kg): k_h f B^alpha + k_e f^2 B^2 (Steinmetz split).

    Coefficients are per kg and fitted on the lamination's loss curves; the
    split holds for sinusoidal flux without DC bias in the fitted range of f
    and B (the caller's data sheet states it).

    >>> round(float(steinmetz_loss_density(400.0, 1.5, 0.012, 2.0, 1.0e-5)), 2)
    14.4
    """
    return (hysteresis_coeff * frequency_Hz * flux_density_T ** exponent
            + eddy_coeff * frequency_Hz ** 2 * flux_density_T ** 2)


#: Resistivity of annealed copper at 20 degC (IEC 60028), ohm m.
COPPER_RESISTIVITY_20C_OHM_M = 1.7241e-8


def layer_porosity(copper_fill: float) -> float:
    """
    Return Dowell's layer porosity of round wires, sqrt(copper fill).

    Round wire of diameter d in a square array of pitch s fills the slot to
    k = pi d^2 / (4 s^2); its equal-area square conductor of side
    h = d sqrt(pi) / 2 fills the layer's breadth to eta = h / s = sqrt(k)
    (square packing assumed; P. L. Dowell, "Effects of eddy currents in
    transformer windings", Proc. IEE 113(8), 1966, 1387-1394, treats such a
    layer as a foil of conductivity eta sigma).

    >>> round(layer_porosity(0.6), 4)
    0.7746
    """
    return float(np.sqrt(copper_fill))


def copper_ac_factor(frequency_Hz, diameter_m: float, layers: int, porosity: float,
                     resistivity_ohm_m: float = COPPER_RESISTIVITY_20C_OHM_M,
                     log: Optional[ValidityLog] = None):
    """
    Return R_ac / R_dc of a winding portion of ``layers`` layers of round wire (Dowell).

    F_R = Delta [zeta_1 + (2/3)(p^2 - 1) zeta_2], p the layers between the
    points of zero MMF (in a tooth-coil slot: the layers of one slot side, the
    field growing from the slot bottom), zeta_1 = (sinh 2D + sin 2D) /
    (cosh 2D - cos 2D) (skin), zeta_2 = (sinh D - sin D) / (cosh D + cos D)
    (proximity), Delta = sqrt(eta) h / delta with h = d sqrt(pi) / 2 the side of
    the equal-area square conductor, eta the porosity (:func:`layer_porosity`)
    and delta = sqrt(rho / (pi f mu0)) the skin depth (Dowell 1966, with his
    porosity factor). Below Delta = 0.01 the series
    1 + (5 p^2 - 1) Delta^4 / 45 is used (the same function). One-dimensional
    field across the layers that fill the slot's breadth; for round wire an
    approximation whose error grows past d / delta of about 2 (Dowell's
    equivalence is exact for foils only); flagged past d / delta = 3.
    ``frequency_Hz`` may be an array.

    >>> round(float(copper_ac_factor(20e3, 0.8e-3, 2, layer_porosity(0.6))), 3)
    2.191
    >>> # 1333 Hz: Delta = 0.3447, the series 1 + 19 Delta^4 / 45
    >>> round(float(copper_ac_factor(1333.0, 0.8e-3, 2, layer_porosity(0.6))), 4)
    1.006
    """
    f = np.asarray(frequency_Hz, float)
    delta = np.sqrt(resistivity_ohm_m / (np.pi * np.maximum(f, 1e-300) * 4.0e-7 * np.pi))
    check(log, 'Dowell copper AC resistance', 'd/delta', diameter_m / delta, 0.0, 3.0,
          'round-wire equivalence of Dowell untested past d/delta = 3')
    big = np.minimum(np.sqrt(porosity) * diameter_m * np.sqrt(np.pi) / 2.0 / delta, 300.0)
    small = big < 0.01
    x = np.where(small, 1.0, big)
    zeta1 = (np.sinh(2 * x) + np.sin(2 * x)) / (np.cosh(2 * x) - np.cos(2 * x))
    zeta2 = (np.sinh(x) - np.sin(x)) / (np.cosh(x) + np.cos(x))
    exact = x * (zeta1 + 2.0 / 3.0 * (layers ** 2 - 1) * zeta2)
    return np.where(small, 1.0 + (5.0 * layers ** 2 - 1.0) * big ** 4 / 45.0, exact)
