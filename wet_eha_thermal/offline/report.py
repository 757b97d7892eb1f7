"""
Report of a duty-cycle simulation: temperature table, limits, heat, CSV and PNG.

The job behind ``wet-eha-thermal simulate`` turns a
:class:`~wet_eha_thermal.simulation.SimulationResult` into a text table of
end and peak temperatures, the time each temperature limit is (or would be)
reached, where the motor's heat is made and where it goes, an energy check,
a CSV of every recorded history and a PNG plot.
"""

import csv
from dataclasses import dataclass
import math
from pathlib import Path
import re
from typing import Dict, List, Optional, Sequence, Tuple
import warnings

import numpy as np

from ..config import Config
from ..model import quantity_table
from ..model.motor import LOSS_NAMES
from ..model.quantities import OIL_OUTPUTS
from ..output_files import atomic, pyplot, save_figure
from ..units import C_TO_K

#: Temperatures of the table, in print order.
TABLE = ('winding_mean', 'winding_hotspot', 'frame', 'magnet', 'airgap_oil_outlet',
         'motor_oil_outlet', 'pump_case', 'pump_outlet', 'chamber_a', 'chamber_b',
         'accumulator')
#: Fraction of the recorded history, at its end, that the extrapolation fits.
FIT_FRACTION = 1.0 / 3.0
#: Peak-to-peak change (K) below which the fitted part of a history counts as flat.
FLAT_K = 1e-3
#: The motor's heat paths in a result's heat flows (W), with their printed names.
HEAT_PATHS = (('motor_bore', 'through the bore to the airgap oil'),
              ('motor_end_spaces', 'through the end spaces to their oil'),
              ('motor_to_ambient', 'frame and end caps to ambient'),
              ('motor_to_oil', 'carried off by the oil'))
#: Unit suffixes that a heat-flow key may already carry (otherwise it is in W).
_UNIT = re.compile(r'_(W|J|K|C|L_min|m3_s|Pa|MPa|kg_s)$')


@dataclass
class LimitCheck:
    """
    One temperature against its limit over a run (degC and s).

    ``time_to_limit_s`` is None when the limit is not reached; ``method`` is
    ``'in run'`` (crossed during the run), ``'extrapolated'`` (first-order
    fit), ``'extrapolated, linear'`` (the fit found no settling),
    ``'not reached'`` or ``'unknown'`` (history too short to fit).
    ``settles_C`` and ``tau_s`` are the fitted settling value and time
    constant when there is a first-order fit.
    """

    label: str
    limit_C: float
    end_C: float
    peak_C: float
    peak_time_s: float
    time_to_limit_s: Optional[float]
    method: str
    settles_C: Optional[float] = None
    tau_s: Optional[float] = None
    note: str = ''

    def describe(self) -> str:
        """Return the outcome as text: when the limit is reached, or where it settles."""
        fit = f'tau {self.tau_s:.0f} s' if self.tau_s is not None else ''
        if self.method == 'in run':
            text = f'reached at {_time_text(self.time_to_limit_s)} (in the run)'
        elif self.method == 'unknown':
            text = 'unknown (history too short to extrapolate)'
        elif self.time_to_limit_s is not None:
            extra = f'; settles at {self.settles_C:.1f} degC, {fit}' if fit else ''
            how = ('extrapolated' if self.method == 'extrapolated'
                   else 'extrapolated along a straight line: no settling seen yet')
            text = f'reached at about {_time_text(self.time_to_limit_s)}{extra} ({how})'
        elif self.settles_C is not None:
            extra = f', {fit}' if fit else ''
            text = f'not reached (settles at {self.settles_C:.1f} degC{extra}) (extrapolated)'
        else:
            text = 'not reached (not rising at the end of the run) (extrapolated)'
        return text + (f'; {self.note}' if self.note else '')


def _time_text(t_s: float) -> str:
    if t_s < 3600.0:
        return f'{t_s:.0f} s'
    return f'{t_s:.0f} s ({t_s / 3600.0:.1f} h)'


def _rise(x: np.ndarray, k: float) -> np.ndarray:
    """Return (1 - exp(-k x)) / k, and x itself at k = 0 (the linear limit)."""
    if abs(k) < 1e-12:
        return x
    return -np.expm1(-k * x) / k


