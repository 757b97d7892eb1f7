"""
Calibration of the thermal model on bench logs: fit parameters to the thermocouples.

A log (a rosbag2-style MCAP holding the sensor topics and the thermocouples,
read as :mod:`wet_eha_thermal.offline.replay` reads it: the same topic mapping, the same stamps) is
read once. Its inputs are averaged onto a coarse grid (``calibration.
average_rate_Hz``: the current as the root of the mean of I^2, speed and
pressures as means, the position sampled at the end of each interval, as the
live estimator interpolates it), and kept in memory with the raw readings of
the thermocouples and the ambient. An evaluation of a parameter set then
reruns only the model: the real :class:`~wet_eha_thermal.estimator.core.Estimator`, the live
twin's code path, configured with those values by
:func:`~wet_eha_thermal.config.with_values`, at ``calibration.step_s`` with its averaging
grid on the pre-averaged samples, fed through ``add_many``/``advance``.

Assumptions, stated in the report too:

- a log starts in thermal equilibrium: every model temperature starts at the
  median over the thermocouples of their first readings (``START_WINDOW_S``);
  a warning names a log whose first readings spread by more than
  ``START_SPREAD_K``. The fit refines it: each fit log's start gets a uniform
  offset (within ``START_OFFSET_MAX_K``), a nuisance parameter eliminated by
  its linearised effect (one run started 1 K warmer), since 0.1 K on the start
  moved the fitted seal loss by 5 % in the tests. The errors reported use the
  readings' start, as the estimator would;
- the ambient of each minute is the mean of that minute's ambient readings
  (the configuration's ambient when the log has none);
- the thermocouples lag the temperature they measure by a first-order
  ``calibration.thermocouple_lag_s``, applied to the model before comparing;
- the model runs open-loop: a live correction (``estimator.correction``) is off.

Residuals: for every thermocouple, the model (at its step ends) and the
readings are averaged over windows of ``calibration.residual_interval_s``, and
their difference is divided by the standard error of the readings' mean
(sigma from the messages' variance, or ``calibration.thermocouple_sigma_K``
when it is 0). ``scipy.optimize.least_squares`` (trust region reflective,
within the bounds, ``x_scale='jac'``) fits the parameters, scaled to [0, 1]
over their bounds, with a forward-difference Jacobian whose columns, like the
logs, are evaluated in parallel worker processes (``jobs``; each worker
holding the pre-averaged logs), or on the workers of a Dask ``client`` (a
cluster; the logs are sent to each worker once). Either way the same numbers.

Identifiability, judged twice:

- before the fit, on the scaled Jacobian at the nominal values: a parameter
  whose move across its bounds changes no thermocouple by ``min_effect_K``
  (RMS over a log) is held, and so is one whose effect is, to within
  ``1 / max_collinearity`` (the sine of the angle), a combination of the
  effects of parameters with larger ones (greedy, largest effect first);
- after the fit, from its 95 % interval: wider than ``max_ci_fraction`` of
  its bounds, it is held and the others are fitted again.

A held parameter stays at its nominal value and is reported as not
identifiable: it is never fitted to noise.

Intervals: 1.96 sigma from the covariance s^2 (J^T J)^-1, s^2 the residuals'
mean square, inflated by n / n_eff. The residuals after a fit are model error
more than sensor noise and autocorrelated, so each series (a log's
thermocouple) counts n / tau independent samples, tau its integrated
autocorrelation time (:func:`effective_samples`). The error of the fit step
itself is estimated once (``calibration.check_step_s``): the fitted model
runs at that finer step, and the parameter shift it implies (one linearised
Gauss-Newton step) is reported and added to the interval's half-width. The
interval otherwise assumes the model's structure.

The modules follow the method: :mod:`.logs` reads a bag into memory,
:mod:`.evaluator` runs the model on a log and compares it with the
thermocouples, :mod:`.fit` chooses and fits the parameters
(:func:`calibrate`) on the least-squares problem of :mod:`.problem`,
:mod:`.results` holds what it found and :mod:`.outputs` writes the
calibrated configuration, the report and the plots.
"""

from .evaluator import (channel_errors, evaluate_run, Evaluator, lagged, make_windows,
                        residuals, run_config, simulate_log, window_means, Windows)
from .fit import calibrate, effective_samples, fit_keys, screen
from .logs import (CalibrationError, CHANNELS, InputAverager, load_log, log_from_rig,
                   LogBuilder, LogData, plan_log, read_log)
from .outputs import (CALIBRATED_YAML, config_yaml, error_table, report_text, summary_text,
                      times_text, write_outputs, write_plots)
from .results import CalibrationRun, LogFit, ParameterFit, result_record

__all__ = [
    'calibrate', 'CALIBRATED_YAML', 'CalibrationError', 'CalibrationRun', 'channel_errors',
    'CHANNELS', 'config_yaml', 'effective_samples', 'error_table', 'evaluate_run', 'Evaluator',
    'fit_keys', 'InputAverager', 'lagged', 'load_log', 'log_from_rig', 'LogBuilder', 'LogData',
    'LogFit', 'make_windows', 'ParameterFit', 'plan_log', 'read_log', 'report_text', 'residuals',
    'result_record', 'run_config', 'screen', 'simulate_log', 'summary_text', 'times_text',
    'window_means', 'Windows', 'write_outputs', 'write_plots',
]
