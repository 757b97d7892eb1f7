"""
Typed, validated configuration loaded from YAML.

Every field states its unit in its name and its allowed range in its
metadata. Loading checks missing and unknown keys, types and ranges, and the
geometric consistency of the parts; the first problem found raises one
:class:`ConfigError` whose message names the key, the value and what is
allowed, so a user can fix the file without reading the code.
"""

import dataclasses
from dataclasses import dataclass, field
import math
import os
from pathlib import Path
import sys
import typing
from typing import Any, Dict, Optional, Tuple

import yaml

from .loss_map import LossMapError, read_loss_map


#: The oil grades a configuration may name; model/oil.py holds the properties of each.
OIL_GRADE_NAMES = ('MIL-PRF-5606', 'MIL-PRF-83282')


class ConfigError(ValueError):
    """A configuration value that is missing, unknown, mistyped or out of range."""


def spec(low: Optional[float] = None, high: Optional[float] = None, *,
         low_open: bool = False, high_open: bool = False, default: Any = dataclasses.MISSING,
         choices: Optional[Tuple[str, ...]] = None, doc: str = '',
         default_factory: Any = dataclasses.MISSING, min_items: int = 1):
    """
    Declare a config field with its allowed range (or choices) and a short description.

    ``min_items``: the fewest entries a list field may hold.
    """
    meta = {'low': low, 'high': high, 'low_open': low_open, 'high_open': high_open,
            'choices': choices, 'doc': doc, 'min_items': min_items}
    return field(default=default, default_factory=default_factory, metadata=meta)


def positive(doc: str = '', **kw):
    """Declare a field that must be strictly positive."""
    return spec(0.0, None, low_open=True, doc=doc, **kw)


def fraction(doc: str = '', **kw):
    """Declare a field in the open-closed interval (0, 1]."""
    return spec(0.0, 1.0, low_open=True, doc=doc, **kw)


def range_text(meta: dict) -> str:
    """Return a field's allowed range as an interval, e.g. ``(0, 1]`` or ``(-inf, 300]``."""
    lo, hi = meta['low'], meta['high']
    left = '(' if meta['low_open'] or lo is None else '['
    right = ')' if meta['high_open'] or hi is None else ']'
    return (f'{left}{"-inf" if lo is None else f"{lo:g}"}, '
            f'{"inf" if hi is None else f"{hi:g}"}{right}')


def _check_value(key: str, value: Any, tp: Any, meta: dict) -> Any:
    origin = typing.get_origin(tp)
    if origin is typing.Union:  # Optional[X]
        if value is None:
            return None
        tp = [t for t in typing.get_args(tp) if t is not type(None)][0]
        origin = typing.get_origin(tp)
    if dataclasses.is_dataclass(tp):
        return from_dict(tp, value, key)
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(f'{key} = {value!r}: expected true or false')
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f'{key} = {value!r}: expected a whole number in '
                              f'{range_text(meta)}')
    elif tp is float:
        if isinstance(value, str):
            # YAML 1.1 (PyYAML) reads 2.0e4, without an exponent sign, as text
            try:
                value = float(value)
            except ValueError:
                pass
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f'{key} = {value!r}: expected a number in {range_text(meta)}')
        value = float(value)
        if not math.isfinite(value):
            raise ConfigError(f'{key} = {value!r}: expected a finite number in '
                              f'{range_text(meta)}')
    elif tp is str:
        if not isinstance(value, str):
            raise ConfigError(f'{key} = {value!r}: expected text')
        if meta.get('choices') and value not in meta['choices']:
            raise ConfigError(f'{key} = {value!r}: unknown; allowed: '
                              f'{", ".join(meta["choices"])}')
        return value
    elif origin is tuple:
        item = typing.get_args(tp)[0]
        if not isinstance(value, (list, tuple)) or len(value) < meta.get('min_items', 1):
            what = 'numbers' if item is float else 'entries'
            raise ConfigError(f'{key} = {value!r}: expected a non-empty list of {what}')
        return tuple(_check_value(f'{key}[{i}]', v, item, meta) for i, v in enumerate(value))
    elif origin is dict:
        if not isinstance(value, dict):
            raise ConfigError(f'{key} = {value!r}: expected a mapping')
        item = typing.get_args(tp)[1]
        for k in value:
            if not isinstance(k, str):
                raise ConfigError(f'{key}: key {k!r} is not text')
        return {k: _check_value(f'{key}.{k}', v, item, meta) for k, v in value.items()}
    lo, hi = meta.get('low'), meta.get('high')
    bad_lo = lo is not None and (value <= lo if meta['low_open'] else value < lo)
    bad_hi = hi is not None and (value >= hi if meta['high_open'] else value > hi)
    if bad_lo or bad_hi:
        raise ConfigError(f'{key} = {value!r}: out of range; allowed {range_text(meta)}')
    return value


def from_dict(cls, data: Any, key: str = ''):
    """Build dataclass ``cls`` from a mapping, checking every key (``key`` is the path so far)."""
    where = key or 'the top level'
    if not isinstance(data, dict):
        raise ConfigError(f'{where}: expected a mapping of keys, got {data!r}')
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - names)
    if unknown:
        raise ConfigError(f'{key + "." if key else ""}{unknown[0]}: unknown key in {where}; '
                          f'allowed: {", ".join(sorted(names))}')
    values = {}
    for f in dataclasses.fields(cls):
        sub = f'{key}.{f.name}' if key else f.name
        if f.name not in data:
            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                raise ConfigError(f'{sub}: missing key')
            continue
        tp = hints[f.name]
        if dataclasses.is_dataclass(tp):
            values[f.name] = from_dict(tp, data[f.name], sub)
        else:
            values[f.name] = _check_value(sub, data[f.name], tp, dict(f.metadata))
    obj = cls(**values)
    check = getattr(obj, 'check', None)
    if check is not None:
        check(key)
    return obj


def _below(key: str, a_name: str, a: float, b_name: str, b: float) -> None:
    if not a < b:
        raise ConfigError(f'{key}.{a_name} = {a!r}: must be below {key}.{b_name} = {b!r}')


