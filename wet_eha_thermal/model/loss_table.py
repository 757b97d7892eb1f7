"""
The motor's electromagnetic losses over speed and current, tabulated once.

A model step needs the rotor's eddy-current losses and the AC part of the
copper loss at a step's speed samples and mean current squared. Their laws
(:mod:`.losses`) sum harmonics; an FEA loss map (``motor.loss_map``,
:mod:`wet_eha_thermal.loss_map`) is a table. Either way the model tabulates
them once, on a uniform grid of |speed| and of the RMS current squared
(losses that grow as I^2 are then exact between grid lines), and a compiled
kernel interpolates bilinearly per step. Outside the grid the table is
extrapolated linearly from its edge cells and the use is flagged.

Columns (:data:`COLUMNS`): magnet, sleeve and rotor-core losses (W); the
copper loss's excess over phases x I^2 R_dc as an equivalent current squared
(A^2, so that the copper loss keeps following R(T) node by node); the stator
iron loss (W, a map's; the analytical model keeps Steinmetz per sample).
"""

from dataclasses import dataclass
from typing import Dict, Optional

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from .compiled import jit
from .losses import copper_ac_factor, copper_resistance, electrical_frequency
from .rotor_losses import rotor_eddy_loss_table
from .validity import ValidityLog
from .winding import winding_layout
from ..config import Motor
from ..loss_map import read_loss_map
from ..units import C_TO_K, RPM

MAGNET, SLEEVE, ROTOR_CORE, COPPER_EXCESS, IRON = range(5)
COLUMNS = ('magnet_W', 'sleeve_W', 'rotor_core_W', 'copper_excess_A2', 'stator_iron_W')
#: grid lines of the analytical table (speed, current squared): 500 r/min and 5 A^2 x 1.5^2
#: apart on the reference rig; within 1 % of the direct sum between them
ANALYTICAL_GRID = (61, 41)
#: grid lines a map is resampled onto (linear in speed and in I^2: scipy), per axis
MAP_GRID = (201, 81)


@dataclass(frozen=True)
class LossTable:
    """
    A uniform table of :data:`COLUMNS` over |speed| (rad/s) and I^2 (A^2).

    :ivar grid: first speed line (rad/s), speed spacing, first current-squared
        line (A^2) and its spacing: what :func:`table_values` takes.
    :ivar values: ``(speeds, currents squared, COLUMNS)``.
    :ivar from_map: True when an FEA loss map filled it (its iron loss then
        replaces Steinmetz's).
    :ivar source: what filled it, for the validity flag of its extrapolation.
    """

    grid: tuple
    values: np.ndarray
    from_map: bool
    source: str

    def speed_range_rad_s(self) -> tuple:
        """Return the lowest and highest |speed| (rad/s) of the grid."""
        w0, dw = self.grid[:2]
        return w0, w0 + dw * (self.values.shape[0] - 1)

    def current_range_A(self) -> tuple:
        """Return the lowest and highest RMS current (A) of the grid."""
        q0, dq = self.grid[2:]
        return np.sqrt(q0), np.sqrt(q0 + dq * (self.values.shape[1] - 1))

    def flag(self, log: Optional[ValidityLog], speed_abs_rad_s, current_sq_A2) -> None:
        """Flag in ``log`` the speeds and current outside the grid (the table extrapolated)."""
        if log is None:
            return
        what = f'{self.source} loss table'
        log.check(what, 'speed_rpm', np.asarray(speed_abs_rad_s) / RPM,
                  *(v / RPM for v in self.speed_range_rad_s()),
                  'speed outside the loss table; extrapolated linearly')
        log.check(what, 'current_A', np.sqrt(current_sq_A2), *self.current_range_A(),
                  'current outside the loss table; extrapolated linearly')


def build_loss_table(cfg: Motor) -> LossTable:
    """
    Tabulate the electromagnetic losses of ``cfg``: from its loss map, or analytically.

    The analytical table (:func:`~.rotor_losses.rotor_eddy_loss_table`, and
    the copper's AC factor at the fundamental and the PWM ripple, at 20 degC:
    :func:`~.losses.copper_ac_factor`)
    covers 0 to 1.5 times the top speed and the peak current; a map's table
    its own grid, resampled with scipy linearly in speed and in I^2 (exact
    for losses that grow as I^2). Motors that differ only in what the losses
    do not depend on (a calibration's thermal parameters) share one table.
    """
    if cfg.loss_map is not None:
        return _map_table(cfg)
    st, ro, wd = cfg.stator, cfg.rotor, cfg.winding
    key = (cfg.electromagnetic, cfg.pole_pairs, cfg.slots, cfg.stack_length_m,
           cfg.torque_constant_Nm_A, cfg.max_speed_rpm, cfg.peak_current_A, st.bore_radius_m,
           ro.outer_radius_m, ro.sleeve_thickness_m, ro.magnet_thickness_m,
           ro.core_inner_radius_m, wd.phases, wd.phase_resistance_20C_ohm,
           wd.conductor_diameter_m, winding_layout(cfg))
    table = _TABLES.get(key)
    if table is None:
        if len(_TABLES) >= 16:
            _TABLES.clear()
        table = _TABLES[key] = _analytical_table(cfg)
    return table


