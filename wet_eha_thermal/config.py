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

from .model.oil import OIL_GRADES


class ConfigError(ValueError):
    """A configuration value that is missing, unknown, mistyped or out of range."""


def spec(low: Optional[float] = None, high: Optional[float] = None, *,
         low_open: bool = False, high_open: bool = False, default: Any = dataclasses.MISSING,
         choices: Optional[Tuple[str, ...]] = None, doc: str = ''):
    """Declare a config field with its allowed range (or choices) and a short description."""
    meta = {'low': low, 'high': high, 'low_open': low_open, 'high_open': high_open,
            'choices': choices, 'doc': doc}
    return field(default=default, metadata=meta)


def positive(doc: str = '', **kw):
    """Declare a field that must be strictly positive."""
    return spec(0.0, None, low_open=True, doc=doc, **kw)


def fraction(doc: str = '', **kw):
    """Declare a field in the open-closed interval (0, 1]."""
    return spec(0.0, 1.0, low_open=True, doc=doc, **kw)


def _range_text(meta: dict) -> str:
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
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(f'{key} = {value!r}: expected true or false')
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f'{key} = {value!r}: expected a whole number in '
                              f'{_range_text(meta)}')
    elif tp is float:
        if isinstance(value, str):
            # YAML 1.1 (PyYAML) reads 2.0e4, without an exponent sign, as text
            try:
                value = float(value)
            except ValueError:
                pass
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f'{key} = {value!r}: expected a number in {_range_text(meta)}')
        value = float(value)
        if not math.isfinite(value):
            raise ConfigError(f'{key} = {value!r}: expected a finite number in '
                              f'{_range_text(meta)}')
    elif tp is str:
        if not isinstance(value, str):
            raise ConfigError(f'{key} = {value!r}: expected text')
        if meta.get('choices') and value not in meta['choices']:
            raise ConfigError(f'{key} = {value!r}: unknown; allowed: '
                              f'{", ".join(meta["choices"])}')
        return value
    elif origin is tuple:
        if not isinstance(value, (list, tuple)) or not value:
            raise ConfigError(f'{key} = {value!r}: expected a non-empty list of numbers')
        return tuple(_check_value(f'{key}[{i}]', v, float, meta) for i, v in enumerate(value))
    lo, hi = meta.get('low'), meta.get('high')
    bad_lo = lo is not None and (value <= lo if meta['low_open'] else value < lo)
    bad_hi = hi is not None and (value >= hi if meta['high_open'] else value > hi)
    if bad_lo or bad_hi:
        raise ConfigError(f'{key} = {value!r}: out of range; allowed {_range_text(meta)}')
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
    density_kg_m3: float = positive()
    specific_heat_J_kgK: float = positive()

    @property
    def rho_c_J_m3K(self) -> float:
        """Volumetric heat capacity (J/(m^3 K))."""
        return self.density_kg_m3 * self.specific_heat_J_kgK


@dataclass(frozen=True, kw_only=True)
class Frame:
    """Motor frame (housing) over the stack and the end spaces."""

    outer_radius_m: float = positive()
    inner_radius_m: float = positive()
    length_m: float = positive('total axial length, stack plus both end spaces')
    emissivity: float = spec(0.0, 1.0)
    forced_air_htc_W_m2K: Optional[float] = spec(
        0.0, None, low_open=True, default=None,
        doc='fan cooling; null for natural convection plus radiation')
    material: Solid

    def check(self, key: str) -> None:
        """Check the frame geometry."""
        _below(key, 'inner_radius_m', self.inner_radius_m, 'outer_radius_m',
               self.outer_radius_m)


@dataclass(frozen=True, kw_only=True)
class Stator:
    """Laminated stator: yoke, teeth and the Steinmetz loss data of the steel."""

    outer_radius_m: float = positive()
    yoke_inner_radius_m: float = positive()
    bore_radius_m: float = positive()
    tooth_tip_depth_m: float = spec(0.0, None, doc='tooth tips between bore and slot')
    tooth_fraction: float = spec(0.0, 1.0, low_open=True, high_open=True,
                                 doc='share of the tooth annulus that is iron')
    material: Solid
    hysteresis_coeff_W_kgHzT: float = spec(0.0, None, doc='Steinmetz k_h per kg')
    steinmetz_exponent: float = spec(1.0, 3.0)
    eddy_coeff_W_kgHz2T2: float = spec(0.0, None, doc='Steinmetz k_e per kg')
    yoke_flux_density_T: float = spec(0.0, 2.5)
    teeth_flux_density_T: float = spec(0.0, 2.5)
    frame_contact_gap_m: float = spec(0.0, 1e-3, low_open=True,
                                      doc='equivalent air gap of the interference fit')
    contact_gap_conductivity_W_mK: float = positive()

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

    phases: int = spec(1, 12)
    phase_resistance_20C_ohm: float = positive('line to neutral')
    copper_tempco_1_K: float = spec(0.0, 0.01)
    copper_fill: float = fraction('copper share of the slot area')
    k_radial_W_mK: float = positive('slot-equivalent transverse conductivity')
    k_axial_W_mK: float = positive('along the conductors')
    copper_density_kg_m3: float = positive()
    copper_specific_heat_J_kgK: float = positive()
    insulation_density_kg_m3: float = positive()
    insulation_specific_heat_J_kgK: float = positive()
    end_overhang_m: float = positive('axial length of the end winding, each side')
    end_turn_length_m: float = positive('conductor length of one end turn, each side')
    liner_thickness_m: float = positive('slot liner (and wedge) thickness')
    liner_conductivity_W_mK: float = positive()
    insulation_limit_C: float = spec(0.0, 300.0, doc='insulation class limit')


