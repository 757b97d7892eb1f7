"""
A replay's report: ``report.md`` and its plots, and the thermocouples' error figures.

The plots (inputs, temperatures with their thermocouples and limits, errors,
alert level, current limits) are PNGs beside ``report.md``, which links them.
"""

import math
from pathlib import Path
from typing import Dict, List, Optional, Tuple

import numpy as np

from .run import OUTPUT_ESTIMATES, ReplayResult
from ... import interface
from ...model import quantity_table
from ...output_files import markdown_table, pyplot, save_figure, write_text


def thermocouple_errors(result: ReplayResult) -> Dict[str, dict]:
    """
    Return, per thermocouple, the error of its estimate (estimate - measured, K).

    The estimate is interpolated at the thermocouple's stamps inside the
    estimated span: max abs, RMS, bias (mean) and the count compared.
    """
    out = {}
    for tc, (t, v) in result.measured.items():
        est = result.temperatures_C[interface.THERMOCOUPLES[tc]]
        inside = (t >= result.stamp_s[0]) & (t <= result.stamp_s[-1])
        if not np.any(inside):
            continue
        err = np.interp(t[inside], result.stamp_s, est) - v[inside]
        out[tc] = {'estimate': interface.THERMOCOUPLES[tc], **error_stats(err),
                   't_s': t[inside], 'error_K': err}
    return out


def error_stats(err: np.ndarray) -> Dict[str, float]:
    """Return the count, max abs, RMS and bias (mean) of errors (K); NaN for none."""
    if not err.size:
        return {'n': 0, 'max_abs_K': math.nan, 'rms_K': math.nan, 'bias_K': math.nan}
    return {'n': int(err.size), 'max_abs_K': float(np.max(np.abs(err))),
            'rms_K': float(np.sqrt(np.mean(err ** 2))), 'bias_K': float(np.mean(err))}


def write_report(result: ReplayResult, out_dir: Path) -> Path:
    """Write the PNG plots (inputs, temperatures, errors, alerts, limits) and report.md."""
    out_dir.mkdir(parents=True, exist_ok=True)
    errors = thermocouple_errors(result)
    images = _write_plots(result, errors, out_dir)
    lines = _summary_lines(result) + _temperature_lines(result) + _error_lines(errors) \
        + _health_lines(result) + _correction_lines(result.correction) + _limits_lines(result)
    lines += [''] + [f'![{p.stem}]({p.name})' for p in images]
    return write_text(out_dir / 'report.md', '\n'.join(lines) + '\n')


def _write_plots(result: ReplayResult, errors: Dict[str, dict], out_dir: Path) -> List[Path]:
    """Write the report's PNGs (errors.png with thermocouples, limits.png with limits)."""
    plt = pyplot()

    t0 = float(result.stamp_s[0])
    t_min = (result.stamp_s - t0) / 60.0
    images = [save_figure(_plot_inputs(plt, result, t0), out_dir / 'inputs.png'),
              save_figure(_plot_temperatures(plt, result, t0, t_min),
                          out_dir / 'temperatures.png')]
    if errors:
        images.append(save_figure(_plot_errors(plt, errors, t0), out_dir / 'errors.png'))
    images.append(save_figure(_plot_alerts(plt, result, t_min), out_dir / 'alerts.png'))
    if result.current_limits:
        images.append(save_figure(_plot_limits(plt, result, t0), out_dir / 'limits.png'))
    return images


def _plot_inputs(plt, result: ReplayResult, t0: float):
    """Return the figure of the inputs as replayed, one panel each."""
    fig, axes = plt.subplots(len(result.inputs), 1, figsize=(10, 1.8 * len(result.inputs) + 1),
                             sharex=True, squeeze=False)
    for ax, (name, (t, v)) in zip(axes[:, 0], result.inputs.items()):
        ax.plot((t - t0) / 60.0, v, lw=0.6)
        ax.set_ylabel(name, fontsize=8)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel('time since the first estimate [min]')
    fig.suptitle(f'inputs of {result.plan.info.path.name}')
    return fig


#: The estimates the temperature figure always shows (besides those a thermocouple measures)
PLOTTED_ESTIMATES = ('winding_hotspot', 'winding_mean', 'magnet', 'frame', 'pump_case', 'oil')