# --------------------------------------------------------------------- parts
@dataclass(frozen=True, kw_only=True)
class Solid:
    """Thermal properties of a solid material (anisotropic conductivity allowed)."""

    k_radial_W_mK: float = positive('radial (in-plane) conductivity')
    k_axial_W_mK: float = positive('axial conductivity')
    density_kg_m3: float = positive('times the specific heat: the heat capacity per volume')
    specific_heat_J_kgK: float = positive('specific heat capacity')

    @property
    def rho_c_J_m3K(self) -> float:
        """Volumetric heat capacity (J/(m^3 K))."""
        return self.density_kg_m3 * self.specific_heat_J_kgK


@dataclass(frozen=True, kw_only=True)
class Frame:
    """Motor frame (housing) over the stack and the end spaces."""

    outer_radius_m: float = positive('outer radius of the barrel, whose surface meets the air')
    inner_radius_m: float = positive('bore of the housing, where the stator sits')
    length_m: float = positive('total axial length, stack plus both end spaces')
    emissivity: float = spec(0.0, 1.0, doc=(
        'of the barrel and end caps, for radiation to ambient (reference rig: est.)'))
    forced_air_htc_W_m2K: Optional[float] = spec(
        0.0, None, low_open=True, default=None,
        doc='fan cooling; null for natural convection plus radiation')
    natural_convection: str = spec(
        choices=('churchill_chu', 'morgan_mcadams'), default='churchill_chu',
        doc='free convection law of the barrel and the end caps: Churchill-Chu (1975), '
            'or the power laws of Morgan (1975, cylinder) and McAdams (1954, plate)')
    material: Solid = spec(doc='housing material, also of the frame over the end spaces')

    def check(self, key: str) -> None:
        """Check the frame geometry."""
        _below(key, 'inner_radius_m', self.inner_radius_m, 'outer_radius_m',
               self.outer_radius_m)


@dataclass(frozen=True, kw_only=True)
class Stator:
    """Laminated stator: yoke, teeth and the Steinmetz loss data of the steel."""

    outer_radius_m: float = positive('outer radius of the laminations, in the frame bore')
    yoke_inner_radius_m: float = positive('inner radius of the yoke: the slot bottoms')
    bore_radius_m: float = positive('at the tooth tips: the outer wall of the oil-filled airgap')
    tooth_tip_depth_m: float = spec(0.0, None, doc='tooth tips between bore and slot')
    tooth_fraction: float = spec(0.0, 1.0, low_open=True, high_open=True,
                                 doc='share of the tooth annulus that is iron')
    material: Solid = spec(doc='lamination steel; axial conductivity across the laminations')
    hysteresis_coeff_W_kgHzT: float = spec(0.0, None, doc='Steinmetz k_h per kg')
    steinmetz_exponent: float = spec(1.0, 3.0, doc='Steinmetz alpha of k_h f B^alpha')
    eddy_coeff_W_kgHz2T2: float = spec(0.0, None, doc='Steinmetz k_e per kg')
    yoke_flux_density_T: float = spec(0.0, 2.5, doc='in the yoke: the B of its iron loss')
    teeth_flux_density_T: float = spec(0.0, 2.5, doc='in the teeth: the B of their iron loss')
    frame_contact_gap_m: float = spec(0.0, 1e-3, low_open=True,
                                      doc='equivalent air gap of the interference fit')
    contact_gap_conductivity_W_mK: float = positive(
        'of the gas in that gap: h = conductivity / gap (reference rig: air at about 60 degC)')

    def check(self, key: str) -> None:
        """Check the stator geometry."""
        _below(key, 'bore_radius_m', self.bore_radius_m, 'yoke_inner_radius_m',
               self.yoke_inner_radius_m)
        _below(key, 'yoke_inner_radius_m', self.yoke_inner_radius_m, 'outer_radius_m',
               self.outer_radius_m)
        _below(key, 'tooth_tip_depth_m', self.tooth_tip_depth_m, 'slot depth (yoke inner '
               'radius - bore radius)', self.yoke_inner_radius_m - self.bore_radius_m)


@dataclass(frozen=True, kw_only=True)
class Winding:
    """Slot winding and end windings (copper + insulation + impregnation)."""

    phases: int = spec(1, 12, doc='the copper loss is phases x I^2 R, I the RMS phase current')
    phase_resistance_20C_ohm: float = positive('line to neutral')
    copper_tempco_1_K: float = spec(0.0, 0.01, doc=(
        'temperature coefficient of the resistance: R = R_20 (1 + a (T - 20 degC))'))
    copper_fill: float = fraction('copper share of the slot area')
    k_radial_W_mK: float = positive('slot-equivalent transverse conductivity')
    k_axial_W_mK: float = positive('along the conductors')
    copper_density_kg_m3: float = positive('of the conductors, for the heat capacity')
    copper_specific_heat_J_kgK: float = positive('of the conductors')
    insulation_density_kg_m3: float = positive(
        'of what is not copper (insulation, impregnation), for the heat capacity')
    insulation_specific_heat_J_kgK: float = positive('of what is not copper')
    end_overhang_m: float = positive('axial length of the end winding, each side')
    end_turn_length_m: float = positive('conductor length of one end turn, each side')
    liner_thickness_m: float = positive('slot liner (and wedge) thickness')
    liner_conductivity_W_mK: float = positive(
        'of the slot liner: winding to yoke and teeth through h = conductivity / thickness')
    insulation_limit_C: float = spec(0.0, 300.0, doc=(
        'insulation class limit: the winding hot-spot limit of the reports, the forecast and '
        'the margin current'))
    conductor_diameter_m: float = spec(0.0, 0.01, low_open=True, doc=(
        "bare diameter of the round wire: Dowell's AC resistance of the copper"))
    layers_per_slot_side: int = spec(1, 50, doc=(
        'conductor layers of one coil side, from the slot bottom to the opening (Dowell p)'))


