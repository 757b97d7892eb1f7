"""
The estimator's topics as serialised messages: one builder for the live node and for replay.

Each message is built here, once, as the CDR bytes of its type
(:mod:`wet_eha_thermal.bag.cdr`): the live node hands the bytes to rclpy
(``Publisher.publish`` takes serialised messages) and replay writes them to
its MCAP, so a replay's ``estimates.mcap`` holds what the node would have
published for the same estimates:

- ``/eha/estimate/<name>`` (sensor_msgs/Temperature), one per name of
  ``interface.ESTIMATES``: the estimate stamped with its sample time, the
  variance that of that quantity (K^2);
- ``/eha/state`` (std_msgs/Float64MultiArray): the model's state (K), its
  names once on ``/eha/state_names`` (std_msgs/String, JSON, latched);
- ``/eha/alerts`` (std_msgs/String): the alert summary as JSON
  (:meth:`~wet_eha_thermal.estimator.session.EstimatorSession.alert_summary`);
- ``/eha/current_limits`` (sensor_msgs/JointState: the horizons as
  ``position``, the limits as ``effort``, the status in ``header.frame_id``)
  and ``/eha/current_limit`` (std_msgs/Float64, the binding limit); live, the
  same limits as numbers on ``/eha/drive/limits`` (std_msgs/Float64MultiArray,
  :class:`~wet_eha_thermal.interface.DriveLimits`), numbered in the order sent;
- ``/eha/drive/alerts`` (std_msgs/Float64MultiArray,
  :class:`~wet_eha_thermal.interface.DriveAlerts`): each alert summary again as
  numbers, numbered in the order sent.

Topic names are the interface's; a node with a ``topic_prefix`` maps them.
"""

import json
from typing import List, Optional, Sequence, Tuple

import numpy as np

from . import interface
from .bag import cdr
from .estimator.alerts import Level
from .estimator.limits import CurrentLimits
from .estimator.session import Output

#: (topic, serialised message, stamp ns or None): one message to publish or log
Message = Tuple[str, bytes, Optional[int]]


def state_label(names_topic: str = interface.STATE_NAMES_TOPIC) -> str:
    """Return the state array's dimension label: where its names are."""
    return f'state_K: names on {names_topic}'


def state_names(names: Sequence[str]) -> bytes:
    """Return the ``/eha/state_names`` message: the state's names and unit, as JSON."""
    return cdr.encode_string(json.dumps({'unit': 'K', 'names': list(names)}))


def alerts(summary: dict) -> bytes:
    """Return the ``/eha/alerts`` message of an alert summary."""
    return cdr.encode_string(json.dumps(summary))


def limits(lim: CurrentLimits) -> List[Message]:
    """Return a tick's limits: the JointState of every horizon and the binding Float64."""
    ns = int(round(lim.stamp_s * 1e9))
    return [(interface.CURRENT_LIMITS_TOPIC, cdr.encode_joint_state(
        ns, lim.frame_id, lim.names, lim.horizons_s, (),
        lim.limits_A), ns),
        (interface.CURRENT_LIMIT_TOPIC, cdr.encode_float64(float(lim.binding_A)), ns)]


def drive_limits(lim: CurrentLimits, sequence: int) -> Message:
    """
    Return a tick's limits as the drive reads them: numbers at fixed places, no text.

    ``sequence`` numbers the limit messages of a run from 1; the status is
    the limits' own code.
    """
    ns = int(round(lim.stamp_s * 1e9))
    shortest = min(range(len(lim.horizons_s)), key=lim.horizons_s.__getitem__)
    drive = interface.DriveLimits(
        stamp_ns=ns, sequence=sequence, status=lim.code,
        binding_A=lim.binding_A, binding_horizon_s=lim.horizons_s[shortest],
        horizons_s=lim.horizons_s, limits_A=lim.limits_A)
    return (interface.DRIVE_LIMITS_TOPIC,
            cdr.encode_float64_array(drive.LABEL, np.asarray(drive.to_data())), ns)


