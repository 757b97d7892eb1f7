"""What a calibration found: each parameter, each log's runs and errors, and their record."""

from dataclasses import dataclass, field
import datetime
import math
from typing import Dict, List, Optional, Tuple

import numpy as np

from .evaluator import Windows
from .logs import LogData
from ..config import CalibrationResult, Config, from_dict


@dataclass
class ParameterFit:
    """One parameter: bounds, nominal and fitted value, interval, identifiability."""

    key: str
    low: float
    high: float
    nominal: float
    value: float
    ci95: Optional[Tuple[float, float]] = None   # statistical, widened by the step shift
    identifiable: bool = True
    note: str = ''
    effect_K: float = math.nan          # largest RMS change of a reading across the bounds
    collinearity: float = math.nan      # 1 / sine of its effect's angle to the others'
    step_shift: float = 0.0             # the change a finer step implies (linearised)

    @property
    def span(self) -> float:
        """Return the width of the bounds."""
        return self.high - self.low

    def record(self) -> dict:
        """Return the configuration's record of this parameter (a CalibratedParameter)."""
        low, high = self.ci95 if self.ci95 is not None else (None, None)
        return {'key': self.key, 'nominal': self.nominal, 'value': self.value,
                'ci95_low': low, 'ci95_high': high, 'identifiable': self.identifiable,
                'step_shift': self.step_shift, 'note': self.note}


@dataclass
class LogFit:
    """One log's model runs (nominal, calibrated) and errors against its thermocouples."""

    log: LogData
    role: str                                  # 'fit' or 'validate'
    t_model: np.ndarray
    nominal_C: np.ndarray                      # lagged model, one row per step
    calibrated_C: np.ndarray
    windows: Windows
    start_offset_before_K: float = 0.0         # fitted to the starting temperature
    start_offset_after_K: float = 0.0
    before: Dict[str, dict] = field(default_factory=dict)
    after: Dict[str, dict] = field(default_factory=dict)


@dataclass
class CalibrationRun:
    """Everything a calibration found, for the report and the calibrated configuration."""

    base_cfg: Config
    config_source: str
    parameters: List[ParameterFit]
    logs: List[LogFit]
    calibrated_cfg: Config
    evaluations: int = 0                       # model runs of whole logs
    iterations: int = 0
    fit_s: float = 0.0
    read_s: float = 0.0
    rms_before_K: float = math.nan             # fit logs, window means, all channels
    rms_after_K: float = math.nan
    n_eff: float = math.nan
    n_residuals: int = 0
    messages: List[str] = field(default_factory=list)

    @property
    def fitted(self) -> List[ParameterFit]:
        """Return the parameters that were fitted."""
        return [p for p in self.parameters if p.identifiable]


def result_record(run: CalibrationRun) -> CalibrationResult:
    """Return the record of a calibration for the calibrated configuration, validated."""
    logs = [{'path': log_fit.log.path or log_fit.log.name, 'role': log_fit.role,
             'size_bytes': int(log_fit.log.size_bytes), 'sha256': log_fit.log.sha256,
             'duration_s': round(float(log_fit.log.duration_s), 3)} for log_fit in run.logs]
    record = {
        'created_utc': datetime.datetime.now(datetime.timezone.utc).isoformat(
            timespec='seconds'),
        'base_config': run.config_source, 'step_s': run.base_cfg.calibration.step_s,
        'parameters': [plain(p.record()) for p in run.parameters], 'logs': logs,
        'fit_rms_before_K': round(run.rms_before_K, 4),
        'fit_rms_after_K': round(run.rms_after_K, 4)}
    return from_dict(CalibrationResult, record, 'calibration.result')


def plain(x):
    """Return ``x`` with numpy scalars as Python numbers, tuples as lists (for YAML)."""
    if isinstance(x, dict):
        return {k: plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [plain(v) for v in x]
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return float(x)
    return x
