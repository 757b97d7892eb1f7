"""
A replay's outputs: ``estimates.csv``, ``limits.csv`` and ``estimates.mcap``.

Each is written under a ``.partial`` name and renamed when complete. The MCAP holds
the messages the live node publishes for the same estimates, built by the same code
(:mod:`wet_eha_thermal.messages`).
"""

import csv
import math
from pathlib import Path
from typing import List

import numpy as np

from .report import write_report
from .run import OUTPUT_ESTIMATES, ReplayResult
from ... import interface
from ...output_files import atomic


def write_csv(result: ReplayResult, path: Path) -> Path:
    """
    Write the estimates (degC) with stamps, uncertainty and alert level; return the path.

    With the outlook, also the latest forecast's time to each limit from its
    start (``inf``: beyond its horizon; ``nan``: no forecast yet), that start
    and the continuous current limit.
    """
    header = ['stamp_s'] + [f'{n}_C' for n in OUTPUT_ESTIMATES] + [
        'sigma_K', 'alert_level', 'inputs_on_fallback']
    columns = [result.stamp_s] + [result.temperatures_C[n] for n in OUTPUT_ESTIMATES] + [
        result.sigma_K, result.alert_level, result.stale_inputs]
    fmt = ['%.6f'] + ['%.4f'] * len(OUTPUT_ESTIMATES) + ['%.3f', '%d', '%d']
    if result.outlook:
        header += [f'time_to_limit_{q}_s' for q in result.time_to_limit_s] + [
            'forecast_stamp_s', 'margin_current_A']
        columns += list(result.time_to_limit_s.values()) + [result.forecast_stamp_s,
                                                            result.margin_current_A]
        fmt += ['%.1f'] * len(result.time_to_limit_s) + ['%.6f', '%.3f']
    table = np.column_stack(columns)
    with atomic(path) as tmp:
        np.savetxt(tmp, table, fmt=fmt, delimiter=',', header=','.join(header), comments='')
    return path


def write_limits_csv(result: ReplayResult, path: Path) -> Path:
    """
    Write every tick's current limits, one row each; return the path.

    Columns: the tick's stamp (sample time, s), the binding limit (A RMS),
    then for each limit (``continuous``, ``10s``, ...) its value (A RMS) and
    what binds it, the status, why it fell back, how long the limits were in
    force and the RMS current the log carried meanwhile. Values at full
    precision: a replay's limits are reproducible bit for bit.
    """
    names = result.current_limits[0].names if result.current_limits else ()
    header = ['stamp_s', 'binding_A'] + [c for name in names
                                         for c in (f'limit_{name}_A', f'binds_{name}')] + [
        'status', 'reason', 'held_s', 'current_rms_A']
    with atomic(path) as tmp, open(tmp, 'w', newline='') as f:
        writer = csv.writer(f)
        writer.writerow(header)
        for lim, held, current in zip(result.current_limits, result.limits_held_s.tolist(),
                                      result.limits_current_A.tolist()):
            writer.writerow([repr(lim.stamp_s), repr(lim.binding_A)]
                            + [c for v, b in zip(lim.limits_A, lim.binds) for c in (repr(v), b)]
                            + [lim.status, lim.reason, repr(held), repr(current)])
    return path


def _node_topics(outlook: bool) -> List[tuple]:
    """Return (topic, type, offered QoS) of the live node's publishers (limits: ``outlook``)."""
    from ...bag.writer import offered_qos
    latched = offered_qos(durability='transient_local', depth=1)
    topics = [(t, interface.TEMPERATURE, offered_qos(depth=10))
              for t in interface.ESTIMATE_TOPICS]
    topics += [(interface.STATE_TOPIC, interface.FLOAT64_ARRAY, offered_qos(depth=10)),
               (interface.STATE_NAMES_TOPIC, interface.STRING, latched),
               (interface.ALERT_TOPIC, interface.STRING, latched),
               (interface.DRIVE_ALERTS_TOPIC, interface.FLOAT64_ARRAY, latched)]
    if outlook:
        # the live node's publishers: reliable, volatile, 10 deep
        topics += [(interface.CURRENT_LIMITS_TOPIC, interface.JOINT_STATE, offered_qos(depth=10)),
                   (interface.CURRENT_LIMIT_TOPIC, interface.FLOAT64, offered_qos(depth=10)),
                   (interface.DRIVE_LIMITS_TOPIC, interface.FLOAT64_ARRAY,
                    offered_qos(depth=10))]
    return topics


