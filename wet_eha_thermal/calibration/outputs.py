"""
The outputs of a calibration: ``calibrated.yaml``, ``report.md`` and a plot per log.

:func:`write_outputs` writes them atomically (:mod:`wet_eha_thermal.output_files`),
the configuration last.
"""

import dataclasses
import math
from pathlib import Path
from typing import List, Sequence

from .evaluator import window_means
from .logs import CHANNELS
from .results import CalibrationRun, LogFit, plain
from ..config import Config, config_from_yaml, ConfigError
from ..output_files import markdown_table, pyplot, save_figure, write_text

#: Name of the calibrated configuration in the output folder.
CALIBRATED_YAML = 'calibrated.yaml'


def config_yaml(cfg: Config, header: str = '') -> str:
    """Return ``cfg`` as YAML that :func:`~wet_eha_thermal.config.load_config` reads back equal."""
    import yaml

    text = yaml.safe_dump(plain(dataclasses.asdict(cfg)), sort_keys=False,
                          default_flow_style=None, width=99)
    back = config_from_yaml(text, 'the calibrated configuration')
    if back != cfg:
        raise ConfigError('the calibrated configuration does not read back as written')
    lines = ''.join(f'# {line}'.rstrip() + '\n' for line in header.splitlines())
    return lines + text


def write_outputs(run: CalibrationRun, out_dir: Path, command: str = '') -> List[Path]:
    """
    Write the plots, ``report.md`` and ``calibrated.yaml`` (last); return their paths.

    Every file is written under a ``.partial`` name and renamed when complete;
    the report and the configuration of an earlier run are removed first, so a
    folder with ``calibrated.yaml`` holds one complete calibration.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    for name in (CALIBRATED_YAML, 'report.md'):
        (out_dir / name).unlink(missing_ok=True)
    images = write_plots(run, out_dir)
    report = write_text(out_dir / 'report.md', report_text(run, images, command))
    fitted = ', '.join(f'{p.key} = {p.value:.6g}' for p in run.fitted) or 'nothing'
    created = run.calibrated_cfg.calibration.result.created_utc
    header = (f'Calibrated by wet-eha-thermal calibrate, {created}\nfrom {run.config_source}.'
              f'\nFitted: {fitted}.\n'
              'calibration.result records each fitted value with its 95 % interval, what was '
              'not identifiable,\nand the logs used. Load it as any configuration (--config).')
    if command:
        header += f'\nCommand: {command}'
    path = write_text(out_dir / CALIBRATED_YAML, config_yaml(run.calibrated_cfg, header))
    return images + [report, path]


def _stem(run: CalibrationRun, k: int) -> str:
    names = [Path(log_fit.log.name).stem for log_fit in run.logs]
    stem = names[k]
    return stem if names.count(stem) == 1 else f'{k + 1}_{stem}'


def write_plots(run: CalibrationRun, out_dir: Path) -> List[Path]:
    """Write one PNG per log: measured, nominal and calibrated per thermocouple, and errors."""
    plt = pyplot()

    images = []
    for k, log_fit in enumerate(run.logs):
        w = log_fit.windows
        n = len(w.channels)
        fig, axes = plt.subplots(n, 2, figsize=(12, 1.9 * n + 1.0), sharex=True, squeeze=False)
        t0 = log_fit.t_model[0]
        centres = 0.5 * (w.edges[1:] + w.edges[:-1])
        nom = window_means(w, log_fit.t_model, log_fit.nominal_C)
        cal = window_means(w, log_fit.t_model, log_fit.calibrated_C)
        for row, (c, idx, meas) in enumerate(zip(w.channels, w.index, w.measured)):
            col = CHANNELS.index(c)
            tm = (centres[idx] - t0) / 60.0
            ax = axes[row, 0]
            ax.plot(tm, meas, '.', ms=2.5, color='k', label='thermocouple')
            ax.plot((log_fit.t_model - t0) / 60.0, log_fit.nominal_C[:, col], lw=0.9,
                    color='tab:blue', label='nominal')
            ax.plot((log_fit.t_model - t0) / 60.0, log_fit.calibrated_C[:, col], lw=0.9,
                    color='tab:red', label='calibrated')
            ax.set_ylabel(f'{c}\n[degC]', fontsize=8)
            ax.grid(alpha=0.3)
            ax = axes[row, 1]
            ax.plot(tm, nom[c] - meas, lw=0.9, color='tab:blue', label='nominal')
            ax.plot(tm, cal[c] - meas, lw=0.9, color='tab:red', label='calibrated')
            ax.axhline(0.0, color='k', lw=0.5)
            ax.set_ylabel('model - tc [K]', fontsize=8)
            ax.grid(alpha=0.3)
        axes[0, 0].legend(fontsize=7)
        axes[0, 1].legend(fontsize=7)
        axes[-1, 0].set_xlabel('time [min]')
        axes[-1, 1].set_xlabel('time [min]')
        fig.suptitle(f'{log_fit.log.name} ({"fit" if log_fit.role == "fit" else "held out"}): '
                     f'{run.base_cfg.calibration.residual_interval_s:g} s means')
        images.append(save_figure(fig, out_dir / f'{_stem(run, k)}.png'))
    return images


def _fmt(x: float, digits: int = 4) -> str:
    return f'{x:.{digits}g}' if math.isfinite(x) else '-'


def error_table(log_fit: LogFit) -> List[str]:
    """Return a markdown table of a log's errors per thermocouple, before and after."""
    def row(c: str) -> tuple:
        before, after = log_fit.before[c], log_fit.after[c]
        return (c, before['estimate'], f'{before["max_abs_K"]:.2f}', f'{before["rms_K"]:.2f}',
                f'{before["bias_K"]:+.2f}', f'{after["max_abs_K"]:.2f}',
                f'{after["rms_K"]:.2f}', f'{after["bias_K"]:+.2f}',
                f'{after["max_abs_raw_K"]:.2f}')

    return markdown_table(('thermocouple', 'estimate', 'before: max abs', 'RMS', 'bias',
                           'after: max abs', 'RMS', 'bias', 'after, max abs of single readings'),
                          (row(c) for c in log_fit.windows.channels))