@dataclass(frozen=True, kw_only=True)
class Rotor:
    """Surface-mounted PM rotor: sleeve, magnets, core, shaft and their contacts."""

    outer_radius_m: float = positive('over the sleeve')
    sleeve_thickness_m: float = positive()
    magnet_thickness_m: float = positive()
    core_inner_radius_m: float = positive('= shaft radius')
    shaft_length_m: float = positive()
    sleeve: Solid
    magnet: Solid
    core: Solid
    shaft: Solid
    sleeve_magnet_htc_W_m2K: float = positive('contact conductance per area')
    magnet_core_htc_W_m2K: float = positive('glue layer')
    core_shaft_htc_W_m2K: float = positive('shrink fit')
    magnet_limit_C: float = spec(0.0, 400.0)

    def check(self, key: str) -> None:
        """Check that the rotor layers fit inside each other."""
        inner = self.outer_radius_m - self.sleeve_thickness_m - self.magnet_thickness_m
        _below(key, 'core_inner_radius_m', self.core_inner_radius_m,
               'magnet inner radius (outer_radius_m - sleeve - magnet thickness)', inner)


@dataclass(frozen=True, kw_only=True)
class EndSpaces:
    """The two oil-filled end spaces, end caps and bearings."""

    oil_volume_m3: float = positive('each end space')
    htc_still_W_m2K: float = positive('oil convection with the rotor at rest')
    htc_speed_coeff: float = spec(0.0, None,
                                  doc='h = h_still + coeff * v_tip^0.8, v_tip in m/s')
    cap_thickness_m: float = positive()
    cap_material: Solid
    cap_frame_htc_W_m2K: float = positive('bolted joint, per area of the frame end face')
    bearing_radius_m: float = positive('bearing seat radius in the end cap')
    bearing_conductance_W_K: float = positive()


@dataclass(frozen=True, kw_only=True)
class Motor:
    """The wet motor: geometry, materials, contacts and discretisation."""

    slices: int = spec(1, 50, doc='axial Mellor slices of the stack')
    pole_pairs: int = spec(1, 50)
    slots: int = spec(3, 200)
    stack_length_m: float = positive()
    torque_constant_Nm_A: float = positive('per A RMS phase current')
    max_continuous_current_A: float = positive()
    frame: Frame
    stator: Stator
    winding: Winding
    rotor: Rotor
    end_spaces: EndSpaces

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
        _below(key or 'motor', 'stack_length_m', self.stack_length_m, 'rotor.shaft_length_m',
               self.rotor.shaft_length_m)
        _below(key + '.end_spaces' if key else 'end_spaces', 'bearing_radius_m',
               self.end_spaces.bearing_radius_m, 'frame inner radius',
               self.frame.inner_radius_m)
        _below(key + '.rotor' if key else 'rotor', 'core_inner_radius_m',
               self.rotor.core_inner_radius_m, 'end_spaces.bearing_radius_m',
               self.end_spaces.bearing_radius_m + 1e-12)


@dataclass(frozen=True, kw_only=True)
class Shell:
    """Solid shell of a hydraulic component, lumped: heat capacity and two convective areas."""

    mass_kg: float = positive()
    specific_heat_J_kgK: float = positive()
    oil_htc_W_m2K: float = positive('oil side')
    oil_area_m2: float = positive('oil side, per oil volume it wets')
    air_htc_W_m2K: float = positive('air side, convection plus radiation')
    air_area_m2: float = positive()

    @property
    def capacity_J_K(self) -> float:
        """Heat capacity (J/K)."""
        return self.mass_kg * self.specific_heat_J_kgK


@dataclass(frozen=True, kw_only=True)
class Pump:
    """Bidirectional axial piston pump without shaft seal (case drains through the motor)."""

    displacement_m3_rev: float = positive()
    internal_leak_coeff_m3: float = spec(0.0, None, doc='Q = C dp / mu, port to port')
    external_leak_coeff_m3: float = spec(0.0, None, doc='Q = C dp / mu, port to case')
    viscous_friction_coeff: float = spec(0.0, None, doc='C_v of T_loss = C_v mu D w')
    pressure_friction_coeff: float = spec(0.0, None, doc='C_f of T_loss = C_f D dp')
    coulomb_torque_Nm: float = spec(0.0, None, doc='T_c')
    friction_to_case_fraction: float = spec(0.0, 1.0, doc='rest heats the shell')
    extra_loss_W: float = spec(0.0, 1000.0, default=0.0, doc=(
        'constant heat into the case oil that the friction law lacks (a shaft seal, say); '
        'fit it from bench logs'))
    port_volume_m3: float = positive('each port (inlet/outlet)')
    case_volume_m3: float = positive()
    shell: Shell