def fit_first_order(t_s: Sequence[float], T: Sequence[float]
                    ) -> Optional[Tuple[float, float, float]]:
    """
    Fit T(t) = T_now + s (1 - exp(-k (t - t_now))) / k to a history; t_now = its last time.

    This is the first-order response T(t) = T_inf - (T_inf - T_now)
    exp(-(t - t_now)/tau) written with the slope ``s`` at ``t_now`` and the
    rate ``k = 1/tau``, so that ``k = 0`` is the straight line of slope
    ``s`` and the fit stays well posed when the history shows no bend yet.
    ``k`` is kept >= 0 (a rise that still accelerates is fitted by the
    straight line). Starting values come from a log-linear fit (dT/dt
    regressed on T, exact for a first-order response), refined by
    :func:`scipy.optimize.curve_fit`.

    :return: ``(T_now, s, k)`` (K or degC as given, per s, 1/s), or None if
        there are fewer than 3 points or the fit fails.
    """
    from scipy.optimize import curve_fit, OptimizeWarning

    t = np.asarray(t_s, dtype=float)
    y = np.asarray(T, dtype=float)
    if t.size < 3:
        return None
    t_now = float(t[-1])
    span = float(t[-1] - t[0])
    if not span > 0.0:
        return None
    dydt = np.gradient(y, t)
    b, a = np.polyfit(y, dydt, 1) if np.ptp(y) > 0.0 else (0.0, 0.0)
    k_max = 50.0 / span
    k0 = float(np.clip(-b, 0.0, k_max))
    s0 = float(a + b * y[-1]) if k0 > 0.0 else float(np.polyfit(t, y, 1)[0])

    def model(tt, y_now, s, k):
        return y_now + s * _rise(tt - t_now, k)

    scale = max(float(np.ptp(y)), 1e-6)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter('ignore', OptimizeWarning)  # no covariance: not needed
            p, _ = curve_fit(model, t, y, p0=(float(y[-1]), s0, k0),
                             bounds=([-np.inf, -np.inf, 0.0], [np.inf, np.inf, k_max]),
                             x_scale=(scale, scale / span, 1.0 / span), max_nfev=2000)
    except (RuntimeError, ValueError):
        return None
    if not np.all(np.isfinite(p)):
        return None
    return float(p[0]), float(p[1]), float(p[2])


def check_limit(label: str, t_s: Sequence[float], T_C: Sequence[float], limit_C: float,
                fit_fraction: float = FIT_FRACTION) -> LimitCheck:
    """
    Return end, peak and the time a history reaches ``limit_C``.

    If the history reaches the limit during the run, the time is the first
    crossing, interpolated linearly between the two recorded times around
    it (method ``'in run'``). Otherwise it is extrapolated from the last
    ``fit_fraction`` of the run (at least 3 records) by a first-order fit,
    T(t) = T_inf - (T_inf - T_now) exp(-(t - t_now)/tau), see
    :func:`fit_first_order`: when T_inf < limit the limit is not reached
    and the history settles at T_inf; otherwise the limit is reached at
    t_now + tau ln((T_inf - T_now)/(T_inf - limit)). A part that is flat
    (within :data:`FLAT_K`) settles at its last value; a fit without a bend
    (tau beyond 50 times the fitted span) gives the straight-line time
    (``'extrapolated, linear'``), or "not rising" when the line falls.
    The extrapolation assumes the duty goes on as at the end of the run and
    one dominant time constant; it is a guide, not a prediction.
    """
    t = np.asarray(t_s, dtype=float)
    y = np.asarray(T_C, dtype=float)
    if t.size == 0:
        raise ValueError(f'{label}: empty history')
    i_peak = int(np.argmax(y))
    base = {'label': label, 'limit_C': float(limit_C), 'end_C': float(y[-1]),
            'peak_C': float(y[i_peak]), 'peak_time_s': float(t[i_peak])}
    over = np.flatnonzero(y >= limit_C)
    if over.size:
        return LimitCheck(**base, time_to_limit_s=_first_crossing(t, y, limit_C, int(over[0])),
                          method='in run')
    return _extrapolated(base, t, y, limit_C, fit_fraction)