def drive_alerts(summary: dict, sequence: int) -> bytes:
    """
    Return an alert summary (the JSON's dict) as the drive reads it: numbers, no text.

    ``sequence`` numbers the alert messages of a run from 1; a value or a
    time the summary does not have yet (None) goes out as NaN.
    """
    def num(value) -> float:
        return np.nan if value is None else float(value)

    stamp_s = summary['stamp_s']
    alerts = interface.DriveAlerts(
        stamp_ns=0 if stamp_s is None else int(round(stamp_s * 1e9)), sequence=sequence,
        level=int(summary['level']), quantities=tuple(
            interface.QuantityAlert(q, Level[d['reported']], Level[d['active']],
                                    d['acknowledged'], num(d['value_C']), d['warn_C'],
                                    d['critical_C'], num(d['since_s']))
            for q, d in summary['quantities'].items()))
    return cdr.encode_float64_array(alerts.LABEL, np.asarray(alerts.to_data()))


def alert_messages(summary: dict, sequence: int, stamp_ns: Optional[int]) -> List[Message]:
    """Return an alert summary's messages: the JSON for people, the numbers for a drive."""
    return [(interface.ALERT_TOPIC, alerts(summary), stamp_ns),
            (interface.DRIVE_ALERTS_TOPIC, drive_alerts(summary, sequence), stamp_ns)]


class EstimateMessages:
    """Build an estimate's messages: the temperatures with their variances, and the state."""

    def __init__(self, frame_id: str = 'eha', label: str = state_label()) -> None:
        self._stamped = cdr.Stamped(frame_id)
        self.label = label

    def build(self, stamp_ns: int, temperatures_C: Sequence[float],
              sigma_K: Sequence[float], state_K: np.ndarray) -> List[Message]:
        """
        Return the messages of one estimate stamped ``stamp_ns``.

        ``temperatures_C`` and ``sigma_K`` (1 sigma, sent as its square) in
        the order of ``interface.ESTIMATES``; the state last: no consumer
        waits on it.
        """
        head = self._stamped.head(stamp_ns)
        out = [(topic, self._stamped.encode(head, float(t), float(s) ** 2), stamp_ns)
               for topic, t, s in zip(interface.ESTIMATE_TOPICS, temperatures_C, sigma_K)]
        out.append((interface.STATE_TOPIC, cdr.encode_float64_array(self.label, state_K),
                    stamp_ns))
        return out


class OutputMessages:
    """
    Turn a session's outputs into messages, in the order a node publishes them.

    The last estimate of each output (or the held one, stamped with the
    clock), never one stamped at or before the last sent (the stamps start
    over when the clock jumped); the alert summary, then the same as the
    drive's numbers; the limits, then the same limits as the drive's numbers.
    """

    def __init__(self, frame_id: str = 'eha', label: str = state_label()) -> None:
        self.estimate = EstimateMessages(frame_id, label)
        self._last_ns: Optional[int] = None
        #: estimates sent
        self.published = 0
        #: limits sent: the sequence of the last drive limits
        self.limits_sent = 0
        #: alert summaries sent: the sequence of the last drive alerts
        self.alerts_sent = 0

    def build(self, out: Output) -> List[Message]:
        """Return the messages of ``out`` (see the class)."""
        if out.restarted:
            self._last_ns = None
        msgs: List[Message] = []
        if out.estimates:
            msgs += self._estimate(out.estimates[-1], out.estimates[-1].stamp_s)
        elif out.held is not None:
            msgs += self._estimate(*out.held)
        if out.alerts is not None:
            self.alerts_sent += 1
            msgs += alert_messages(out.alerts, self.alerts_sent, self._last_ns)
        for lim in out.limits:
            self.limits_sent += 1
            msgs += limits(lim)
            msgs.append(drive_limits(lim, self.limits_sent))
        return msgs

    def _estimate(self, est, stamp_s: float) -> List[Message]:
        ns = int(round(stamp_s * 1e9))
        if self._last_ns is not None and ns <= self._last_ns:
            return []                  # never the same or an older stamp twice
        self._last_ns = ns
        self.published += 1
        names = interface.ESTIMATES
        return self.estimate.build(ns, [est.temperatures_C[n] for n in names],
                                   [est.uncertainty_K[n] for n in names], est.state_K)
