"""
Typed, validated configuration loaded from YAML.

Every field states its unit in its name and its allowed range in its
metadata. Loading checks missing and unknown keys, types and ranges, and the
geometric consistency of the parts; the first problem found raises one
:class:`ConfigError` whose message names the key, the value and what is
allowed, so a user can fix the file without reading the code.

Three modules by job: :mod:`.config_spec` declares and checks a key,
:mod:`.config_model` holds the rig's sections (``motor``, ``hydraulics``,
``fluid``), and this one the jobs' sections (``maps``, ``estimator``,
``calibration``), the whole :class:`Config` and its loading. Import every
name from here.
"""

import dataclasses
from dataclasses import dataclass, field
import os
from pathlib import Path
import sys
import typing
from typing import Any, Dict, Optional, Tuple

import yaml

# the rig's sections and the key machinery, re-exported: callers import from here
from .config_model import (  # noqa: F401
    Accumulator, Actuator, Bearings, Electromagnetic, EndSpaces, Fluid, Frame, Hydraulics,
    Lines, LossMap, Motor, Pump, Rotor, Shell, Solid, Stator, Winding)
from .config_spec import (  # noqa: F401
    check_below, check_value, ConfigError, fraction, from_dict, OIL_GRADE_NAMES, positive,
    range_text, spec)
from .config_uncertainty import (  # noqa: F401
    LAW_KEYS, Structural, UncertainParameter, Uncertainty)


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
        check_below(key, 'low', self.low, 'high', self.high)


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
        check_below(key, 'warn_C', self.warn_C, 'critical_C', self.critical_C)


@dataclass(frozen=True, kw_only=True)
class Alerts:
    """Alert thresholds of the estimated temperatures (limits: docs/model.md, reference rig)."""

    winding_hotspot: AlertLevels = spec(doc='the hottest point in the slot winding')
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
class CurrentLimitSettings:
    """
    The thermal current limits the drive reads (``estimator/limits.py``, docs/live.md).

    Every key has a default: a configuration without this section gets them.
    """

    period_s: float = spec(0.02, 60.0, default=0.5, doc=(
        'limits are computed at every multiple of this in sample time (a whole number of '
        'model steps), from the state there, and published'))
    horizons_s: Tuple[float, ...] = spec(0.02, 86400.0, default=(10.0, 60.0, 600.0), doc=(
        'each limit keeps every limited quantity below its limit for this long; the '
        'shortest is the binding limit, the one number a simple drive applies'))
    k_sigma: float = spec(0.0, 10.0, default=2.0, doc=(
        'the limits hold at the estimate plus this many times its 1-sigma uncertainty'))
    max_sigma_K: float = spec(0.0, 100.0, low_open=True, default=10.0, doc=(
        'a limited quantity more uncertain than this (1 sigma, K) at a tick: fallback'))
    fallback_current_A: float = spec(0.0, 1000.0, default=10.0, doc=(
        'the conservative limit (A RMS) published when the twin cannot be trusted: '
        'inputs stale, uncertainty above max_sigma_K, or the estimator behind'))
    max_age_s: float = spec(0.0, 60.0, low_open=True, default=1.5, doc=(
        'a tick whose limits are not computed this long (model time) after it is '
        'published as the fallback (the estimator is behind)'))

    def check(self, key: str) -> None:
        """Check the horizons increase and are whole periods."""
        h = self.horizons_s
        if not h or any(b <= a for a, b in zip(h, h[1:])):
            raise ConfigError(f'{key}.horizons_s = {list(h)!r}: give one or more, increasing')
        for v in h:
            if abs(v / self.period_s - round(v / self.period_s)) > 1e-9 or v < self.period_s:
                raise ConfigError(f'{key}.horizons_s: {v!r} is not a whole number of '
                                  f'period_s = {self.period_s!r}')


@dataclass(frozen=True, kw_only=True)
class EstimatorSettings:
    """The live estimator: model step, averaging, fallbacks, forecast, uncertainty, alerts."""

    step_s: float = spec(0.001, 1.0, doc='model step in sample time')
    block_rate_Hz: float = spec(1.0, 5000.0, doc='grid on which samples are averaged per step')
    ambient_C: float = spec(-60.0, 150.0, doc='used until an ambient temperature arrives')
    coefficient_filter_s: float = spec(0.0, 600.0, doc=(
        "the speed, oil flow and temperatures that set the motor's coefficients pass two "
        'low-pass stages of this time constant; the losses do not'))
    model_uncertainty_K: float = spec(0.0, 50.0, doc=(
        "1 sigma (K) of every temperature when the live correction's filter starts; also "
        'of every open-loop estimate when the configuration has no uncertainty section '
        '(with one, it is propagated: docs/model.md, Uncertainty)'))
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
    limits: CurrentLimitSettings = spec(default_factory=CurrentLimitSettings, doc=(
        'the thermal current limits for the drive'))


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
    uncertainty: Optional[Uncertainty] = spec(default=None, doc=(
        'the stated 1 sigma of the uncertain parameters, propagated to every estimate; '
        'null: the constant estimator.model_uncertainty_K'))

    def check(self, key: str) -> None:
        """Check the calibration bounds and the uncertain parameters name model parameters."""
        self._check_uncertainty()
        for name, (low, high) in self.calibration.bounds.items():
            where = f'calibration.bounds.{name}'
            meta = model_parameter(name, where)
            for value in (low, high):
                check_value(where, value, float, meta)    # a bound the key itself allows
            nominal = config_value(self, name)
            if not low <= nominal <= high:
                raise ConfigError(f'{where} = [{low!r}, {high!r}]: does not hold the configured '
                                  f'value {name} = {nominal!r}')

    def _check_uncertainty(self) -> None:
        """Check each uncertain key names a model parameter, and the period fits the steps."""
        u = self.uncertainty
        if u is None:
            return
        for name, p in u.parameters.items():
            where = f'uncertainty.parameters.{name}'
            model_parameter(name, where)
            nominal = config_value(self, name)
            if p.relative_sigma is not None and nominal == 0.0:
                raise ConfigError(f'{where}.relative_sigma: {name} = 0, so a relative sigma '
                                  'is zero; give sigma in its unit instead')
        per_step = u.copy_period_s / self.estimator.step_s
        if abs(per_step - round(per_step)) > 1e-9 * per_step:
            raise ConfigError(f'uncertainty.copy_period_s = {u.copy_period_s!r}: not a whole '
                              f'number of estimator.step_s = {self.estimator.step_s!r}')


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