def summary_text(run: CalibrationRun, residual_interval_s: float) -> str:
    """Return the console summary: each parameter, each log's errors before and after, times."""
    lines = ['parameters: nominal -> calibrated [95 % interval]']
    for p in run.parameters:
        if p.identifiable:
            lines.append(f'  {p.key:<42} {p.nominal:<10.4g} -> {p.value:<10.4g} '
                         f'[{p.ci95[0]:.4g}, {p.ci95[1]:.4g}]{"  " + p.note if p.note else ""}')
        else:
            lines.append(f'  {p.key:<42} {p.nominal:<10.4g} held: not identifiable ({p.note})')
    for lf in run.logs:
        role = 'fit' if lf.role == 'fit' else 'held out'
        lines.append(f'{lf.log.name} ({role}): model - thermocouple, max abs over '
                     f'{residual_interval_s:g} s means, nominal -> calibrated (K)')
        lines.append('  ' + ', '.join(f'{c} {lf.before[c]["max_abs_K"]:.2f} -> '
                                      f'{lf.after[c]["max_abs_K"]:.2f}'
                                      for c in lf.windows.channels))
    return '\n'.join(lines)


def times_text(run: CalibrationRun, where: str) -> str:
    """Return the wall time line: reading, fit, model runs, and where they ran."""
    return (f'wall time: reading {run.read_s:.1f} s, fit {run.fit_s:.1f} s ({run.evaluations} '
            f'model runs of whole logs, {run.iterations} iterations, {where})')


