"""
One description of the winding: what the wire, the turns and the slot imply (docs/model.md).

From the round wire (bare and insulated diameter, strands in hand), the
turns per coil, the coil sides per slot, the parallel paths and the slot of
the stator, :func:`winding_layout` derives the copper fill of the slot, the
rows of conductors Dowell's and Ferreira's AC factor needs and their
porosity, the series turns per phase and the phase resistance they give.
:func:`check_winding` stops a configuration whose winding contradicts its
phase resistance or its torque constant, or does not fit its slot.

The coil is wound on its tooth: its conductors stack along the tooth (the
slot's depth, from the bottom towards the opening) in as many rows as the
depth holds, and build up away from the tooth flank in as few columns as
the turns need. A row's wires lie across the slot, along its leakage field,
which grows row by row towards the opening: the rows are the "layers" p of
the AC factor, and the wires of both coil sides in a row over the slot's
breadth its porosity eta = n d / b.
"""

from dataclasses import dataclass
import math

import numpy as np

from .losses import COPPER_RESISTIVITY_20C_OHM_M
from ..config_spec import ConfigError

#: How far the phase resistance the winding gives may lie from the configured one: the
#: end-turn length (est.) is about 30 % of the turn and uncertain by about a quarter, which
#: moves R by about 8 %; leads and connections add a few per cent
RESISTANCE_TOLERANCE = 0.10
#: How far the turns may lie from those the torque constant implies: that relation takes the
#: magnets' slotless field and ignores slotting (Carter), saturation and end effects
TURNS_TOLERANCE = 0.15


@dataclass(frozen=True)
class WindingLayout:
    """What a winding description implies (SI units)."""

    slot_area_m2: float          #: one slot, between tooth tips and yoke, teeth excluded
    conductors_per_side: int     #: wires of one coil side: turns x strands in hand
    rows: int                    #: rows of wires along the slot depth (the AC factor's p)
    columns: int                 #: wires of one coil side in a row
    porosity: float              #: copper share of the slot's breadth in a row (eta)
    copper_fill: float           #: copper share of the slot area
    series_turns: float          #: series turns per phase
    turn_length_m: float         #: mean length of one turn: 2 (stack + end turn)
    resistance_20C_ohm: float    #: phase resistance the wire gives at 20 degC