@dataclass(frozen=True, kw_only=True)
class Rotor:
    """Surface-mounted PM rotor: sleeve, magnets, core, shaft and their contacts."""

    outer_radius_m: float = positive('over the sleeve')
    sleeve_thickness_m: float = positive('radial thickness of the retaining sleeve')
    magnet_thickness_m: float = positive('radial thickness of the magnets, under the sleeve')
    core_inner_radius_m: float = positive('= shaft radius')
    shaft_length_m: float = positive(
        'whole shaft; its ends past the stack reach through the end spaces to the bearings')
    sleeve: Solid = spec(doc='retaining sleeve (reference rig: Inconel 718, est.)')
    magnet: Solid = spec(doc='the magnets (reference rig: NdFeB, catalogue values)')
    core: Solid = spec(doc='rotor core under the magnets')
    shaft: Solid = spec(doc='the shaft, through the stack and both end spaces')
    sleeve_magnet_htc_W_m2K: float = positive('contact conductance per area')
    magnet_core_htc_W_m2K: float = positive('glue layer')
    core_shaft_htc_W_m2K: float = positive('shrink fit')
    magnet_limit_C: float = spec(0.0, 400.0, doc=(
        "the magnet grade's limit: the magnet limit of the reports and the forecast"))

    def check(self, key: str) -> None:
        """Check that the rotor layers fit inside each other."""
        inner = self.outer_radius_m - self.sleeve_thickness_m - self.magnet_thickness_m
        _below(key, 'core_inner_radius_m', self.core_inner_radius_m,
               'magnet inner radius (outer_radius_m - sleeve - magnet thickness)', inner)


@dataclass(frozen=True, kw_only=True)
class EndSpaces:
    """The two oil-filled end spaces and end caps."""

    oil_volume_m3: float = positive('each end space')
    rotor_clearance_m: float = positive(
        "axial clearance between the rotor's end face and the end cap: the Daily-Nece "
        'disc friction and heat transfer of the face')
    htc_multiplier: float = spec(0.0, 10.0, low_open=True, default=1.0, doc=(
        "calibration factor on every end-space coefficient (the correlations' value: 1)"))
    cap_thickness_m: float = positive('axial thickness of each end cap (reference rig: est.)')
    cap_material: Solid = spec(doc='end caps (reference rig: aluminium alloy)')
    cap_frame_htc_W_m2K: float = positive('bolted joint, per area of the frame end face')


@dataclass(frozen=True, kw_only=True)
class Bearings:
    """The two rolling bearings, one in each end cap, running flooded in the end-space oil."""

    seat_radius_m: float = positive('bearing seat (outer ring) radius in the end cap')
    mean_diameter_m: float = positive('pitch diameter (bore + outside diameter) / 2')
    conductance_W_K: float = positive(
        'through each bearing, shaft end to end cap (reference rig: est.)')
    mass_kg: float = positive('each bearing: its heat capacity (steel)')
    radial_load_N: float = spec(0.0, None, doc="each bearing's radial load: Palmgren's P1")
    static_load_rating_N: float = positive("C0 of the catalogue: Palmgren's load factor f1")
    lubrication_factor_f0: float = positive(
        "Palmgren's f0 of the bearing type and lubrication (Harris and Kotzalas, ch. 12)")
    friction_factor: float = spec(0.0, 10.0, default=1.0, doc=(
        "calibration factor on Palmgren's friction torque (the correlation's value: 1)"))


@dataclass(frozen=True, kw_only=True)
class LossMap:
    """Motor losses over speed and current from an electromagnetic FEA (Motor-CAD, JMAG, ...)."""

    file: str = spec(doc=(
        'CSV grid with the columns speed_rpm, current_A, copper_W, stator_iron_W, magnet_W, '
        'sleeve_W (and optionally rotor_core_W), one row per point of a full speed x current '
        "grid; a relative path is taken from the configuration file's folder"))
    copper_temperature_C: float = spec(-60.0, 250.0, default=20.0, doc=(
        "winding temperature of the map's copper loss: the model scales it by R(T)"))

    def check(self, key: str) -> None:
        """Read and check the CSV now, so that a bad map stops the load naming this key."""
        try:
            read_loss_map(self.file)
        except LossMapError as exc:
            raise ConfigError(f'{key}.file = {self.file!r}: {exc}') from exc


@dataclass(frozen=True, kw_only=True)
class Electromagnetic:
    """Data of the rotor's eddy-current losses and of the inverter's PWM ripple."""

    magnet_resistivity_ohm_m: float = positive('electrical resistivity of the magnets')
    magnet_relative_permeability: float = spec(1.0, 2.0, doc='recoil permeability')
    magnet_remanence_T: float = spec(0.1, 2.0, doc=(
        "at 20 degC: the magnets' airgap field, which with the torque constant sets the "
        'current sheet of the winding'))
    pole_arc_fraction: float = fraction('magnet arc over pole pitch')
    magnet_pieces_per_pole: int = spec(1, 100, doc='magnet pieces of one pole around the rotor')
    magnet_pieces_axial: int = spec(1, 100, doc='magnet pieces of one pole along the stack')
    sleeve_resistivity_ohm_m: float = positive('electrical resistivity of the retaining sleeve')
    slot_opening_m: float = spec(0.0, None, doc=(
        'width of the slot openings at the bore; the current sheet is spread over it'))
    pwm_frequency_Hz: float = positive('switching (carrier) frequency of the two-level inverter')
    dc_link_voltage_V: float = positive("the inverter's DC link")
    phase_inductance_H: float = positive('line to neutral, at the PWM frequencies')
    rotor_core: str = spec(choices=('solid', 'laminated'), doc=(
        'the steel under the magnets: solid (eddy loss by its surface impedance) or '
        'laminated (no loss)'))
    core_resistivity_ohm_m: float = positive('of a solid rotor core')
    core_relative_permeability: float = spec(1.0, 1.0e5, doc=(
        "of a solid rotor core, incremental, under the magnets' bias"))
    loss_factor: float = spec(0.0, 10.0, default=1.0, doc=(
        'calibration multiplier on the rotor eddy losses (magnets, sleeve, core)'))