def report_text(run: CalibrationRun, images: Sequence[Path], command: str = '') -> str:
    """Return report.md: parameters, identifiability, errors before and after, plots."""
    c = run.base_cfg.calibration
    lines = ['# Calibration of the thermal model', '']
    if command:
        lines += [f'Command: `{command}`', '']
    lines += [f'- base configuration: {run.config_source}',
              f'- model step {c.step_s:g} s on inputs averaged at {c.average_rate_Hz:g} Hz; '
              f'thermocouples compared as {c.residual_interval_s:g} s means, lag '
              f'{c.thermocouple_lag_s:g} s applied to the model',
              f'- {run.evaluations} model runs of whole logs, {run.iterations} iterations; '
              f'wall time: reading {run.read_s:.1f} s, fit {run.fit_s:.1f} s',
              f'- fit logs, all thermocouples: RMS error {run.rms_before_K:.3f} K nominal, '
              f'{run.rms_after_K:.3f} K calibrated; {run.n_residuals} residuals, '
              f'{run.n_eff:.0f} effectively independent', '']
    lines += markdown_table(
        ('log', 'role', 'duration', 'size', 'sha256', 'start (readings)', 'start offset fitted'),
        ((log_fit.log.path or log_fit.log.name, log_fit.role, f'{log_fit.log.duration_s:.0f} s',
          f'{log_fit.log.size_bytes} B', log_fit.log.sha256[:16] or '(in memory)',
          f'{log_fit.log.start_C:.2f} degC',
          f'{log_fit.start_offset_after_K:+.2f} K' if log_fit.role == 'fit' else '-')
         for log_fit in run.logs))
    lines += _parameters_section(run)
    if run.messages:
        lines += ['', '## Warnings', ''] + [f'- {m}' for m in run.messages]
    lines += _errors_sections(run)
    lines += ['', '## Plots', ''] + [f'![{p.stem}]({p.name})' for p in images]
    return '\n'.join(lines) + '\n'


def _parameters_section(run: CalibrationRun) -> List[str]:
    """Return the parameters section: the table, how identifiability and intervals are set."""
    c = run.base_cfg.calibration
    lines = ['', '## Parameters', ''] + markdown_table(
        ('key', 'bounds', 'nominal', 'calibrated', '95 % interval', 'step shift', 'identifiable',
         'largest effect across the bounds', 'collinearity index', 'note'),
        ((p.key, f'{p.low:.4g} .. {p.high:.4g}', f'{p.nominal:.4g}', f'{p.value:.4g}',
          f'{p.ci95[0]:.4g} .. {p.ci95[1]:.4g}' if p.ci95 else '-',
          f'{p.step_shift:+.3g}' if p.identifiable and c.check_step_s else '-',
          'yes' if p.identifiable else '**no**', f'{_fmt(p.effect_K, 3)} K',
          _fmt(p.collinearity, 3), p.note) for p in run.parameters))
    check = (f'plus the step shift: the change of the parameter that the fitted model run once '
             f'at a {c.check_step_s:g} s step implies (linearised), for the error of the fit '
             f'step itself' if c.check_step_s else 'no step check (check_step_s: 0): the '
             'intervals do not cover the error of the fit step itself')
    lines += ['', 'Identifiability: before the fit, a parameter is held at its nominal value '
              f'when moving it across its bounds changes no thermocouple by {c.min_effect_K:g} '
              'K RMS, or when its effect is nearly a combination of those of parameters with '
              f'larger effects (collinearity index above {c.max_collinearity:g}); after the '
              f'fit, when its 95 % interval spans more than {100 * c.max_ci_fraction:.0f} % of '
              'its bounds.', '',
              'Intervals: 1.96 sigma from s^2 (J^T J)^-1, s^2 the mean square of the weighted '
              'residuals, inflated by n / n_eff: the residuals are autocorrelated, and each '
              "series (a log's thermocouple) counts its length over its integrated "
              f"autocorrelation time; {check}. They assume the model's structure otherwise.",
              '', 'Assumptions: each log starts in thermal equilibrium at the median of its '
              "thermocouples' first readings; the fit also fits a uniform offset of that "
              'start for each fit log (a nuisance parameter, table above), while the errors '
              "below use the readings' start, as the estimator would; the ambient of each "
              'minute is the mean of its readings; the model runs open-loop.']
    return lines


def _errors_sections(run: CalibrationRun) -> List[str]:
    """Return the report's error tables, before and after, of the fit and the held-out logs."""
    c = run.base_cfg.calibration
    lines: List[str] = []
    for role, title in (('fit', 'Fit logs'), ('validate', 'Held-out logs')):
        chosen = [log_fit for log_fit in run.logs if log_fit.role == role]
        if not chosen:
            continue
        lines += ['', f'## {title}: model minus thermocouple (K), before (nominal) and after '
                  '(calibrated)', '',
                  f'Over {c.residual_interval_s:g} s means of the readings; the last column '
                  'compares every single reading (its noise included).']
        for log_fit in chosen:
            lines += ['', f'### {log_fit.log.name}', ''] + error_table(log_fit)
    return lines
