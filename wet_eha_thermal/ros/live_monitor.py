"""
The ROS side of ``live``'s own process: a private domain, and a node that follows the twin.

:func:`open_domain` picks a ROS domain no other node uses on this machine;
:func:`monitor_node` subscribes to the ready topic, the estimates, the
alerts, the drive's current limits and /diagnostics, and keeps what it sees
in a :class:`TwinState`, from which :mod:`.live_text` makes the status line and the summary.
"""

from dataclasses import dataclass, field
import json
import math
import os
import time
from typing import Dict, List, Optional

from diagnostic_msgs.msg import DiagnosticArray
import rclpy
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data, QoSProfile
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState, Temperature
from std_msgs.msg import Float64, String
from wet_eha_thermal import interface
from wet_eha_thermal.interface import RIG_NODE
from wet_eha_thermal.ros import topics

#: Environment variable that fixes the ROS domain of a live run (0..232).
DOMAIN_ENV = 'WET_EHA_LIVE_DOMAIN_ID'
#: Domains picked from the process id: 100..232 (Fast DDS ports allow up to 232).
DOMAIN_FIRST, DOMAIN_LAST = 100, 232
#: Domains tried when picking one, and how long each is watched for other nodes (s).
DOMAIN_TRIES, DOMAIN_PROBE_S = 8, 0.5
#: Estimates followed by the status line and the peaks.
WATCHED = ('winding_hotspot', 'winding_mean', 'magnet', 'oil')
ESTIMATE_STATUS = interface.status_name('estimate', interface.ESTIMATOR_NODE)
RECORDER_STATUS = interface.status_name('recorder', interface.RECORDER_NODE)
INPUT_STATUS = interface.status_name('input ', interface.ESTIMATOR_NODE)
RIG_STATUS = interface.status_name('rig', RIG_NODE)
#: the band the truth is checked against: the one the drive's limits hold (k sigma)
TRUTH_BAND_SIGMA = 2.0


def domain_from_env() -> Optional[int]:
    """Return ``$WET_EHA_LIVE_DOMAIN_ID`` (None when unset); ValueError if it is not 0..232."""
    text = os.environ.get(DOMAIN_ENV, '').strip()
    if not text:
        return None
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 0 <= value <= DOMAIN_LAST:
        raise ValueError(f'{DOMAIN_ENV}={text!r}: expected an integer 0..{DOMAIN_LAST}')
    return value


def open_domain(domain: Optional[int] = None):
    """
    Return ``(context, domain)``: an initialised rclpy context on a private ROS domain.

    With ``domain`` None, the first domain without any ROS node on this
    machine, trying from one picked by the process id (nodes that announce
    themselves within ``DOMAIN_PROBE_S``); a given ``domain`` is used as it is.
    """
    span = DOMAIN_LAST - DOMAIN_FIRST + 1
    first = DOMAIN_FIRST + os.getpid() % span
    tries = [domain] if domain is not None else [
        DOMAIN_FIRST + (first - DOMAIN_FIRST + 7 * k) % span for k in range(DOMAIN_TRIES)]
    for k, d in enumerate(tries):
        context = rclpy.Context()
        rclpy.init(args=[], context=context, domain_id=d,
                   signal_handler_options=SignalHandlerOptions.NO)
        if domain is not None or k == len(tries) - 1:
            return context, d
        probe = Node('eha_live_probe', context=context)
        end = time.monotonic() + DOMAIN_PROBE_S
        busy = False
        while not busy and time.monotonic() < end:
            time.sleep(0.05)
            busy = any(n != 'eha_live_probe' for n in probe.get_node_names())
        probe.destroy_node()
        if not busy:
            return context, d
        rclpy.try_shutdown(context=context)
    raise AssertionError('unreachable')