@dataclass(frozen=True, kw_only=True)
class Actuator:
    """Double-rod (balanced) cylinder."""

    bore_m: float = positive()
    rod_m: float = positive()
    half_stroke_m: float = positive('travel each side of centre')
    dead_volume_m3: float = positive('each chamber at centre stroke minus the swept part')
    shell: Shell

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

    oil_volume_m3: float = positive()
    pressure_Pa: float = positive('working pressure of the low-pressure side')
    precharge_Pa: float = positive()
    shell: Shell


@dataclass(frozen=True, kw_only=True)
class Lines:
    """The two pump-actuator lines (identical)."""

    length_m: float = positive()
    bore_m: float = positive()
    wall_m: float = positive()
    wall_density_kg_m3: float = positive()
    wall_specific_heat_J_kgK: float = positive()
    air_htc_W_m2K: float = positive('outside, natural convection plus radiation')


@dataclass(frozen=True, kw_only=True)
class Hydraulics:
    """Hydraulic circuit of the EHA."""

    pump: Pump
    actuator: Actuator
    accumulator: Accumulator
    lines: Lines


@dataclass(frozen=True, kw_only=True)
class Fluid:
    """Hydraulic oil."""

    grade: str = spec(choices=tuple(OIL_GRADES), doc='oil grade')
    oil_limit_C: float = spec(0.0, 300.0, doc='highest oil temperature allowed in service')


@dataclass(frozen=True, kw_only=True)
class MapsJob:
    """Operating points and conditions of the motor maps."""

    speeds_rpm: Tuple[float, ...] = spec(0.0, 1e5, doc='speed sweep')
    sweep_current_A: float = positive('current held during the speed sweep')
    currents_A: Tuple[float, ...] = spec(0.0, 1e3, doc='current sweep')
    sweep_speed_rpm: float = spec(0.0, 1e5, doc='speed held during the current sweep')
    oil_inlet_C: float = spec(-54.0, 200.0)
    oil_flow_L_min: float = positive('leakage flow through the motor')
    case_pressure_Pa: float = spec(0.0, 5e7)
    ambient_C: float = spec(-60.0, 150.0)


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

    current_A: Channel
    speed_rad_s: Channel
    p_a_Pa: Channel
    p_b_Pa: Channel
    p_acc_Pa: Channel
    dp_Pa: Channel
    position_m: Channel


@dataclass(frozen=True, kw_only=True)
class AlertLevels:
    """Warn and critical thresholds of one estimated temperature."""

    warn_C: float = spec(-60.0, 400.0)
    critical_C: float = spec(-60.0, 400.0)
    hysteresis_K: float = spec(0.0, 50.0)
    min_duration_s: float = spec(0.0, 3600.0)
    latch: bool = spec(default=True)

    def check(self, key: str) -> None:
        """Check warn is below critical."""
        _below(key, 'warn_C', self.warn_C, 'critical_C', self.critical_C)


@dataclass(frozen=True, kw_only=True)
class Alerts:
    """Alert thresholds of the estimated temperatures (limits: reference-eha.md)."""

    winding_hotspot: AlertLevels
    magnet: AlertLevels
    oil: AlertLevels


@dataclass(frozen=True, kw_only=True)
class EstimatorSettings:
    """The live estimator: model step, averaging, fallbacks, forecast, uncertainty, alerts."""

    step_s: float = spec(0.001, 1.0, doc='model step in sample time')
    block_rate_Hz: float = spec(1.0, 5000.0, doc='grid on which samples are averaged per step')
    ambient_C: float = spec(-60.0, 150.0, doc='used until an ambient temperature arrives')
    coefficient_filter_s: float = spec(0.0, 600.0)
    model_uncertainty_K: float = spec(0.0, 50.0, doc='1-sigma model uncertainty (est.)')
    stale_uncertainty_K_per_s: float = spec(0.0, 10.0,
                                            doc='added per second an input is on fallback')
    forecast_window_s: float = spec(1.0, 3600.0, doc='recent duty repeated by the forecast')
    forecast_horizon_s: float = spec(60.0, 86400.0)
    forecast_step_s: float = spec(0.1, 60.0)
    forecast_period_s: float = spec(1.0, 3600.0, doc='a new forecast starts this often')
    pressure_inputs: str = spec(choices=('ports', 'differential'), doc=(
        'ports: absolute pressures of port A, port B and the accumulator; differential: '
        'one p_A - p_B sensor, the low side at the accumulator precharge pressure'))
    channels: Channels
    alerts: Alerts


@dataclass(frozen=True, kw_only=True)
class Config:
    """Whole configuration file."""

    motor: Motor
    hydraulics: Hydraulics
    fluid: Fluid
    maps: MapsJob
    estimator: EstimatorSettings


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
    return from_dict(Config, data)


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