def _first_crossing(t: np.ndarray, y: np.ndarray, limit_C: float, i: int) -> float:
    """Return when ``y`` reaches ``limit_C``, first at sample ``i``: linear between i-1 and i."""
    if i == 0:
        return float(t[0])
    return float(t[i - 1] + (limit_C - y[i - 1]) / (y[i] - y[i - 1]) * (t[i] - t[i - 1]))


def _extrapolated(base: dict, t: np.ndarray, y: np.ndarray, limit_C: float,
                  fit_fraction: float) -> LimitCheck:
    """Return the check of a history below its limit, from its last part (:func:`check_limit`)."""
    start = t[0] + (1.0 - fit_fraction) * (t[-1] - t[0])
    sel = np.flatnonzero(t >= start)
    if sel.size < 3:
        sel = np.arange(max(0, t.size - 3), t.size)
    tw, yw = t[sel], y[sel]
    if tw.size >= 2 and np.ptp(yw) < FLAT_K:
        return LimitCheck(**base, time_to_limit_s=None, method='not reached',
                          settles_C=float(yw[-1]))
    fit = fit_first_order(tw, yw)
    if fit is None:
        return LimitCheck(**base, time_to_limit_s=None, method='unknown')
    y_now, s, k = fit
    t_now = float(tw[-1])
    span = float(tw[-1] - tw[0])
    if k * span < 0.02:
        # no bend in the fitted part (tau > 50 spans): straight line of slope s
        if s <= 0.0:
            return LimitCheck(**base, time_to_limit_s=None, method='not reached')
        t_hit = t_now + max(limit_C - y_now, 0.0) / s
        return LimitCheck(**base, time_to_limit_s=t_hit, method='extrapolated, linear')
    tau = 1.0 / k
    T_inf = y_now + s * tau
    run = float(t[-1] - t[0])
    note = 'settling uncertain (tau > 3x the run)' if tau > 3.0 * run else ''
    if T_inf < limit_C:
        return LimitCheck(**base, time_to_limit_s=None, method='not reached',
                          settles_C=T_inf, tau_s=tau, note=note)
    t_hit = t_now + tau * math.log(max(T_inf - y_now, 1e-12) / max(T_inf - limit_C, 1e-12))
    return LimitCheck(**base, time_to_limit_s=max(t_hit, t_now), method='extrapolated',
                      settles_C=T_inf, tau_s=tau, note=note)
    t_hit = t_now + tau * math.log(max(T_inf - y_now, 1e-12) / max(T_inf - limit_C, 1e-12))
    return LimitCheck(**base, time_to_limit_s=max(t_hit, t_now), method='extrapolated',
                      settles_C=T_inf, tau_s=tau, note=note)


def temperatures_C(result) -> Dict[str, np.ndarray]:
    """Return every recorded temperature history in degC."""
    return {k: np.asarray(v, dtype=float) - C_TO_K for k, v in result.temperatures_K.items()}


def hottest_oil_C(result) -> Tuple[np.ndarray, str]:
    """Return the hottest oil volume's temperature at each recorded time, and the end's node."""
    temps = temperatures_C(result)
    names = [n for n in OIL_OUTPUTS if n in temps]
    stack = np.vstack([temps[n] for n in names])
    return np.max(stack, axis=0), names[int(np.argmax(stack[:, -1]))]


def check_limits(result, cfg: Config) -> List[LimitCheck]:
    """Check the temperatures with a limit (:data:`~.quantity_table.LIMITED`) of a run."""
    temps = temperatures_C(result)
    temps['oil'], _ = hottest_oil_C(result)
    return [check_limit(quantity_table.label(name), result.time_s, temps[name], limit)
            for name, limit in quantity_table.limits_C(cfg).items()]


def format_table(result) -> str:
    """Return the end and peak temperature of every :data:`TABLE` node as fixed-width text."""
    temps = temperatures_C(result)
    t = np.asarray(result.time_s, dtype=float)
    head = f'{"temperature":<20} {"end":>6} {"peak":>6} {"peak at":>8}'
    lines = [head, f'{"":<20} {"degC":>6} {"degC":>6} {"s":>8}', '-' * len(head)]
    for name in TABLE:
        if name not in temps:
            continue
        v = temps[name]
        i = int(np.argmax(v))
        lines.append(f'{quantity_table.label(name):<20} {v[-1]:6.1f} {v[i]:6.1f} {t[i]:8.0f}')
    return '\n'.join(lines)