#: analytical tables by what they depend on (a second each to build)
_TABLES: Dict[tuple, 'LossTable'] = {}


def _analytical_table(cfg: Motor) -> LossTable:
    """Return the analytical table of ``cfg``."""
    n_w, n_i = ANALYTICAL_GRID
    w = np.linspace(0.0, 1.5 * cfg.max_speed_rpm * RPM, n_w)
    isq = np.linspace(0.0, (1.5 * cfg.peak_current_A) ** 2, n_i)
    rotor = rotor_eddy_loss_table(cfg, w, np.sqrt(isq))
    wd, lay = cfg.winding, winding_layout(cfg)
    fr1 = copper_ac_factor(electrical_frequency(w, cfg.pole_pairs), wd.conductor_diameter_m,
                           lay.rows, lay.porosity)
    values = np.zeros((n_w, n_i, len(COLUMNS)))
    values[..., MAGNET] = rotor['magnet_W']
    values[..., SLEEVE] = rotor['sleeve_W']
    values[..., ROTOR_CORE] = rotor['core_W']
    # the AC excess at the fundamental on I^2, and the ripple's copper loss, at 20 degC
    values[..., COPPER_EXCESS] = ((fr1[:, None] - 1.0) * isq[None, :]
                                  + rotor['ripple_ac_factor'] * rotor['ripple_rms_A'] ** 2)
    return LossTable((0.0, float(w[1] - w[0]), 0.0, float(isq[1] - isq[0])), values, False,
                     'analytical')


def _map_table(cfg: Motor) -> LossTable:
    """Resample ``cfg.loss_map`` onto a uniform grid of speed and I^2."""
    lm = cfg.loss_map
    grid = read_loss_map(lm.file)
    w_map, isq_map = grid.speeds_rpm * RPM, grid.currents_A ** 2
    n_w, n_i = MAP_GRID
    w = np.linspace(w_map[0], w_map[-1], n_w)
    isq = np.linspace(isq_map[0], isq_map[-1], n_i)
    points = np.stack(np.meshgrid(w, isq, indexing='ij'), axis=-1)
    wd = cfg.winding

    def resample(name):
        return RegularGridInterpolator((w_map, isq_map), grid.losses_W[name])(points)

    values = np.zeros((n_w, n_i, len(COLUMNS)))
    values[..., MAGNET] = resample('magnet_W')
    values[..., SLEEVE] = resample('sleeve_W')
    values[..., ROTOR_CORE] = resample('rotor_core_W')
    values[..., IRON] = resample('stator_iron_W')
    # the map's copper at its temperature, as phases (R(T_map) I^2 + R_20^2 / R(T_map) excess)
    r_20 = wd.phase_resistance_20C_ohm
    r_map = copper_resistance(r_20, wd.copper_tempco_1_K, lm.copper_temperature_C + C_TO_K)
    values[..., COPPER_EXCESS] = ((resample('copper_W') / wd.phases - r_map * points[..., 1])
                                  * r_map / r_20 ** 2)
    return LossTable((float(w[0]), float(w[1] - w[0]), float(isq[0]), float(isq[1] - isq[0])),
                     values, True, f'map {lm.file}')


@jit
def table_values(values, grid, speed_abs_rad_s, current_sq_A2):
    """
    Return the columns at each sample, and whether a sample lay outside the grid.

    ``speed_abs_rad_s`` (|speed|, rad/s) and ``current_sq_A2`` (I^2, A^2) are
    arrays of one length; the result is ``(samples, columns)``. Bilinear in
    speed and I^2; past the grid, linear from its edge cells. ``grid``:
    :attr:`LossTable.grid`.
    """
    w0, dw, q0, dq = grid
    n_w, n_q, n_c = values.shape
    out = np.empty((speed_abs_rad_s.size, n_c))
    outside = False
    for k in range(speed_abs_rad_s.size):
        t = (speed_abs_rad_s[k] - w0) / dw
        u = (current_sq_A2[k] - q0) / dq
        outside = outside or t < 0.0 or t > n_w - 1 or u < 0.0 or u > n_q - 1
        i = min(max(int(np.floor(t)), 0), n_w - 2)
        j = min(max(int(np.floor(u)), 0), n_q - 2)
        fw, fq = t - i, u - j
        for c in range(n_c):
            lo = values[i, j, c] + fq * (values[i, j + 1, c] - values[i, j, c])
            hi = values[i + 1, j, c] + fq * (values[i + 1, j + 1, c] - values[i + 1, j, c])
            out[k, c] = lo + fw * (hi - lo)
    return out, outside