@dataclass(frozen=True, kw_only=True)
class Motor:
    """The wet motor: geometry, materials, contacts and discretisation."""

    slices: int = spec(1, 50, doc='axial Mellor slices of the stack')
    pole_pairs: int = spec(1, 50, doc=(
        'rotor pole pairs: the iron loss frequency is pole_pairs x speed / (2 pi)'))
    slots: int = spec(3, 200, doc=(
        "stator slots: the tooth pitch, and the slot sides that carry the winding's heat to "
        'the teeth'))
    stack_length_m: float = positive('axial length of the laminated stack (the active length)')
    torque_constant_Nm_A: float = positive('per A RMS phase current')
    max_continuous_current_A: float = positive(
        "continuous rating, A RMS (datasheet): the estimator's margin-current search starts there")
    peak_current_A: float = positive(
        'peak rating, A RMS (datasheet): the loss tables cover 1.5 times it')
    max_speed_rpm: float = positive(
        'top speed (datasheet): the loss tables cover 1.5 times it, and are extrapolated above')
    frame: Frame = spec(doc='the housing over the stack and the end spaces')
    stator: Stator = spec(doc='the laminated stator core')
    winding: Winding = spec(doc='slot winding and end windings')
    rotor: Rotor = spec(doc='rotor and shaft')
    end_spaces: EndSpaces = spec(doc='the oil-filled spaces between the stack and the end caps')
    bearings: Bearings = spec(doc='the two shaft bearings, in the end caps')
    electromagnetic: Electromagnetic = spec(doc=(
        "rotor eddy losses and PWM ripple: the magnets', sleeve's and core's electrical data "
        'and the drive'))
    loss_map: Optional[LossMap] = spec(default=None, doc=(
        'losses from an electromagnetic FEA instead of the analytical laws; null: analytical'))

    def check(self, key: str) -> None:
        """Check that the parts fit together."""
        p = f'{key}.' if key else ''
        if abs(self.stator.outer_radius_m - self.frame.inner_radius_m) > 1e-9:
            raise ConfigError(f'{p}stator.outer_radius_m = {self.stator.outer_radius_m!r}: '
                              f'must equal {p}frame.inner_radius_m = '
                              f'{self.frame.inner_radius_m!r} (the fit is a contact gap)')
        _below(key + '.rotor' if key else 'rotor', 'outer_radius_m', self.rotor.outer_radius_m,
               'stator bore radius', self.stator.bore_radius_m)
        _below(key or 'motor', 'stack_length_m', self.stack_length_m, 'frame.length_m',
               self.frame.length_m)
        if self.max_continuous_current_A > self.peak_current_A:
            raise ConfigError(f'{p}max_continuous_current_A = {self.max_continuous_current_A!r}: '
                              f'must not exceed {p}peak_current_A = {self.peak_current_A!r}')
        _below(key + '.end_spaces' if key else 'end_spaces', 'rotor_clearance_m',
               self.end_spaces.rotor_clearance_m, 'the end space length ((frame.length_m - '
               'stack_length_m) / 2)', 0.5 * (self.frame.length_m - self.stack_length_m))
        _below(key or 'motor', 'stack_length_m', self.stack_length_m, 'rotor.shaft_length_m',
               self.rotor.shaft_length_m)
        _below(key + '.bearings' if key else 'bearings', 'seat_radius_m',
               self.bearings.seat_radius_m, 'frame inner radius', self.frame.inner_radius_m)
        _below(key + '.rotor' if key else 'rotor', 'core_inner_radius_m',
               self.rotor.core_inner_radius_m, 'bearings.seat_radius_m',
               self.bearings.seat_radius_m + 1e-12)


@dataclass(frozen=True, kw_only=True)
class Shell:
    """Solid shell of a hydraulic component, lumped: heat capacity and two convective areas."""

    mass_kg: float = positive('times the specific heat: the heat capacity')
    specific_heat_J_kgK: float = positive('of the shell material')
    oil_htc_W_m2K: float = positive('oil side')
    oil_area_m2: float = positive(
        "oil side: the pump's is shared by case and ports (60/20/20 %, est.); the actuator's "
        'is per chamber')
    air_htc_W_m2K: float = positive('air side, convection plus radiation')
    air_area_m2: float = positive('outer surface, to ambient')

    @property
    def capacity_J_K(self) -> float:
        """Heat capacity (J/K)."""
        return self.mass_kg * self.specific_heat_J_kgK


@dataclass(frozen=True, kw_only=True)
class Pump:
    """Bidirectional axial piston pump without shaft seal (case drains through the motor)."""

    displacement_m3_rev: float = positive('geometric displacement per shaft revolution')
    internal_leak_coeff_m3: float = spec(0.0, None, doc='laminar Q = C dp / mu, port to port')
    external_leak_coeff_m3: float = spec(0.0, None, doc='laminar Q = C dp / mu, port to case')
    leak_gap_height_m: float = positive(
        'height h of the equivalent gap of both leakage paths (width b = 12 C l / h^3): with '
        'its length it sets the gap Reynolds number and where the laminar law turns into the '
        'orifice law', default=1.0e-5)
    leak_gap_length_m: float = positive('length l of that gap along the flow', default=2.0e-3)
    leak_discharge_coeff: float = fraction(
        'C_d of the orifice law Q = C_d b h sqrt(2 dp / rho) the leakage tends to at high gap '
        'Reynolds numbers', default=0.61)
    viscous_friction_coeff: float = spec(0.0, None, doc='C_v of T_loss = C_v mu D w')
    pressure_friction_coeff: float = spec(0.0, None, doc='C_f of T_loss = C_f D dp')
    coulomb_torque_Nm: float = spec(0.0, None, doc='T_c')
    friction_to_case_fraction: float = spec(0.0, 1.0, doc='rest heats the shell')
    extra_loss_W: float = spec(0.0, 1000.0, default=0.0, doc=(
        'constant heat into the case oil that the friction law lacks (a shaft seal, say); '
        'fit it from bench logs'))
    port_volume_m3: float = positive('each port (inlet/outlet)')
    case_volume_m3: float = positive(
        "oil in the pump case: the external leakage fills it, the motor's cooling flow drains it")
    shell: Shell = spec(doc='the pump body (reference rig: aluminium)')


@dataclass(frozen=True, kw_only=True)
class Actuator:
    """Double-rod (balanced) cylinder."""

    bore_m: float = positive('cylinder bore diameter')
    rod_m: float = positive(
        'rod diameter, both sides: the flow is pi (bore^2 - rod^2) / 4 times the rod speed')
    half_stroke_m: float = positive('travel each side of centre')
    dead_volume_m3: float = positive('each chamber at centre stroke minus the swept part')
    shell: Shell = spec(doc='the cylinder body (reference rig: steel)')

    @property
    def area_m2(self) -> float:
        """Annular piston area (m^2)."""
        return 0.25 * 3.141592653589793 * (self.bore_m ** 2 - self.rod_m ** 2)

    def check(self, key: str) -> None:
        """Check the rod fits the bore."""
        _below(key, 'rod_m', self.rod_m, 'bore_m', self.bore_m)