def _plot_temperatures(plt, result: ReplayResult, t0: float, t_min: np.ndarray):
    """
    Return a small multiple of the estimates: one panel each, sharing the time axis.

    A panel shows an estimate (line), the thermocouples that measure it (dots)
    and its limit (dashed) when the limit is within reach of the data; a
    limit out of reach is named in the panel's title instead.
    """
    measures = {}
    for tc, estimate in interface.THERMOCOUPLES.items():
        if tc in result.measured and result.measured[tc][0].size:
            measures.setdefault(estimate, []).append(tc)
    names = [n for n in OUTPUT_ESTIMATES if n in PLOTTED_ESTIMATES or n in measures]
    rows = math.ceil(len(names) / 2)
    fig, axes = plt.subplots(rows, 2, figsize=(10, 1.9 * rows + 0.6), sharex=True,
                             squeeze=False)
    limits = quantity_table.limits_C(result.plan.cfg)
    for ax, name in zip(axes.flat, names):
        estimate = result.temperatures_C[name]
        # the line over the dots: ten readings a second would hide it
        ax.plot(t_min, estimate, color='C0', lw=1.5, label='estimate', zorder=3)
        top = float(np.max(estimate))
        for tc in measures.get(name, []):
            t, v = result.measured[tc]
            ax.plot((t - t0) / 60.0, v, '.', color='C3', ms=1.5, alpha=0.6, label='thermocouple')
            top = max(top, float(np.max(v)))
        title = quantity_table.label(name)
        if name in measures:
            title += f' (thermocouple {", ".join(measures[name])})'
        if name in limits:
            value = limits[name]
            if value < 1.3 * top:
                ax.axhline(value, ls='--', lw=1.0, color='grey',
                           label=quantity_table.LIMIT_LABELS[name])
            else:
                title += f'; {quantity_table.LIMIT_LABELS[name]} {value:g} degC, off the scale'
        ax.set_title(title, fontsize=9, loc='left')
        ax.set_ylabel('degC', fontsize=8)
        ax.tick_params(labelsize=8)
        ax.grid(alpha=0.3)
    for ax in axes.flat[len(names):]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel('time since the first estimate [min]', fontsize=8)
    # one key for all panels, in the first that has every kind of line it needs
    keyed = next((ax for ax, n in zip(axes.flat, names) if n in measures), axes[0, 0])
    keyed.legend(fontsize=7, loc='best')
    return fig


def _plot_errors(plt, errors: Dict[str, dict], t0: float):
    """Return the figure of each thermocouple's estimate minus its readings."""
    fig, ax = plt.subplots(figsize=(10, 4))
    for tc, e in errors.items():
        ax.plot((e['t_s'] - t0) / 60.0, e['error_K'], lw=0.8,
                label=f'{e["estimate"]} - {tc}')
    ax.axhline(0.0, color='k', lw=0.5)
    ax.set_xlabel('time [min]')
    ax.set_ylabel('estimate - thermocouple [K]')
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    return fig


def _plot_alerts(plt, result: ReplayResult, t_min: np.ndarray):
    """Return the figure of the alert level over time."""
    fig, ax = plt.subplots(figsize=(10, 2.2))
    ax.step(t_min, result.alert_level, where='post')
    ax.set_yticks([0, 1, 2], ['OK', 'WARN', 'CRITICAL'])
    ax.set_xlabel('time [min]')
    ax.set_title('alert level')
    ax.grid(alpha=0.3)
    return fig


def _limit_table(result: ReplayResult) -> tuple:
    """Return the ticks' stamps (s), limits (A, ticks x limits) and fallback flags."""
    lims = result.current_limits
    return (np.array([lim.stamp_s for lim in lims]), np.array([lim.limits_A for lim in lims]),
            np.array([lim.status != 'ok' for lim in lims]))


