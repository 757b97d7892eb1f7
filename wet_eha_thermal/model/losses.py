"""
Electromagnetic losses of the motor (copper and stator iron).

Rotor eddy-current loss is neglected, as in the reference paper (Jiao et al.,
Chin. J. Aeronaut. 35(6), 2022); oil friction lives in :mod:`.correlations`.
The laws are compiled (:func:`~.compiled.jit`): the motor's losses kernel
calls them; they take floats or arrays.
"""

import numpy as np

from .compiled import jit

T_REF_COPPER_K = 293.15  # 20 degC, reference of the phase resistance


@jit
def copper_resistance(r_20C_ohm, tempco_1_K, T_K):
    """
    Return a copper resistance (ohm) at ``T_K``: R_20 [1 + a (T - 20 degC)].

    Linear law, accurate to about 1 % from -50 to 200 degC for annealed copper
    (a = 0.00393 1/K).
    """
    return r_20C_ohm * (1.0 + tempco_1_K * (T_K - T_REF_COPPER_K))


@jit
def electrical_frequency(speed_rad_s, pole_pairs: int):
    """Return the electrical frequency (Hz) of a machine at mechanical speed ``speed_rad_s``."""
    return pole_pairs * np.abs(speed_rad_s) / (2.0 * np.pi)


@jit
def steinmetz_loss_density(frequency_Hz, flux_density_T, hysteresis_coeff: float,
                           exponent: float, eddy_coeff: float):
    """
    Return iron loss per kg (W/kg): k_h f B^alpha + k_e f^2 B^2 (Steinmetz split).

    Coefficients are per kg and fitted on the lamination's loss curves; the
    split holds for sinusoidal flux without DC bias in the fitted range of f
    and B (the caller's data sheet states it).
    """
    return (hysteresis_coeff * frequency_Hz * flux_density_T ** exponent
            + eddy_coeff * frequency_Hz ** 2 * flux_density_T ** 2)