def format_limits(checks: List[LimitCheck]) -> str:
    """Return the limits block as a fixed-width table, one row per checked temperature."""
    width = max(18, max(len(c.label) for c in checks))
    head = (f'{"":<{width}} {"limit":>5} {"end":>6} {"peak":>6} {"peak at":>8}  '
            'limit reached')
    lines = [head, f'{"":<{width}} {"degC":>5} {"degC":>6} {"degC":>6} {"s":>8}',
             '-' * len(head)]
    for c in checks:
        lines.append(f'{c.label:<{width}} {c.limit_C:5.0f} {c.end_C:6.1f} {c.peak_C:6.1f} '
                     f'{c.peak_time_s:8.0f}  {c.describe()}')
    return '\n'.join(lines)


def energy_check(result) -> Dict[str, float]:
    """
    Return the run's energy balance (J).

    ``net_in`` = electrical input - load work, ``accounted`` = stored + to
    ambient, ``residual`` = their difference, ``relative`` = residual over
    ``|net_in|``.
    """
    e = result.model.energy()
    net_in = float(result.electrical_J - result.load_work_J)
    accounted = float(e['stored'] + e['to_ambient'])
    residual = net_in - accounted
    return {'electrical': float(result.electrical_J), 'load_work': float(result.load_work_J),
            'net_in': net_in, 'stored': float(e['stored']),
            'to_ambient': float(e['to_ambient']), 'accounted': accounted,
            'residual': residual,
            'relative': residual / abs(net_in) if net_in != 0.0 else math.nan}


def format_energy(e: Dict[str, float]) -> str:
    """Return the energy check as one line."""
    return (f'Energy: electrical in {e["electrical"]:.4g} J - load work {e["load_work"]:.4g} J '
            f'= {e["net_in"]:.4g} J; stored {e["stored"]:.4g} J + to ambient '
            f'{e["to_ambient"]:.4g} J = {e["accounted"]:.4g} J; residual '
            f'{e["residual"]:.3g} J ({e["relative"]:.2e} relative)')


def motor_heat_W(result,
                 period_s: Optional[float] = None) -> Tuple[Dict[str, float], Dict[str, float]]:
    """
    Return the motor's losses and heat paths (W): means over the run's last duty period.

    Over the last record when the period is unknown or spans one record.
    """
    t = np.asarray(result.time_s, dtype=float)
    n = _window(t, period_s)

    def mean(key):
        return float(np.mean(result.heat_W[key][-n:]))

    return ({k: mean(f'loss_{k}') for k in LOSS_NAMES},
            {k: mean(k) for k, _ in HEAT_PATHS})


def format_heat(result, period_s: Optional[float] = None) -> str:
    """Return where the motor's heat is made and where it goes, as fixed-width text."""
    losses, paths = motor_heat_W(result, period_s)
    total = sum(losses.values())
    lines = [f'{"motor loss":<28} {"W":>7} {"share":>6}']
    lines += [f'{quantity_table.LOSS_LABELS[k]:<28} {v:7.1f} {v / total:6.1%}'
              for k, v in losses.items() if v != 0.0]
    lines += [f'{"total":<28} {total:7.1f}', '', f'{"where it goes":<40} {"W":>7}']
    lines += [f'{label:<40} {paths[k]:7.1f}' for k, label in HEAT_PATHS]
    return '\n'.join(lines)


def format_summary(result, cfg: Config, period_s: Optional[float]) -> str:
    """Return what ``simulate`` prints of a run: temperatures, limits, heat paths, energy."""
    oil_lim, oil_src = quantity_table.limits_C(cfg)['oil'], quantity_table.LIMIT_KEYS['oil']
    _, hottest = hottest_oil_C(result)
    return '\n'.join([
        format_table(result),
        '\nLimits: first crossing in the run, else extrapolated by a first-order fit to the '
        'last third of the run',
        format_limits(check_limits(result, cfg)),
        f'(oil limit {oil_lim:g} degC from {oil_src}; hottest oil node at the end: '
        f'{hottest.replace("_", " ")})',
        '\nWhere the heat is made and where it goes, mean over the last duty period:',
        format_heat(result, period_s),
        '\n' + format_energy(energy_check(result))])