def _runs(flags: np.ndarray) -> List[Tuple[int, int]]:
    """Return the [start, stop) index ranges where ``flags`` holds."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], flags.astype(np.int8), [0]])))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def _plot_limits(plt, result: ReplayResult, t0: float):
    """
    Return the figure of the current limits over time, with the RMS current of the log.

    Each tick's limits hold until the next tick (steps); the binding one (the
    shortest horizon's) is thick, the fallback periods are shaded, and the
    RMS current of each period is drawn over them: where it rises above the
    binding limit, a drive applying that limit would have clamped it.
    """
    stamps, values, fallback = _limit_table(result)
    first = result.current_limits[0]
    period = result.plan.cfg.estimator.limits.period_s
    # each tick's limits (and the current under them) hold until the next: the last too
    t = (np.append(stamps, stamps[-1] + result.limits_held_s[-1]) - t0) / 60.0
    values = np.vstack([values, values[-1]])
    current = np.append(result.limits_current_A, result.limits_current_A[-1])
    fig, ax = plt.subplots(figsize=(10, 3.8))
    binding = int(np.argmin(first.horizons_s))
    others = iter(('C0', 'C2', 'C4', 'C1', 'C5', 'C6'))     # red is the binding one's
    for k, name in enumerate(first.names):
        if k == binding:
            # under the others: a limit equal to it (at the rating) stays visible on it
            style = {'color': 'C3', 'lw': 2.2, 'label': f'{name} (binding)', 'zorder': 1.5}
        elif math.isinf(first.horizons_s[k]):
            style = {'color': 'grey', 'lw': 1.0, 'ls': '--', 'label': name}
        else:
            style = {'color': next(others, 'C7'), 'lw': 1.0, 'label': name}
        ax.step(t, values[:, k], where='post', **style)
    ax.step(t, current, where='post', color='k', lw=0.8,
            label=f'RMS current over each {period:g} s', zorder=4)
    for k, (lo, hi) in enumerate(_runs(fallback)):
        ax.axvspan(t[lo], t[hi], color='orange', alpha=0.25, lw=0,
                   label='fallback' if k == 0 else None)
    ax.set_ylim(bottom=0.0)
    ax.set_xlabel('time since the first estimate [min]')
    ax.set_ylabel('A RMS')
    ax.set_title('current limits for the drive', fontsize=10, loc='left')
    ax.legend(fontsize=7, loc='upper left', bbox_to_anchor=(1.01, 1.0))
    ax.grid(alpha=0.3)
    return fig


def _limits_lines(result: ReplayResult) -> List[str]:
    """
    Return the report's section on the current limits for the drive.

    Per limit its lowest value, when, what bound it, and how long the RMS
    current (per tick period) was above it; the time on the fallback and why.
    Times are those the limits held (:attr:`ReplayResult.limits_held_s`).
    """
    lines = ['', '## Current limits for the drive', '']
    if not result.outlook:
        return lines + ['Not computed (`--no-outlook`).']
    if not result.current_limits:
        return lines + ['The log ends before the first limit tick.']
    lim_cfg = result.plan.cfg.estimator.limits
    stamps, values, fallback = _limit_table(result)
    t0 = float(result.stamp_s[0])
    first = result.current_limits[0]
    binding = int(np.argmin(first.horizons_s))
    lines += [f'{len(stamps)} ticks, one every {lim_cfg.period_s:g} s of sample time, each at '
              f'the estimate + {lim_cfg.k_sigma:g} sigma, as the live estimator publishes them '
              f'on `{interface.CURRENT_LIMITS_TOPIC}` (all in `limits.csv`). "Current above": '
              f'the time the RMS current over a tick period exceeded the limit of its tick; '
              f'above the binding ({first.names[binding]}) limit, a drive applying it would '
              f'have clamped the current.', '']
    held = result.limits_held_s
    rows = []
    for k, name in enumerate(first.names):
        i = int(np.argmin(values[:, k]))
        with np.errstate(invalid='ignore'):
            above = result.limits_current_A > values[:, k]
        rows.append((name + (' (binding)' if k == binding else ''), f'{values[i, k]:.2f}',
                     f'{stamps[i] - t0:.1f}', result.current_limits[i].binds[k],
                     f'{held[above].sum():.1f}'))
    lines += markdown_table(('limit', 'lowest (A RMS)', 'at (s)', 'bound by',
                             'current above (s)'), rows)
    lines += ['', f'On the fallback ({lim_cfg.fallback_current_A:g} A at most): '
              f'{held[fallback].sum():.1f} s of {held.sum():.1f} s.']
    causes: Dict[str, List[int]] = {}
    for k in np.flatnonzero(fallback).tolist():
        causes.setdefault(interface.limits_cause(result.current_limits[k].code), []).append(k)
    if causes:
        lines += [''] + markdown_table(
            ('cause', 'time (s)', 'first at (s)', 'first reason'),
            ((cause, f'{held[ks].sum():.1f}', f'{stamps[ks[0]] - t0:.1f}',
              result.current_limits[ks[0]].reason) for cause, ks in causes.items()))
    if math.isfinite(result.forecast_stamp_s[-1]):
        horizon = result.plan.cfg.estimator.forecast_horizon_s
        reach = ', '.join(f'{q} beyond {horizon:g} s' if math.isinf(v[-1])
                          else f'{q} {v[-1]:.0f} s' for q, v in result.time_to_limit_s.items())
        lines += ['', f'The last forecast (from {result.forecast_stamp_s[-1] - t0:.1f} s, the '
                  f'recent duty repeated) reaches each limit after: {reach}.']
    return lines


def _summary_lines(result: ReplayResult) -> List[str]:
    """Return the report's title and what was replayed, how fast."""
    lines = [f'# Replay of {result.plan.info.path.name}', '',
             f'- configuration: {result.plan.config_source}',
             '- inputs: ' + ', '.join(f'{n} <- {t}' for n, t in result.plan.inputs.items()),
             f'- on fallback all along (no topic): {", ".join(result.plan.missing) or "none"}',
             f'- {result.messages} messages, {result.steps} model steps, '
             f'{result.sample_time_s:.1f} s of sample time in {result.wall_s:.1f} s '
             f'({result.speed_x:.0f}x real time)']
    if result.truncated:
        lines.append(f'- **the bag is truncated**: replayed what could be read ({result.problem})')
    return lines