@dataclass(frozen=True, kw_only=True)
class Accumulator:
    """Gas-charged accumulator holding the low-pressure side (the pump case drains to it)."""

    oil_volume_m3: float = positive('oil held in the accumulator')
    pressure_Pa: float = positive(
        'working pressure of the low-pressure side (also the low side of a differential sensor)')
    precharge_Pa: float = positive(
        'gas precharge (datasheet); the model does not use it: the low side is at pressure_Pa')
    shell: Shell = spec(doc='the accumulator body (reference rig: steel)')


@dataclass(frozen=True, kw_only=True)
class Lines:
    """The two pump-actuator lines (identical)."""

    length_m: float = positive('each line, pump to actuator')
    bore_m: float = positive('inner diameter')
    wall_m: float = positive('wall thickness')
    wall_density_kg_m3: float = positive('of the tube wall, for its heat capacity')
    wall_specific_heat_J_kgK: float = positive('of the tube wall')
    air_htc_W_m2K: float = positive('outside, natural convection plus radiation')


@dataclass(frozen=True, kw_only=True)
class Hydraulics:
    """Hydraulic circuit of the EHA."""

    pump: Pump = spec(doc='the pump, its two ports and its case')
    actuator: Actuator = spec(doc='the cylinder and its two chambers')
    accumulator: Accumulator = spec(doc='the low-pressure side')
    lines: Lines = spec(doc='the two lines between the pump ports and the chambers')
    substep_s: float = spec(1e-4, 10.0, default=0.05, doc=(
        'longest sub-step of the oil volumes inside a model step: their flows, volumes and '
        'pressure work swing within a duty cycle, and a step mean misplaces that heat'))


@dataclass(frozen=True, kw_only=True)
class Fluid:
    """Hydraulic oil."""

    grade: str = spec(choices=OIL_GRADE_NAMES, doc='oil grade')
    oil_limit_C: float = spec(0.0, 300.0, doc='highest oil temperature allowed in service')


@dataclass(frozen=True, kw_only=True)
class MapsJob:
    """Operating points and conditions of the motor maps."""

    speeds_rpm: Tuple[float, ...] = spec(0.0, 1e5, doc='speed sweep')
    sweep_current_A: float = positive('current held during the speed sweep')
    currents_A: Tuple[float, ...] = spec(0.0, 1e3, doc='current sweep')
    sweep_speed_rpm: float = spec(0.0, 1e5, doc='speed held during the current sweep')
    oil_inlet_C: float = spec(-54.0, 200.0, doc=(
        'oil entering the motor (maps --oil-inlet-C overrides it)'))
    oil_flow_L_min: float = positive('leakage flow through the motor')
    case_pressure_Pa: float = spec(0.0, 5e7, doc=(
        "of the oil in the motor, for the oil's density and viscosity"))
    ambient_C: float = spec(-60.0, 150.0, doc=(
        'air around the motor (maps --ambient-C overrides it)'))


@dataclass(frozen=True, kw_only=True)
class Channel:
    """One sensor input of the estimator: how stale it may get and what values are plausible."""

    timeout_s: float = positive('no sample for this long: stale, the fallback takes over')
    low: float = spec(doc='smallest plausible value (SI unit of the channel)')
    high: float = spec(doc='largest plausible value')

    def check(self, key: str) -> None:
        """Check the range is not empty."""
        _below(key, 'low', self.low, 'high', self.high)


@dataclass(frozen=True, kw_only=True)
class Channels:
    """
    The estimator's sensor inputs (SI units: A RMS, rad/s, Pa, m).

    ``dp_Pa`` (port A minus port B) is used instead of the three absolute
    pressures when ``estimator.pressure_inputs`` is ``differential``.
    """

    current_A: Channel = spec(doc='motor phase current, RMS')
    speed_rad_s: Channel = spec(doc='motor shaft speed, signed')
    p_a_Pa: Channel = spec(doc='pressure of actuator port A')
    p_b_Pa: Channel = spec(doc='pressure of actuator port B')
    p_acc_Pa: Channel = spec(doc='accumulator pressure')
    dp_Pa: Channel = spec(doc='port A minus port B, from one differential sensor')
    position_m: Channel = spec(doc=(
        'LVDT rod position: 0 at centre stroke, positive as chamber A fills'))


@dataclass(frozen=True, kw_only=True)
class AlertLevels:
    """Warn and critical thresholds of one estimated temperature."""

    warn_C: float = spec(-60.0, 400.0, doc=(
        'the estimate at or above this for min_duration_s raises WARN'))
    critical_C: float = spec(-60.0, 400.0, doc='the same for CRITICAL')
    hysteresis_K: float = spec(0.0, 50.0, doc=(
        'a level clears below its threshold minus this; a dip within it keeps the pickup timer'))
    min_duration_s: float = spec(0.0, 3600.0, doc=(
        'how long the estimate must stay at or above a threshold to raise its level'))
    latch: bool = spec(default=True, doc='a raised level stays reported until acknowledged')

    def check(self, key: str) -> None:
        """Check warn is below critical."""
        _below(key, 'warn_C', self.warn_C, 'critical_C', self.critical_C)


@dataclass(frozen=True, kw_only=True)
class Alerts:
    """Alert thresholds of the estimated temperatures (limits: docs/model.md, reference rig)."""

    winding_hotspot: AlertLevels = spec(doc='the hottest winding node')
    magnet: AlertLevels = spec(doc='the hottest magnet slice')
    oil: AlertLevels = spec(doc="the hottest oil volume, the motor's or the circuit's")


@dataclass(frozen=True, kw_only=True)
class Thermocouple:
    """One rig thermocouple as the live correction sees it."""

    use: bool = spec(default=True, doc='correct the model with it; false: displayed only')
    sigma_K: float = spec(0.0, 50.0, low_open=True, default=0.5,
                          doc='1-sigma noise of one reading (K)')


@dataclass(frozen=True, kw_only=True)
class Thermocouples:
    """The rig's thermocouples (``interface.THERMOCOUPLES``) and the trust in each."""

    winding: Thermocouple = spec(default_factory=Thermocouple, doc=(
        'in the winding: one point, read as the winding mean'))
    frame: Thermocouple = spec(default_factory=Thermocouple, doc='on the motor frame')
    pump_inlet: Thermocouple = spec(default_factory=Thermocouple, doc='in the pump inlet oil')
    pump_case: Thermocouple = spec(default_factory=Thermocouple, doc='in the pump case oil')
    chamber_a: Thermocouple = spec(default_factory=Thermocouple, doc='in actuator chamber A')
    chamber_b: Thermocouple = spec(default_factory=Thermocouple, doc='in actuator chamber B')
    motor_oil_outlet: Thermocouple = spec(default_factory=Thermocouple,
                                          doc='in the oil leaving the motor')


