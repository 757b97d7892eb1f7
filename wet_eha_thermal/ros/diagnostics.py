"""
The estimator node's /diagnostics as data: pure functions of the session and node counters.

One :class:`Status` per concern, in the order the node publishes them: the
estimate, each input, the plausibility checks, and each thermocouple of the
live correction. :mod:`.estimator_node` turns them into
``diagnostic_msgs/DiagnosticStatus``; nothing here needs ROS, so the texts
can be checked on a session alone (:class:`~.EstimatorSession`).
"""

from dataclasses import dataclass
from typing import List, Mapping, Optional, Sequence, Tuple

import numpy as np
from wet_eha_thermal import interface
from wet_eha_thermal.estimator.core import Estimate
from wet_eha_thermal.estimator.limits import CurrentLimits
from wet_eha_thermal.estimator.session import EstimatorSession, SessionStatus
from wet_eha_thermal.model.quantity_table import LIMITED

# the levels of diagnostic_msgs/DiagnosticStatus
OK, WARN, ERROR, STALE = 0, 1, 2, 3


@dataclass(frozen=True)
class Status:
    """One diagnostic status: name (without the node's prefix), level, message, key-values."""

    name: str
    level: int
    message: str
    values: List[Tuple[str, object]]


@dataclass(frozen=True)
class NodeCounters:
    """What the node counts beside the estimator, at the moment of a report."""

    hardware_id: str
    published: int                  # estimates published
    callback_errors: Mapping[str, int]   # per input (or other callback) name
    waiting_for_clock: int          # samples received before the clock
    latency_ms: Sequence[float]     # closing sample received -> estimate published
    view: str                       # the Foxglove view's state in words


def fmt(value: Optional[float], spec: str = '.2f', none: str = 'pending') -> str:
    """Format ``value`` with ``spec``, or return ``none`` for None."""
    return none if value is None else format(value, spec)


def statuses(est: EstimatorSession, node: NodeCounters, now_s: float, topic_of: Mapping[str, str],
             new_rejected: Mapping[str, int], new_implausible: int) -> List[Status]:
    """
    Return every status of one report.

    ``topic_of`` maps each input and ``measured/<thermocouple>`` to its topic;
    ``new_rejected`` counts each input's samples rejected since the last
    report, ``new_implausible`` the implausible steps.
    """
    out = [estimate_status(est, est.status(), node)]
    out += [input_status(est, name, now_s, topic_of[name], new_rejected[name],
                         node.callback_errors.get(name, 0)) for name in est.inputs]
    out.append(plausibility_status(est, new_implausible))
    if est.correcting:
        out += [thermocouple_status(est, tc, topic_of[f'{interface.MEASURED_PREFIX}/{tc}'])
                for tc in interface.THERMOCOUPLES]
    return out


def estimate_status(est: EstimatorSession, st: SessionStatus, node: NodeCounters) -> Status:
    """Return the status of the estimate: alerts, fallbacks, the latest values, the counters."""
    latest = est.latest
    stale = st.stale
    values = [('hardware_id', node.hardware_id)]
    if latest is None:
        return Status('estimate', STALE,
                      'no estimate yet: waiting for the clock or the first step',
                      values + [('inputs on fallback', ', '.join(stale) or 'none')])
    alerts = st.alert_message
    level = st.alert_level        # OK/WARN/CRITICAL = OK/WARN/ERROR
    message = 'estimating' if alerts == 'OK' else alerts
    if stale:
        message += f'; on fallback: {", ".join(stale)}'
    if len(stale) == len(est.inputs):
        level = STALE
        message = 'every input stale (data gap): estimates run on held values; ' + alerts
    if st.model_error is not None:
        level = ERROR
        message = f'model step failed, republishing the last estimate: {st.model_error}'
    values += latest_values(latest)
    values += limit_values(st.limits)
    if node.latency_ms:
        lat = np.percentile(node.latency_ms, [50, 99])
        values.append(('step latency p50/p99/max [ms]',
                       f'{lat[0]:.2f}/{lat[1]:.2f}/{max(node.latency_ms):.2f} (last '
                       f'{len(node.latency_ms)} estimates; closing sample received -> '
                       'estimate published)'))
    for tc, name in interface.THERMOCOUPLES.items():
        if tc in est.measured_C:
            t_meas = est.measured_C[tc][1]
            values.append((f'measured {tc} [degC]',
                           f'{t_meas:.2f} (estimate {name} '
                           f'{latest.temperatures_C[name] - t_meas:+.2f} K)'))
    values += correction_values(est)
    return Status('estimate', level, message, values + counter_values(st, node))