def heat_column(name: str) -> str:
    """Return the CSV column of a heat-flow key: the key with ``_W`` unless it has a unit."""
    return name if _UNIT.search(name) else f'{name}_W'


def write_csv(result, path: Path) -> List[str]:
    """Write time, every temperature (degC), input and heat flow per record; return the columns."""
    cols: Dict[str, Sequence[float]] = {'time_s': result.time_s}
    cols.update({f'{k}_C': v for k, v in temperatures_C(result).items()})
    cols.update(result.inputs)
    cols.update({heat_column(k): v for k, v in result.heat_W.items()})
    names = list(cols)
    with atomic(path) as tmp, open(tmp, 'w', newline='') as f:
        writer = csv.writer(f)
        writer.writerow(names)
        for i in range(len(result.time_s)):
            # a run stopped early may lack the inputs of its last row: leave those blank
            writer.writerow(['' if i >= len(cols[n]) else f'{float(cols[n][i]):.6g}'
                             if n == 'time_s' else round(float(cols[n][i]), 4) for n in names])
    return names


def _top(values) -> float:
    return float(np.max(values)) if values is not None and len(values) else 0.0


def _window(t: np.ndarray, period_s: Optional[float]) -> int:
    """Return how many records span one duty period (1 if unknown or at most one record)."""
    if period_s is None or not math.isfinite(period_s) or t.size < 2:
        return 1
    step = float(np.median(np.diff(t)))
    return max(1, min(int(round(period_s / step)), t.size)) if step > 0.0 else 1


def _moving_mean(v: np.ndarray, n: int) -> np.ndarray:
    """Return the trailing mean over ``n`` records (fewer at the start)."""
    if n <= 1:
        return v
    c = np.concatenate(([0.0], np.cumsum(v)))
    i = np.arange(1, v.size + 1)
    lo = np.maximum(i - n, 0)
    return (c[i] - c[lo]) / (i - lo)


def _plot_input(ax, x, raw, mean, color, label, n):
    """Plot an input: recorded values thin, the mean over one duty period thick."""
    x = x[:raw.size]   # a run stopped early may lack the inputs of its last row
    if n <= 1:
        return ax.plot(x, raw, color=color, lw=1.4, label=label)
    ax.plot(x, raw, color=color, lw=0.6, alpha=0.3)
    return ax.plot(x, mean, color=color, lw=1.8, label=f'{label}\n(mean over a duty period)')


def _plot_heat(ax_made, ax_goes, result, x, n) -> None:
    """Plot the motor's losses stacked and its heat paths, as means over ``n`` records."""
    heat = result.heat_W
    if 'loss_copper_slot' not in heat:
        return

    def series(key):
        return _moving_mean(np.asarray(heat[key], dtype=float), n)

    parts = [(quantity_table.LOSS_LABELS[k], series(f'loss_{k}')) for k in LOSS_NAMES]
    parts = [(label, v) for label, v in parts if np.any(v)]
    m = len(parts[0][1])
    ax_made.stackplot(x[:m], [v for _, v in parts], labels=[label for label, _ in parts],
                      alpha=0.85)
    ax_made.set_ylabel('motor losses (W)')
    for key, label in HEAT_PATHS:
        v = series(key)
        ax_goes.plot(x[:v.size], v, lw=1.5, label=label)
    ax_goes.set_ylabel("motor's heat goes (W)")
    for ax in (ax_made, ax_goes):
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc='upper left', bbox_to_anchor=(1.01, 1.0))