@dataclass(frozen=True, kw_only=True)
class Correction:
    """
    Live correction of the model with measured temperatures (``estimator/correction.py``).

    Every key has a default: a configuration without this section runs
    open-loop, as before the correction existed.
    """

    enabled: bool = spec(default=False, doc='false: thermocouples are displayed, never used')
    thermocouples: Thermocouples = spec(default_factory=Thermocouples, doc=(
        'which rig thermocouples correct the model, and the noise of each'))
    heat_noise_W: float = spec(0.0, 1000.0, default=0.5, doc=(
        'process noise: white heat-rate error into every node with heat capacity, 1 sigma '
        'of its mean over 1 s (W)'))
    case_heat_sigma_W: float = spec(0.0, 1000.0, default=20.0, doc=(
        'prior 1 sigma of an unknown heat into the pump case oil that the filter learns '
        '(W); 0: no such state'))
    case_heat_rate_W_per_sqrt_s: float = spec(0.0, 100.0, default=0.3, doc=(
        'random-walk rate of that heat (W/s^0.5)'))
    winding_heat_sigma_W: float = spec(0.0, 1000.0, default=0.0, doc=(
        'prior 1 sigma of an unknown heat into the winding (W); 0: no such state'))
    winding_heat_rate_W_per_sqrt_s: float = spec(0.0, 100.0, default=0.1, doc=(
        'random-walk rate of that heat (W/s^0.5)'))
    initial_correlation: float = spec(0.0, 0.999, default=0.9, doc=(
        'correlation of the temperature errors when the correction starts (their 1 sigma '
        'is estimator.model_uncertainty_K)'))
    unmodelled_sigma_K: float = spec(0.0, 50.0, default=0.5, doc=(
        'added (in quadrature) to every filtered uncertainty: what the filter does not model'))
    stale_timeout_s: float = spec(0.0, 3600.0, low_open=True, default=2.0, doc=(
        'a thermocouple silent this long is stale; an older reading is never used'))
    gate_sigma: float = spec(1.0, 100.0, default=5.0, doc=(
        'a reading whose innovation exceeds this many sigma is not used'))
    gate_count: int = spec(1, 100000, default=5, doc=(
        'that many gated readings in a row drop the thermocouple'))
    recover_count: int = spec(1, 100000, default=10, doc=(
        'that many readings inside the gate in a row take a dropped thermocouple back'))
    noise_window: int = spec(4, 100000, default=20, doc=(
        'readings over which the observed noise is measured'))
    noisy_ratio: float = spec(1.0, 1000.0, low_open=True, default=4.0, doc=(
        'observed noise above this multiple of sigma_K drops the thermocouple'))
    stuck_window_s: float = spec(0.0, 3600.0, low_open=True, default=3.0, doc=(
        'readings that stay within stuck_tolerance_K this long are frozen: not used'))
    stuck_tolerance_K: float = spec(0.0, 10.0, default=0.01, doc=(
        'spread of frozen readings (K); keep it below the sensor resolution'))
    stuck_motion_K: float = spec(0.0, 100.0, low_open=True, default=1.0, doc=(
        'a frozen thermocouple whose estimate moved this much since it froze is stuck'))


@dataclass(frozen=True, kw_only=True)
class EstimatorSettings:
    """The live estimator: model step, averaging, fallbacks, forecast, uncertainty, alerts."""

    step_s: float = spec(0.001, 1.0, doc='model step in sample time')
    block_rate_Hz: float = spec(1.0, 5000.0, doc='grid on which samples are averaged per step')
    ambient_C: float = spec(-60.0, 150.0, doc='used until an ambient temperature arrives')
    coefficient_filter_s: float = spec(0.0, 600.0, doc=(
        "the speed, oil flow and temperatures that set the motor's coefficients pass two "
        'low-pass stages of this time constant; the losses do not'))
    model_uncertainty_K: float = spec(0.0, 50.0, doc='1-sigma model uncertainty (est.)')
    stale_uncertainty_K_per_s: float = spec(0.0, 10.0,
                                            doc='added per second an input is on fallback')
    forecast_window_s: float = spec(1.0, 3600.0, doc='recent duty repeated by the forecast')
    forecast_horizon_s: float = spec(60.0, 86400.0, doc=(
        'how far ahead the forecast looks for the time to each limit'))
    forecast_step_s: float = spec(0.1, 60.0, doc=(
        'first step of a forecast; doubled while the state moves under 0.5 K a step, up to '
        'forecast_window_s'))
    forecast_period_s: float = spec(1.0, 3600.0, doc='a new forecast starts this often')
    forecast_substep_s: float = spec(1e-4, 10.0, default=0.25, doc=(
        "longest sub-step of the oil volumes in the forecast (the estimator's is "
        'hydraulics.substep_s): its duty is one mean sample per model step'))
    pressure_inputs: str = spec(choices=('ports', 'differential'), doc=(
        'ports: absolute pressures of port A, port B and the accumulator; differential: '
        'one p_A - p_B sensor, the low side at hydraulics.accumulator.pressure_Pa'))
    max_future_s: float = spec(0.0, 86400.0, default=0.5, doc=(
        'a sample stamped further ahead of the receiving clock is rejected (counted as '
        'future): a clock glitch of the source never moves the model'))
    max_lag_s: float = spec(0.0, 60.0, default=2.0, doc=(
        'an input still arriving whose stamps lag the receiving clock by up to this is '
        'waited for (a busy receiver delivers late); more, and it is stale'))
    clock_jump_s: float = spec(0.0, 86400.0, low_open=True, default=1.0, doc=(
        'the receiving clock going back by more than this is a jump: the model time '
        're-starts there, the thermal state is kept'))
    max_steps_per_call: int = spec(1, 1000000, default=5, doc=(
        'model steps one advance() makes at most (a held block across a silence counts '
        'as one); the rest waits for the next call, so no call blocks for long'))
    buffer_samples: int = spec(1024, 100000000, default=131072, doc=(
        'samples kept per input until the model steps past them; beyond, new samples are '
        'dropped and counted (overflow)'))
    channels: Channels = spec(doc='timeout and plausible range of each sensor input')
    alerts: Alerts = spec(doc='warn and critical thresholds of the estimated temperatures')
    correction: Correction = spec(default_factory=Correction, doc=(
        "the rig's thermocouples correct the model; without it, open loop"))