def latest_values(latest: Estimate) -> List[Tuple[str, object]]:
    """Return the key-values of the latest estimate: temperatures, margin, times to limit."""
    sigma = max(latest.uncertainty_K.values()) if latest.uncertainty_K else None
    values = [('stamp [s]', f'{latest.stamp_s:.3f}'), ('step', latest.step)]
    values += [(f'{n} [degC]', fmt(latest.temperatures_C.get(n))) for n in interface.ESTIMATES]
    values.append(('uncertainty [K, 1 sigma]', fmt(sigma)))
    values.append(('margin_current [A RMS]', fmt(latest.margin_current_A, '.1f')))
    for q in LIMITED:
        ttl = latest.time_to_limit_s
        text = 'pending' if q not in ttl else (
            'beyond horizon' if ttl[q] is None else f'{ttl[q]:.0f}')
        values.append((f'time_to_limit {q} [s]', text))
        values.append((f'limit {q} [degC]', fmt(latest.limits_C.get(q), '.1f')))
    values.append(('forecast started at [s]', fmt(latest.forecast_stamp_s, '.3f')))
    return values


def counter_values(st: SessionStatus, node: NodeCounters) -> List[Tuple[str, object]]:
    """Return the key-values of the session's and the node's counters: gaps, jumps, errors."""
    gaps = st.gaps
    gap_text = f'{gaps.count}, longest {gaps.longest_s:.1f} s, total {gaps.total_s:.1f} s'
    if gaps.open_since_s is not None:
        gap_text = f'every input silent since {gaps.open_since_s:.3f} s; ' + gap_text
    jump = st.last_clock_jump
    return [('alerts', st.alert_message),
            ('data gaps (every input silent)', gap_text),
            ('held blocks (silences crossed)', st.held_blocks),
            ('clock jumps', st.clock_jumps if jump is None else
             f'{st.clock_jumps} (last from {jump[0]:.3f} s to {jump[1]:.3f} s)'),
            ('inputs on fallback', ', '.join(st.stale) or 'none'),
            ('estimates published', node.published),
            ('model errors', st.model_errors),
            ('forecast and limit failures', st.outlook_failures),
            ('limit ticks behind (fallback)', st.limit_ticks_behind),
            ('forecasts skipped (one under way)', st.forecasts_skipped),
            ('background errors', st.background_errors),
            ('callback errors', sum(node.callback_errors.values())),
            ('samples before the clock', node.waiting_for_clock),
            ('foxglove view', node.view)]


def limit_values(limits: Optional[CurrentLimits]) -> List[Tuple[str, object]]:
    """Return the estimate status's key-values of the latest current limits."""
    if limits is None:
        return [('current limit [A RMS]', 'pending')]
    out = [('current limit [A RMS]', f'{limits.binding_A:.1f}'),
           ('current limits status', limits.frame_id),
           ('current limits stamp [s]', f'{limits.stamp_s:.3f}')]
    for name, value, binds in zip(limits.names, limits.limits_A, limits.binds):
        out.append((f'current limit {name} [A RMS]', f'{value:.1f} ({binds})'))
    return out


def correction_values(est: EstimatorSession) -> List[Tuple[str, object]]:
    """Return the estimate status's key-values of the live correction."""
    c = est.correction_summary()
    if c is None:
        return [('correction', 'off (estimator.correction.enabled: false)')]
    tcs = est.thermocouples
    used = [tc for tc, h in tcs.items() if h.status == 'ok']
    dropped = [f'{tc} ({h.status})' for tc, h in tcs.items() if h.dropped]
    if not c['active']:
        text = 'waiting for a usable thermocouple: open loop'
    else:
        text = f'on, correcting with: {", ".join(used) or "none now"}'
    if dropped:
        text += f'; dropped: {", ".join(dropped)}'
    failures = c['failures']
    values = [('correction', text), ('correction updates', c['updates']),
              ('correction failures', failures if not failures
               else f"{failures} (last: {c['last_failure']})")]
    values += [(f'learned heat {name} [W]', f'{value:.2f}')
               for name, value in c['disturbance_W'].items()]
    return values