def _plot_temperature_panels(axes, x: np.ndarray, temps: Dict[str, np.ndarray],
                             cfg: Config) -> None:
    """Plot the motor's and the oil's temperatures, each with its limits within 30 K."""
    limits = quantity_table.limits_C(cfg)
    # per panel: the temperatures (colour, line style) and the limits (colour) drawn
    panels = (
        ('motor temperature (degC)',
         (('winding_hotspot', 'C3', '-'), ('winding_mean', 'C1', '-'), ('magnet', 'C4', '-'),
          ('frame', 'C7', '-')),
         (('winding_hotspot', 'C3'), ('magnet', 'C4'))),
        ('oil temperature (degC)',
         (('airgap_oil_outlet', 'C5', ':'), ('motor_oil_outlet', 'C0', '-'),
          ('pump_case', 'C2', '-'), ('chamber_a', 'C1', '-'), ('chamber_b', 'C6', '--'),
          ('accumulator', 'C9', '-')),
         (('oil', 'C2'),)),
    )
    for ax, (ylabel, series, limited) in zip(axes, panels):
        top = -math.inf
        for key, color, style in series:
            if key in temps:
                ax.plot(x, temps[key], style, color=color, lw=1.5,
                        label=quantity_table.label(key))
                top = max(top, float(np.max(temps[key])))
        for name, color in limited:
            value = limits[name]
            grade = f' ({cfg.fluid.grade})' if name == 'oil' else ''
            if value - top <= 30.0:
                ax.axhline(value, color=color, ls='--', lw=1.2, alpha=0.8,
                           label=f'{quantity_table.LIMIT_LABELS[name]}{grade} {value:g} degC')
        ax.set_ylabel(ylabel)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc='upper left', bbox_to_anchor=(1.01, 1.0))


def _plot_inputs_panel(ax, result, x: np.ndarray, n: int) -> None:
    """Plot the RMS current and, on a twin axis, the speed: as recorded and per period."""
    handles = []
    current = result.inputs.get('current_A_rms')
    if current is not None:
        current = np.asarray(current, dtype=float)
        handles += _plot_input(ax, x, current, np.sqrt(_moving_mean(current ** 2, n)), 'C3',
                               'current, RMS', n)
    ax.set_ylabel('current, RMS (A)', color='C3')
    ax.tick_params(axis='y', colors='C3')
    ax.set_ylim(0.0, 1.15 * max(_top(current), 1e-3))
    ax.grid(True, alpha=0.3)
    speed = result.inputs.get('speed_rpm')
    if speed is not None:
        speed = np.asarray(speed, dtype=float)
        ax2 = ax.twinx()
        handles += _plot_input(ax2, x, speed, _moving_mean(speed, n), 'C0', 'speed, mean |n|', n)
        ax2.set_ylabel('speed, mean |n| (r/min)', color='C0')
        ax2.tick_params(axis='y', colors='C0')
        ax2.set_ylim(0.0, 1.15 * max(_top(speed), 1.0))
    if handles:
        ax.legend(handles=handles, fontsize=8, loc='upper left', bbox_to_anchor=(1.09, 1.0))


def plot(result, cfg: Config, path: Path, title: str,
         period_s: Optional[float] = None) -> None:
    """
    Plot a run to a PNG in five panels sharing the time axis.

    Top: winding mean and hot-spot, magnet, frame; then oil temperatures;
    where the motor's heat is made (its losses, stacked) and where it goes
    (its paths), each as the mean over one duty period; bottom: RMS current
    and speed on twin axes, as recorded
    (over the last step before each recorded time) and, when the duty's
    ``period_s`` spans several records, their mean over one period. A
    limit is drawn as a dashed line where it is within 30 K of the panel's
    data.
    """
    plt = pyplot()

    temps = temperatures_C(result)
    t = np.asarray(result.time_s, dtype=float)
    scale, unit = (1.0, 's') if t[-1] <= 1200.0 else (60.0, 'min')
    x = t / scale
    fig, axes = plt.subplots(5, 1, figsize=(12, 16), sharex=True,
                             gridspec_kw={'height_ratios': (3, 3, 2, 2, 2)})
    _plot_temperature_panels(axes[:2], x, temps, cfg)
    n = _window(t, period_s)
    _plot_heat(axes[2], axes[3], result, x, n)
    _plot_inputs_panel(axes[4], result, x, n)
    axes[4].set_xlabel(f'time ({unit})')
    axes[4].set_xlim(0.0, x[-1])
    fig.suptitle(title, fontsize=10)
    save_figure(fig, path)