@dataclass(frozen=True, kw_only=True)
class CalibratedParameter:
    """One parameter of a calibration: the value fitted and its 95 % interval, or why not."""

    key: str = spec(doc='dotted key of the thermal-model parameter')
    nominal: float = spec(doc="value before the calibration (the key's unit)")
    value: float = spec(doc='value after it: the nominal when the data could not identify it')
    ci95_low: Optional[float] = spec(default=None, doc=(
        'low end of the 95 % interval; null when not fitted'))
    ci95_high: Optional[float] = spec(default=None, doc='high end of it; null when not fitted')
    identifiable: bool = spec(doc='false: the logs do not determine it; held at the nominal')
    step_shift: float = spec(default=0.0, doc=(
        'the change a finer model step implies (linearised); inside the interval'))
    note: str = spec(default='', doc='why it was held, or that it ended on a bound')

    def check(self, key: str) -> None:
        """Check the interval holds the value and exists only for a fitted parameter."""
        model_parameter(self.key, f'{key}.key = {self.key!r}')
        if (self.ci95_low is None) != (self.ci95_high is None):
            raise ConfigError(f'{key}: give both ci95_low and ci95_high, or neither')
        if self.ci95_low is not None and not self.ci95_low <= self.value <= self.ci95_high:
            raise ConfigError(f'{key}.value = {self.value!r}: outside its interval '
                              f'[{self.ci95_low!r}, {self.ci95_high!r}]')
        if not self.identifiable and self.ci95_low is not None:
            raise ConfigError(f'{key}: a parameter that was not identifiable has no interval')


@dataclass(frozen=True, kw_only=True)
class CalibrationLog:
    """A log a calibration used: where it was and what it was (to tell if it changed)."""

    path: str = spec(doc='as given on the command line')
    role: str = spec(choices=('fit', 'validate'), doc=(
        'fit: the parameters were fitted to it; validate: held out, only compared'))
    size_bytes: int = spec(0, None, doc='total size of its files')
    sha256: str = spec(doc='hex digest of the file; empty for data made in memory')
    duration_s: float = spec(0.0, None, doc='span of the inputs used')

    def check(self, key: str) -> None:
        """Check the digest is 64 hex digits (or empty)."""
        if self.sha256 and (len(self.sha256) != 64
                            or any(c not in '0123456789abcdef' for c in self.sha256)):
            raise ConfigError(f'{key}.sha256 = {self.sha256!r}: expected 64 hex digits')


@dataclass(frozen=True, kw_only=True)
class CalibrationResult:
    """What ``wet-eha-thermal calibrate`` did: written into the calibrated configuration."""

    created_utc: str = spec(doc='ISO 8601')
    base_config: str = spec(doc='the configuration the fit started from')
    step_s: float = spec(0.001, 1.0, doc='model step of the fit')
    parameters: Tuple[CalibratedParameter, ...] = spec(doc=(
        'every parameter asked for: fitted, or held at its nominal value'))
    logs: Tuple[CalibrationLog, ...] = spec(doc='the logs it read: fit and held-out')
    fit_rms_before_K: float = spec(0.0, None, doc='RMS error over the fit logs, nominal')
    fit_rms_after_K: float = spec(0.0, None, doc='the same, calibrated')


@dataclass(frozen=True, kw_only=True)
class Calibration:
    """
    Calibration of the thermal model on bench logs (``wet-eha-thermal calibrate``).

    Every key has a default, so a configuration without this section loads;
    ``bounds`` then holds nothing and a calibration needs them added.
    """

    step_s: float = spec(0.001, 1.0, default=1.0, doc=(
        'model step of the fit; each evaluation reruns every log at this step'))
    average_rate_Hz: float = spec(1.0, 5000.0, default=50.0, doc=(
        'the inputs are averaged once onto this grid (current as RMS, the others as means, '
        'the position sampled); a whole number of grid intervals per step'))
    residual_interval_s: float = spec(0.0, 3600.0, low_open=True, default=10.0, doc=(
        'the readings and the model are compared as means over intervals this long'))
    thermocouple_sigma_K: float = spec(0.0, 50.0, low_open=True, default=0.2, doc=(
        '1-sigma noise of one reading when its message gives variance 0'))
    thermocouple_lag_s: float = spec(0.0, 600.0, default=1.0, doc=(
        'first-order lag of the thermocouples, applied to the model before comparing'))
    min_effect_K: float = spec(0.0, 100.0, default=0.5, doc=(
        'a parameter moved across its bounds must change some reading by this much (RMS '
        'over the log) to be fitted'))
    max_collinearity: float = spec(1.0, None, default=20.0, doc=(
        'a parameter whose effect is this close to a combination of the others is held'))
    max_ci_fraction: float = spec(0.0, 1.0, low_open=True, default=0.25, doc=(
        'a fitted parameter whose 95 % interval is wider than this share of its bounds is '
        'not identified: held at its nominal value'))
    max_iterations: int = spec(1, 1000, default=30, doc='model evaluations of the fit, at most')
    check_step_s: float = spec(0.0, 1.0, default=0.1, doc=(
        'the fitted model is run once more at this finer step: the shift of each parameter '
        'it implies is reported and widens its interval; 0: no check'))
    fit: Tuple[str, ...] = spec(default=(), min_items=0, doc=(
        'the parameters fitted when the command names none (dotted keys with bounds)'))
    bounds: Dict[str, Tuple[float, ...]] = spec(default_factory=dict, doc=(
        "key: [low, high] in the key's own unit; the parameters a calibration may fit"))
    result: Optional[CalibrationResult] = spec(default=None, doc=(
        'written by the calibration: fitted values, intervals, logs'))

    def check(self, key: str) -> None:
        """Check the steps fit together, every bound is [low, high] and every fit key has one."""
        for name, step in (('step_s', self.step_s), ('check_step_s', self.check_step_s)):
            per_step = step * self.average_rate_Hz
            if step and abs(per_step - round(per_step)) > 1e-6 * max(per_step, 1.0):
                raise ConfigError(f'{key}.average_rate_Hz = {self.average_rate_Hz!r}: must '
                                  f'give a whole number of intervals per {key}.{name} = '
                                  f'{step!r}')
        if self.check_step_s >= self.step_s:
            raise ConfigError(f'{key}.check_step_s = {self.check_step_s!r}: must be below '
                              f'{key}.step_s = {self.step_s!r} (or 0: no check)')
        if self.residual_interval_s < self.step_s:
            raise ConfigError(f'{key}.residual_interval_s = {self.residual_interval_s!r}: must '
                              f'be at least {key}.step_s = {self.step_s!r}')
        for name, pair in self.bounds.items():
            if len(pair) != 2 or not pair[0] < pair[1]:
                raise ConfigError(f'{key}.bounds.{name} = {list(pair)!r}: expected [low, high] '
                                  'with low < high')
        for i, name in enumerate(self.fit):
            if name not in self.bounds:
                raise ConfigError(f'{key}.fit[{i}] = {name!r}: has no bounds; add '
                                  f'"{name}: [low, high]" to {key}.bounds')
            if name in self.fit[:i]:
                raise ConfigError(f'{key}.fit[{i}] = {name!r}: listed twice')