def _alerts_and_limits(result: ReplayResult) -> List[tuple]:
    """
    Return the alert and limits messages as (stamp s, 0 alert or 1 limits, message), in order.

    They go out behind the estimates of their stamp; a summary before the
    first estimate (stamp -inf) goes out with it.
    """
    from ... import messages
    return sorted([(-math.inf if s is None else s, 0, m)
                   for seq, (s, a) in enumerate(result.alerts, start=1)
                   for m in messages.alert_messages(
                       a, seq, None if s is None else int(round(s * 1e9)))]
                  + [(lim.stamp_s, 1, m)
                     for seq, lim in enumerate(result.current_limits, start=1)
                     for m in messages.limits(lim) + [messages.drive_limits(lim, seq)]],
                  key=lambda x: (x[0], x[1]))


def write_mcap(result: ReplayResult, path: Path) -> Path:
    """
    Write what the live estimator node publishes for these estimates, with the config.

    The messages of :mod:`wet_eha_thermal.messages`, the node's bytes: per
    estimate kept, the ``/eha/estimate/<name>`` Temperatures (each with its
    own variance) and ``/eha/state`` (its names once, latched); the alert
    summaries the session published (JSON, on ``/eha/alerts``, and as the
    drive's numbers on DRIVE_ALERTS_TOPIC, numbered from 1); with the
    outlook, every tick's limits (a JointState on CURRENT_LIMITS_TOPIC, the
    binding limit as a Float64 on CURRENT_LIMIT_TOPIC, the drive's numbers on
    DRIVE_LIMITS_TOPIC, numbered from 1 as the node numbers them). Each is
    logged at its sample time, in the order the node publishes them, under
    the plan's prefix (the one the bag was recorded under): a replay of
    the /left actuator compares topic for topic with its live recording.
    """
    from ... import messages
    from ...bag.writer import BagWriter

    def under(topic: str) -> str:
        return interface.prefixed(topic, result.plan.prefix)

    cfg_yaml = result.plan.config_yaml
    metadata = {interface.CONFIG_METADATA: {interface.CONFIG_METADATA_KEY: cfg_yaml,
                                            'source': result.plan.config_source}}
    stamps_ns = np.round(result.stamp_s * 1e9).astype(np.int64).tolist()
    later = _alerts_and_limits(result)
    build = messages.EstimateMessages(label=messages.state_label(
        under(interface.STATE_NAMES_TOPIC)))
    temps = [result.temperatures_C[n].tolist() for n in interface.ESTIMATES]
    sigma = [result.uncertainty_K[n].tolist() for n in interface.ESTIMATES]
    with atomic(path) as tmp, BagWriter(tmp, metadata=metadata, flush_interval_s=3600.0) as w:
        for topic, type_name, qos in _node_topics(result.outlook):
            w.add_topic(under(topic), type_name, qos)
        w.write(under(interface.STATE_NAMES_TOPIC), messages.state_names(result.state_names),
                stamps_ns[0])
        j = 0
        for k, ns in enumerate(stamps_ns):
            for topic, data, _ in build.build(ns, [t[k] for t in temps], [s[k] for s in sigma],
                                              result.state_K[k]):
                w.write(under(topic), data, ns)
            while j < len(later) and later[j][0] <= result.stamp_s[k]:
                topic, data, at = later[j][2]
                w.write(under(topic), data, ns if at is None else at)
                j += 1
        for _, _, (topic, data, at) in later[j:]:
            w.write(under(topic), data, stamps_ns[-1] if at is None else at)
    return path


def write_outputs(result: ReplayResult, out_dir: Path, report: bool = True) -> List[Path]:
    """Write estimates.csv, estimates.mcap, limits.csv and the report; return the paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    files = [write_csv(result, out_dir / 'estimates.csv'),
             write_mcap(result, out_dir / 'estimates.mcap')]
    if result.outlook:
        files.append(write_limits_csv(result, out_dir / 'limits.csv'))
    if report:
        files.append(write_report(result, out_dir))
    return files