@dataclass
class TwinState:
    """What the monitor has seen of the estimator and the rig."""

    temps: Dict[str, float] = field(default_factory=dict)
    peaks: Dict[str, float] = field(default_factory=dict)
    sigma_K: Optional[float] = None
    sigmas_K: Dict[str, float] = field(default_factory=dict)     # each estimate's 1 sigma
    # the rig's truth against the estimate at each rig report: the last error (K), and
    # how many reports had the truth inside the 2-sigma band, of how many
    truth_error_K: Dict[str, float] = field(default_factory=dict)
    truth_inside: Dict[str, int] = field(default_factory=dict)
    truth_checks: int = 0
    estimates: int = 0
    first_rx: Optional[float] = None
    last_rx: Optional[float] = None
    first_stamp: Optional[float] = None
    last_stamp: Optional[float] = None
    alert_level: str = 'OK'
    alert_message: str = 'OK'
    alert_events: List[str] = field(default_factory=list)
    raised: int = 0
    reported: Dict[str, str] = field(default_factory=dict)
    margin: str = 'pending'
    time_to_limit: Dict[str, str] = field(default_factory=dict)
    fallback: str = 'unknown'
    stale_events: Dict[str, int] = field(default_factory=dict)
    received: Dict[str, int] = field(default_factory=dict)
    rig: Dict[str, str] = field(default_factory=dict)
    recorder: Dict[str, str] = field(default_factory=dict)    # its last diagnostics' values
    recorder_level: str = ''                                   # '' until it reports
    recorder_message: str = ''
    recorder_faults: List[str] = field(default_factory=list)  # each change to WARN or ERROR
    ready: Dict[str, dict] = field(default_factory=dict)      # node -> its ready message
    limit_A: Optional[float] = None          # the drive's binding current limit, A RMS
    lowest_limit_A: float = math.inf
    limit_status: str = ''                   # the limits' frame_id: ok, fallback: <why>
    limit_fallbacks: int = 0                 # limits messages that said fallback
    rig_started: Optional[float] = None                       # when the duty started
    hardware_id: str = field(default_factory=lambda: f'wet-eha-live-{os.getpid()}')

    def on_estimate(self, name: str, temperature_C: float, variance: float, stamp_s: float,
                    rx: float) -> None:
        """Take one estimate message."""
        self.temps[name] = temperature_C
        self.sigmas_K[name] = math.sqrt(variance) if variance >= 0.0 else math.nan
        if math.isfinite(temperature_C):
            self.peaks[name] = max(self.peaks.get(name, -math.inf), temperature_C)
        if name == WATCHED[0]:
            self.estimates += 1
            self.sigma_K = math.sqrt(variance) if variance >= 0.0 else None
            if self.first_rx is None:
                self.first_rx, self.first_stamp = rx, stamp_s
            self.last_rx, self.last_stamp = rx, stamp_s

    def on_alerts(self, text: str) -> None:
        """Take one alert summary (JSON) of the estimator."""
        try:
            data = json.loads(text)
        except ValueError:
            return
        if data.get('hardware_id', self.hardware_id) != self.hardware_id:
            return
        self.alert_level = str(data.get('level_name', data.get('level', '?')))
        self.alert_message = str(data.get('message', ''))
        self.alert_events += [str(e) for e in data.get('events', [])]
        order = ('OK', 'WARN', 'CRITICAL')
        for q, d in (data.get('quantities') or {}).items():
            level = str(d.get('reported', 'OK'))
            before = self.reported.get(q, 'OK')
            if level in order and before in order and order.index(level) > order.index(before):
                self.raised += 1
            self.reported[q] = level

    def on_diagnostics(self, statuses) -> None:
        """Take one DiagnosticArray's statuses (estimator and rig)."""
        for st in statuses:
            kv = {v.key: v.value for v in st.values}
            if st.hardware_id != self.hardware_id:
                continue                      # another estimator on this domain: not ours
            if st.name == ESTIMATE_STATUS:
                self.margin = kv.get('margin_current [A RMS]', self.margin)
                for key, value in kv.items():
                    if key.startswith('time_to_limit '):
                        self.time_to_limit[key.split()[1]] = value
                self.fallback = kv.get('inputs on fallback', self.fallback)
            elif st.name.startswith(INPUT_STATUS):
                name = st.name[len(INPUT_STATUS):]
                for key, store in (('stale_events', self.stale_events),
                                   ('received', self.received)):
                    try:
                        store[name] = int(kv.get(key, ''))
                    except ValueError:
                        pass
            elif st.name == RIG_STATUS:
                self.rig = kv
                self.check_truth(kv)
            elif st.name == RECORDER_STATUS:
                self.on_recorder(level_name(st.level), st.message, kv)

    def check_truth(self, rig: Dict[str, str]) -> None:
        """Compare the rig's truth with the latest estimates and their 2-sigma band."""
        errors = {}
        for q in WATCHED:
            try:
                errors[q] = self.temps[q] - float(rig[f'truth_{q}_C'])
            except (KeyError, ValueError):
                return
        self.truth_error_K = errors
        self.truth_checks += 1
        for q, e in errors.items():
            inside = abs(e) <= TRUTH_BAND_SIGMA * self.sigmas_K.get(q, math.nan)
            self.truth_inside[q] = self.truth_inside.get(q, 0) + inside

    def on_recorder(self, level: str, message: str, values: Dict[str, str]) -> None:
        """Take the recorder's status: level (OK, WARN, ERROR), message and values."""
        if level != self.recorder_level and level in ('WARN', 'ERROR'):
            self.recorder_faults.append(f'{level}: {message}')
        self.recorder_level, self.recorder_message, self.recorder = level, message, values

    def on_limit(self, value_A: float) -> None:
        """Take the binding current limit (A RMS) the estimator published for the drive."""
        self.limit_A = value_A
        if math.isfinite(value_A):
            self.lowest_limit_A = min(self.lowest_limit_A, value_A)

    def on_limits(self, status: str) -> None:
        """Take the status (``frame_id``) of one message of the limits per horizon."""
        self.limit_status = status
        self.limit_fallbacks += status != 'ok'

    def on_ready(self, text: str, rx: float) -> None:
        """Take one ready message (JSON); the rig's ``running`` starts the run's clock."""
        try:
            data = json.loads(text)
        except ValueError:
            return
        if not isinstance(data, dict) or not isinstance(data.get('node'), str):
            return
        self.ready[data['node']] = data
        if data['node'] == RIG_NODE and data.get('running') and self.rig_started is None:
            self.rig_started = rx