def winding_layout(motor) -> WindingLayout:
    """
    Return the :class:`WindingLayout` of a :class:`~..config.Motor`.

    The slot is the network's: an annular sector between the tooth tips
    (bore + tip depth) and the yoke, of the slots' share (1 - tooth fraction)
    of the pitch; the liner takes its thickness off each side. Rows: as many
    as the depth holds at the insulated diameter, fewer when the coil side has
    fewer wires; columns the wires of a coil side over the rows. R_20 =
    rho_Cu l_turn N / (a s pi d^2 / 4), N the series turns per phase
    (coils / phases x turns / a), a the parallel paths, s the strands.

    >>> from wet_eha_thermal.config import load_config
    >>> w = winding_layout(load_config().motor)
    >>> w.rows, w.columns, round(w.copper_fill, 3), w.series_turns
    (14, 2, 0.181, 36.0)
    >>> round(w.resistance_20C_ohm, 4), round(w.porosity, 3)
    (0.065, 0.383)
    """
    st, wd = motor.stator, motor.winding
    r_tip = st.bore_radius_m + st.tooth_tip_depth_m
    r_yoke = st.yoke_inner_radius_m
    slot_share = (1.0 - st.tooth_fraction) * 2.0 * np.pi / motor.slots
    area = slot_share * 0.5 * (r_yoke ** 2 - r_tip ** 2)
    depth = r_yoke - r_tip - 2.0 * wd.liner_thickness_m
    breadth = slot_share * 0.5 * (r_yoke + r_tip)        # at the mean radius
    per_side = wd.turns_per_coil * wd.strands_in_hand
    rows_max = max(int(depth // wd.insulated_diameter_m), 1)
    columns = math.ceil(per_side / rows_max)
    rows = math.ceil(per_side / columns)
    wire = np.pi * wd.conductor_diameter_m ** 2 / 4.0
    coils = motor.slots * wd.coil_sides_per_slot / 2.0
    turns = coils / wd.phases * wd.turns_per_coil / wd.parallel_paths
    turn = 2.0 * (motor.stack_length_m + wd.end_turn_length_m)
    return WindingLayout(
        slot_area_m2=float(area), conductors_per_side=per_side, rows=rows, columns=columns,
        porosity=float(wd.coil_sides_per_slot * columns * wd.conductor_diameter_m / breadth),
        copper_fill=float(wd.coil_sides_per_slot * per_side * wire / area),
        series_turns=float(turns), turn_length_m=float(turn),
        resistance_20C_ohm=float(COPPER_RESISTIVITY_20C_OHM_M * turn * turns
                                 / (wd.parallel_paths * wd.strands_in_hand * wire)))


def check_winding(motor, key: str = 'motor') -> None:
    """
    Raise :class:`~..config_spec.ConfigError` if the winding contradicts the rest of ``motor``.

    It must fit its slot; give the configured phase resistance within
    :data:`RESISTANCE_TOLERANCE`; and have the series turns the torque
    constant implies within :data:`TURNS_TOLERANCE`: k_t = sqrt(2) m k_w1 N
    R L B_1 (:func:`~.rotor_losses.implied_turns_per_phase`: sinusoidal EMF,
    current in phase with it, the magnets' slotless fundamental field B_1 at
    the bore radius R, k_w1 from the star of slots).
    """
    from .rotor_losses import implied_turns_per_phase

    wd, st = motor.winding, motor.stator
    w = f'{key}.winding'
    if wd.insulated_diameter_m < wd.conductor_diameter_m:
        raise ConfigError(f'{w}.insulated_diameter_m = {wd.insulated_diameter_m!r}: must not be '
                          f'below {w}.conductor_diameter_m = {wd.conductor_diameter_m!r}')
    coils = motor.slots * wd.coil_sides_per_slot / 2.0
    if coils % (wd.phases * wd.parallel_paths):
        raise ConfigError(f'{w}: {motor.slots} slots x coil_sides_per_slot '
                          f'{wd.coil_sides_per_slot} / 2 = {coils:g} coils do not share out '
                          f'over phases {wd.phases} x parallel_paths {wd.parallel_paths}')
    lay = winding_layout(motor)
    r_tip = st.bore_radius_m + st.tooth_tip_depth_m
    depth = st.yoke_inner_radius_m - r_tip - 2.0 * wd.liner_thickness_m
    breadth = ((1.0 - st.tooth_fraction) * np.pi * (st.yoke_inner_radius_m + r_tip)
               / motor.slots - 2.0 * wd.liner_thickness_m)
    width = lay.columns * wd.insulated_diameter_m * wd.coil_sides_per_slot
    if depth < wd.insulated_diameter_m or width > breadth:
        raise ConfigError(
            f'{w}: the coil sides do not fit the slot: turns_per_coil {wd.turns_per_coil} x '
            f'strands_in_hand {wd.strands_in_hand} wires of insulated_diameter_m '
            f'{wd.insulated_diameter_m!r} make {lay.rows} rows x {lay.columns} columns per '
            f'coil side, {width * 1e3:.2f} mm across the slot for coil_sides_per_slot '
            f'{wd.coil_sides_per_slot}; the slot (stator geometry, less the liners) is '
            f'{depth * 1e3:.2f} mm deep and {breadth * 1e3:.2f} mm wide at mid-depth')
    r_cfg = wd.phase_resistance_20C_ohm
    if abs(lay.resistance_20C_ohm / r_cfg - 1.0) > RESISTANCE_TOLERANCE:
        raise ConfigError(
            f'{w}.phase_resistance_20C_ohm = {r_cfg!r} contradicts the wire: rho_Cu l_turn N / '
            f'(a s A_wire) = {lay.resistance_20C_ohm:.4g} ohm with N = {lay.series_turns:g} '
            f'series turns (turns_per_coil {wd.turns_per_coil}, coil_sides_per_slot '
            f'{wd.coil_sides_per_slot}, parallel_paths a = {wd.parallel_paths}), strands_in_hand '
            f's = {wd.strands_in_hand}, conductor_diameter_m {wd.conductor_diameter_m!r}, '
            f'l_turn = 2 (stack_length_m + end_turn_length_m) = {lay.turn_length_m:.4g} m; '
            f'allowed within {RESISTANCE_TOLERANCE:.0%}')
    implied = implied_turns_per_phase(motor)
    if abs(lay.series_turns / implied - 1.0) > TURNS_TOLERANCE:
        raise ConfigError(
            f'{w}: {lay.series_turns:g} series turns per phase (turns_per_coil '
            f'{wd.turns_per_coil}, coil_sides_per_slot {wd.coil_sides_per_slot}, parallel_paths '
            f'{wd.parallel_paths}) contradict {key}.torque_constant_Nm_A = '
            f'{motor.torque_constant_Nm_A!r}, which with the magnets ({key}.electromagnetic.'
            f'magnet_remanence_T {motor.electromagnetic.magnet_remanence_T!r}) and the bore '
            f'implies {implied:.1f} (k_t = sqrt(2) m k_w1 N R L B_1); allowed within '
            f'{TURNS_TOLERANCE:.0%}')