# a thermocouple's status in the correction -> (level, message)
_THERMOCOUPLE_STATES = {
    'ok': (OK, 'correcting the model'),
    'waiting': (OK, 'learning its noise before use'),
    'absent': (OK, 'no reading yet'),
    'unused': (OK, 'displayed only (use: false)'),
    'held': (WARN, 'not used'),
    'stale': (STALE, 'stale: not used'),
}


def thermocouple_status(est: EstimatorSession, tc: str, topic: str) -> Status:
    """Return the status of one thermocouple in the live correction."""
    h = est.thermocouples[tc]
    level, message = _THERMOCOUPLE_STATES.get(h.status, (WARN, 'dropped from the correction'))
    if h.reason:
        message += f': {h.reason}'
    estimate = est.latest.temperatures_C.get(h.quantity) if est.latest is not None else None
    values = [('topic', topic),
              ('measures', h.quantity), ('status', h.status),
              ('received', h.received), ('rejected', h.rejected), ('used', h.used),
              ('gated', h.gated), ('late', h.late), ('stale_events', h.stale_events),
              ('dropped_events', h.dropped_events), ('recovered', h.recovered),
              ('last_value [degC]', fmt(h.last_value_C, '.2f', 'none')),
              ('last_stamp [s]', fmt(h.last_stamp_s, '.3f', 'none')),
              (f'estimate {h.quantity} [degC]', fmt(estimate, '.2f', 'none')),
              ('innovation [K]', fmt(h.innovation_K, '+.3f', 'none')),
              ('innovation sigma [K]', fmt(h.innovation_sigma_K, '.3f', 'none')),
              ('observed noise [K]', fmt(h.noise_K, '.3f', 'none')),
              ('sigma_K (config)', f'{h.sigma_K:g}')]
    return Status(f'thermocouple {tc}', level, message, values)


def input_status(est: EstimatorSession, name: str, now_s: float, topic: str, new_rejected: int,
                 callback_errors: int) -> Status:
    """Return the status of one sensor input: rejections since the last report, staleness."""
    h = est.health[name]
    level, message = OK, 'OK'
    if new_rejected > 0:
        level = WARN
        message = f'{new_rejected} samples rejected since the last report'
    if h.stale:
        level = STALE
        if h.last_value is None:
            message = f'stale: no sample yet, using the resting value {est.rest[name]:g}'
        else:
            since = h.stale_since_s if h.stale_since_s is not None else now_s
            message = (f'stale: holding last value {h.last_value:g} since {since:.3f} s '
                       f'({max(now_s - since, 0.0):.1f} s)')
    cfg = est.channel_cfg[name]
    values = [('topic', topic), ('received', h.received),
              ('accepted', h.accepted), ('non_finite', h.non_finite),
              ('out_of_range', h.out_of_range), ('backwards', h.backwards),
              ('late', h.late), ('future', h.future), ('overflow', h.overflow),
              ('discarded at clock jumps', h.discarded), ('stale_events', h.stale_events),
              ('callback_errors', callback_errors),
              ('last_value', fmt(h.last_value, 'g', 'none')),
              ('last_stamp [s]', fmt(h.last_stamp_s, '.3f', 'none')),
              ('timeout [s]', f'{cfg.timeout_s:g}'),
              ('range', f'[{cfg.low:g}, {cfg.high:g}]')]
    return Status(f'input {name}', level, message, values)


def plausibility_status(est: EstimatorSession, new_implausible: int) -> Status:
    """Return the status of the plausibility checks: implausible steps since the last report."""
    if new_implausible > 0:
        latest = est.latest.implausible if est.latest is not None else []
        level = WARN
        message = (f'{new_implausible} implausible steps since the last report: '
                   f'{", ".join(latest) or "see counters"}')
    else:
        level, message = OK, 'OK'
    return Status('plausibility', level, message, list(est.implausible_counts.items()))