def level_name(level) -> str:
    """Return a DiagnosticStatus level's name (rclpy gives a byte field as 1-byte bytes)."""
    value = level[0] if isinstance(level, (bytes, bytearray)) else int(level)
    return ('OK', 'WARN', 'ERROR', 'STALE')[value] if 0 <= value <= 3 else str(value)


def monitor_node(context, state: TwinState):
    """Create the node of this process that feeds ``state``."""
    node = Node('eha_live_monitor', context=context)

    def estimate_cb(name):
        def cb(msg: Temperature) -> None:
            st = msg.header.stamp
            state.on_estimate(name, msg.temperature, msg.variance, st.sec + 1e-9 * st.nanosec,
                              time.monotonic())
        return cb

    for name in WATCHED:
        node.create_subscription(Temperature, f'{interface.ESTIMATE_PREFIX}/{name}',
                                 estimate_cb(name), QoSProfile(depth=50))
    node.create_subscription(String, interface.ALERT_TOPIC, lambda m: state.on_alerts(m.data),
                             topics.latched_qos())
    node.create_subscription(DiagnosticArray, interface.DIAGNOSTICS_TOPIC,
                             lambda m: state.on_diagnostics(m.status), QoSProfile(depth=20))
    # best effort: matches the limits whatever their publisher offers
    node.create_subscription(Float64, interface.CURRENT_LIMIT_TOPIC,
                             lambda m: state.on_limit(m.data), qos_profile_sensor_data)
    node.create_subscription(JointState, interface.CURRENT_LIMITS_TOPIC,
                             lambda m: state.on_limits(m.header.frame_id),
                             qos_profile_sensor_data)
    node.create_subscription(String, interface.READY_TOPIC,
                             lambda m: state.on_ready(m.data, time.monotonic()),
                             topics.latched_qos(depth=10))
    return node