def _temperature_lines(result: ReplayResult) -> List[str]:
    """Return the report's table of the estimates at the end and at their peak."""
    return ['', '## Temperatures at the end and at their peak (degC)', ''] + markdown_table(
        ('estimate', 'end', 'peak'),
        ((n, f'{v[-1]:.1f}', f'{np.max(v):.1f}') for n, v in result.temperatures_C.items()))


def _error_lines(errors: Dict[str, dict]) -> List[str]:
    """Return the report's table of estimate minus thermocouple."""
    lines = ['', '## Estimate minus thermocouple (K)', '']
    if not errors:
        return lines + ['The bag holds no thermocouple topics.']
    return lines + markdown_table(
        ('thermocouple', 'estimate', 'samples', 'max abs', 'RMS', 'bias'),
        ((tc, e['estimate'], e['n'], f'{e["max_abs_K"]:.2f}', f'{e["rms_K"]:.2f}',
          f'{e["bias_K"]:+.2f}') for tc, e in errors.items()))


def _health_lines(result: ReplayResult) -> List[str]:
    """Return the report's alerts, input health and implausible steps."""
    t0 = float(result.stamp_s[0])
    lines = ['', '## Alerts', '']
    lines += [f'- {s - t0:9.1f} s: {text}' for s, text in result.alert_events] or ['- none']
    lines += ['', '## Input health', '']
    lines += markdown_table(
        ('input', 'received', 'accepted', 'rejected'),
        ((name, h['received'], h['accepted'],
          h['non_finite'] + h['out_of_range'] + h['backwards'] + h['late'])
         for name, h in result.health.items()))
    implausible = ', '.join(f'{k} {v}' for k, v in result.implausible.items())
    return lines + ['', f'Implausible steps: {implausible}']


def _correction_lines(c: Optional[dict]) -> List[str]:
    """Return the report's section on the live correction (the session's summary of it)."""
    lines = ['', '## Live correction', '']
    if c is None:
        return lines + ['Off (`--open-loop`, or estimator.correction.enabled: false): the '
                        'estimates are open loop.']
    if not c['active']:
        return lines + ['On, but no thermocouple reading was usable: the estimates are open '
                        'loop.']
    heats = ', '.join(f'{k} {v:.2f} W' for k, v in c['disturbance_W'].items()) or 'none'
    lines += [f'On: {c["updates"]} updates; learned heats at the end: {heats}. The errors '
              'above compare the corrected estimates with the thermocouples that '
              'corrected them.', '']
    return lines + markdown_table(
        ('thermocouple', 'status', 'received', 'used', 'gated', 'stale', 'dropped'),
        ((tc, h['status'], h['received'], h['used'], h['gated'], h['stale_events'],
          h['dropped_events']) for tc, h in c['thermocouples'].items()))