#: Sections of the configuration whose numbers are parameters of the thermal model.
MODEL_SECTIONS = ('motor', 'hydraulics')


def model_parameter(key: str, where: Optional[str] = None) -> dict:
    """
    Return the range metadata of a numeric thermal-model key (``hydraulics.pump.extra_loss_W``).

    Raise :class:`ConfigError`, whose message starts with ``where`` (default:
    the key), when ``key`` names no field, or one that is not a plain number
    of ``motor`` or ``hydraulics``.
    """
    prefix = where or key
    if key.split('.')[0] not in MODEL_SECTIONS:
        raise ConfigError(f'{prefix}: not a parameter of the thermal model (a number under '
                          f'{" or ".join(s + "." for s in MODEL_SECTIONS)})')
    cls: Any = Config
    tp: Any = None
    meta: dict = {}
    for part in key.split('.'):
        fields = {f.name: f for f in dataclasses.fields(cls)} \
            if dataclasses.is_dataclass(cls) else {}
        if part not in fields:
            raise ConfigError(f'{prefix}: no such key in the configuration')
        tp, meta = typing.get_type_hints(cls)[part], dict(fields[part].metadata)
        cls = tp
    if tp is not float:
        raise ConfigError(f'{prefix}: not a number that can be fitted')
    return meta


@dataclass(frozen=True, kw_only=True)
class Config:
    """Whole configuration file."""

    motor: Motor
    hydraulics: Hydraulics
    fluid: Fluid
    maps: MapsJob
    estimator: EstimatorSettings
    calibration: Calibration = field(default_factory=Calibration)

    def check(self, key: str) -> None:
        """Check each calibration bound names a model parameter and holds its present value."""
        for name, (low, high) in self.calibration.bounds.items():
            where = f'calibration.bounds.{name}'
            meta = model_parameter(name, where)
            for value in (low, high):
                _check_value(where, value, float, meta)    # a bound the key itself allows
            nominal = config_value(self, name)
            if not low <= nominal <= high:
                raise ConfigError(f'{where} = [{low!r}, {high!r}]: does not hold the configured '
                                  f'value {name} = {nominal!r}')


def config_dir() -> Path:
    """Return the folder holding the shipped YAML files (source tree, venv or colcon install)."""
    here = Path(__file__).resolve().parent
    candidates = [here.parent / 'config',
                  Path(sys.prefix) / 'share' / 'wet_eha_thermal' / 'config']
    try:
        from ament_index_python.packages import get_package_share_directory
        candidates.append(Path(get_package_share_directory('wet_eha_thermal')) / 'config')
    except Exception:  # noqa: B902 - not a ROS install, or package not indexed
        pass
    for c in candidates:
        if (c / 'reference_eha.yaml').is_file():
            return c
    raise ConfigError('cannot find the shipped config folder; looked in: '
                      + ', '.join(str(c) for c in candidates))


def default_config_path() -> Path:
    """Return the path of the reference rig's configuration."""
    return config_dir() / 'reference_eha.yaml'


def load_config(path: Optional[os.PathLike] = None,
                overrides: Optional[Dict[str, Any]] = None) -> Config:
    """Load and validate a YAML configuration (the reference rig when ``path`` is None)."""
    p = Path(path) if path is not None else default_config_path()
    try:
        text = p.read_text()
    except OSError as exc:
        raise ConfigError(f'cannot read config file {p}: {exc.strerror}') from exc
    return config_from_yaml(text, str(p), overrides)


def config_from_yaml(text: str, origin: str = 'config',
                     overrides: Optional[Dict[str, Any]] = None) -> Config:
    """Validate a configuration given as YAML text (``origin`` names it in messages)."""
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f'{origin}: not valid YAML: {exc}') from exc
    for dotted, value in (overrides or {}).items():
        node = data
        *parents, last = dotted.split('.')
        for part in parents:
            node = node.setdefault(part, {})
        node[last] = value
    _resolve_loss_map(data, origin)
    return from_dict(Config, data)


def _resolve_loss_map(data: Any, origin: str) -> None:
    """Make a relative ``motor.loss_map.file`` relative to the folder of the file ``origin``."""
    try:
        loss_map = data['motor']['loss_map']
        name = loss_map['file']
    except (TypeError, KeyError):
        return
    if isinstance(name, str) and not Path(name).is_absolute() and Path(origin).is_file():
        loss_map['file'] = str(Path(origin).resolve().parent / name)


def config_value(cfg: Config, key: str) -> Any:
    """Return the value of a dotted key, e.g. ``hydraulics.pump.extra_loss_W``."""
    node: Any = cfg
    for part in key.split('.'):
        if not dataclasses.is_dataclass(node) or not hasattr(node, part):
            raise ConfigError(f'{key}: no such key in the configuration')
        node = getattr(node, part)
    return node


def with_values(cfg: Config, values: Dict[str, Any]) -> Config:
    """Return a validated copy of ``cfg`` with dotted keys set, e.g. for a fit or a truth rig."""
    data = dataclasses.asdict(cfg)
    for dotted, value in values.items():
        config_value(cfg, dotted)        # names an unknown key
        node = data
        *parents, last = dotted.split('.')
        for part in parents:
            node = node[part]
        node[last] = value
    return from_dict(Config, data)
