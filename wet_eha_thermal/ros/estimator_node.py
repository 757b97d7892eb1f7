"""
The live estimator as a ROS 2 node: sensor topics in; estimates, diagnostics and alerts out.

The node wraps :class:`wet_eha_thermal.estimator.core.Estimator`. The input
topics, as the ``inputs_file`` declares them (:mod:`wet_eha_thermal.inputs`:
Float64, FluidPressure, Temperature, JointState by joint and field, or a
batched block), are taken raw (CDR bytes) and decoded in place; each sample,
converted to SI, is pushed into the core's preallocated buffer with its stamp
(a Float64 has none: it takes the node's ROS clock, so /clock under
use_sim_time), and that is all the per-sample work; a batched block goes in
as arrays. A sample that can complete a model step steps
it at once (the core checks the new samples then, vectorised), so the estimate
leaves within the step's computing time. A timer at ``publish_rate_Hz`` also
calls ``advance(now)`` with the ROS clock, so the model keeps stepping on its
fallbacks when inputs fall silent. No call steps more than
``estimator.max_steps_per_call`` steps: after a stall the model catches up over
several calls. Each new estimate is published: one sensor_msgs/Temperature per
name in ``interface.ESTIMATES`` (stamped with the estimate's sample time, strictly
increasing), the state vector, and the alert summary whenever it changes
(latched). The rest of each tick's budget goes to the forecast and margin.
Thermocouples (``/eha/measured/<tc>``) go to the core with their header stamps:
with the live correction on they correct the model, and /diagnostics carries
one status per thermocouple (used, held, dropped or stale, with counters).

Time: samples stamped more than ``estimator.max_future_s`` ahead of the clock
are rejected; the clock going back by more than ``estimator.clock_jump_s``
re-starts the model time (the core's rule); without sim time, the ROS clock
moving ahead of the steady clock by more than that between two ticks (the
system clock stepped) re-starts it too, so that the model never steps across a
jump. Under sim time a leap forward of /clock is taken as elapsed time. Data
gaps (every input silent) and clock jumps are logged, listed in the alert
summary's events and counted in /diagnostics.

Once the model is compiled and warmed and every input subscription has
matched a publisher, the node says so on ``/eha/ready`` (latched); the
simulated rig waits for that. A second timer publishes /diagnostics. No
callback ever raises: a failure is logged, counted and shown in the
diagnostics. At shutdown one summary line (samples received and rejected per
input, gaps, clock jumps) goes to stderr for people, and the same counts as
data (an :class:`~wet_eha_thermal.interface.NodeReport` line) to stdout.

With ``foxglove_address`` (HOST:PORT) the node also serves the Foxglove view
(:mod:`wet_eha_thermal.live_view`): each estimate, alert summary and count of
the inputs goes to it after everything ROS gets, through a bounded hand-off
where the newest wins; the view's thread and the Foxglove SDK do the rest. An
address in use is one error line, and the node estimates without the view.
Foxglove may set the publication rates (``FOXGLOVE_SETTABLE``), applied here
on the node's thread as a ROS parameter change; thresholds and limits are
shown read-only.

What-ifs (``interface.WHATIF_REQUEST_TOPIC``, from ROS or from the Foxglove
view): each request takes a snapshot of the model as it arrives and runs in a
worker process (:class:`~wet_eha_thermal.offline.whatif_worker.WhatIfWorker`),
one at a time; a steady timer polls for its answer and publishes it on
``interface.WHATIF_RESPONSE_TOPIC`` (and to the view), so the node's steps
never wait for a what-if.

Run it with ``wet-eha-thermal-estimator --ros-args --params-file
config/estimator.params.yaml`` or ``python -m wet_eha_thermal.ros.estimator_node``.
"""

from collections import deque
import functools
import json
import math
import sys
import time
from typing import Deque, Dict, List, Optional

from builtin_interfaces.msg import Time as TimeMsg
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import NameValidationException, ParameterException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from sensor_msgs.msg import JointState, Temperature
from std_msgs.msg import Float64, Float64MultiArray, MultiArrayDimension, String
from wet_eha_thermal import inputs, interface
from wet_eha_thermal.config import ConfigError, load_config
from wet_eha_thermal.estimator.core import Estimate, Estimator, StepFailed
from wet_eha_thermal.estimator.limits import CurrentLimits
from wet_eha_thermal.live_view import app_url, LiveView, parse_address
from wet_eha_thermal.model.quantity_table import LIMITED
from wet_eha_thermal.offline.whatif_worker import WhatIfWorker
from wet_eha_thermal.ros import diagnostics, topics
from wet_eha_thermal.ros.runtime import (accept_whole_numbers, descriptor, EXECUTORS, FastClock,
                                         prepare_model_step, Readiness, run_node)
from wet_eha_thermal.units import C_TO_K

NODE_NAME = interface.ESTIMATOR_NODE


# name -> (default, descriptor); ranges are enforced by rclpy, also for --params-file values
PARAMETERS = {
    'config_file': ('', descriptor(
        'estimator configuration YAML (the estimator: section and the rig); '
        "'' = the shipped config/reference_eha.yaml")),
    'inputs_file': ('', descriptor(
        'YAML of the inputs: topic, message type, field and unit of each '
        '(wet_eha_thermal/inputs.py); a name not found is looked for in the shipped config/; '
        "'' = the /eha topics of the simulated rig")),
    'qos': ('sensor_data', descriptor(
        "QoS of the sensor subscriptions: 'sensor_data' (best effort) or 'reliable'")),
    'qos_depth': (1000, descriptor('history depth of the sensor subscriptions', 1, 10000)),
    'publish_rate_Hz': (50.0, descriptor(
        'rate of the estimate, state and alert publication (and of advance(now))', 1.0, 500.0,
        read_only=False)),
    'background_budget_ms': (2.0, descriptor(
        'wall time per publish tick given to the forecast and the margin', 0.0, 50.0,
        read_only=False)),
    'diagnostics_rate_Hz': (1.0, descriptor('rate of /diagnostics', 0.1, 10.0, read_only=False)),
    'hardware_id': ('wet-eha-rig', descriptor('hardware_id of the diagnostic statuses')),
    'frame_id': ('eha', descriptor('frame_id of the published temperatures')),
    'topic_prefix': (topics.FROM_NAMESPACE, descriptor(topics.PREFIX_DOC)),
    'executor': ('events', descriptor(
        "executor used by main(): 'events' (rclpy.experimental.EventsExecutor) or 'single' "
        '(SingleThreadedExecutor); the --executor option overrides it')),
    'foxglove_address': ('', descriptor(
        'Foxglove WebSocket server of the live view (wet_eha_thermal/live_view.py), HOST:PORT, '
        "e.g. 127.0.0.1:8765 (port 0: any free one); '' = no server")),
    'foxglove_inputs_rate_Hz': (20.0, descriptor(
        'rate of the inputs, input health and thermocouples in the Foxglove view (averaged '
        'over windows of sample time)', 1.0, 50.0, read_only=False)),
}
#: Parameters Foxglove may set: rates of publication only, which change what is shown,
#: never what is estimated or when an alert is raised (those stay read-only there).
FOXGLOVE_SETTABLE = ('publish_rate_Hz', 'diagnostics_rate_Hz', 'foxglove_inputs_rate_Hz')
#: How often the node looks for a what-if's answer (s, steady clock): a what-if takes seconds.
WHATIF_POLL_S = 0.1


def _stamp_msg(ns: int) -> TimeMsg:
    return TimeMsg(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def _stamp_s(stamp: TimeMsg) -> float:
    return stamp.sec + 1e-9 * stamp.nanosec


def _json_safe(value):
    """Return ``value`` with enums as ints and non-finite floats as None, for strict JSON."""
    if isinstance(value, dict):
        return {str(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    return str(value)


class EstimatorNode(Node):
    """Thermal estimator node: subscribes to the rig's sensors, publishes estimates."""

    def __init__(self, **kwargs) -> None:
        super().__init__(NODE_NAME, **kwargs)
        p, view_at = self._read_parameters()
        self.cfg = load_config(p['config_file'] or None)
        input_spec = inputs.load_inputs(p['inputs_file'])
        self.est = Estimator(self.cfg, outlook='background')
        # before any subscription or publisher: a first step that compiled would keep
        # samples waiting for a minute or more
        prepare_model_step(self, self.cfg, estimator=True)
        self.clock = FastClock(self)
        # the clock read at the last tick, and the steady clock then: a system clock that
        # moves ahead of the steady one was stepped, not waited for
        self._tick_clock: Optional[tuple] = None
        self.hardware_id = p['hardware_id']
        self.frame_id = p['frame_id']
        self.prefix = topics.resolve_prefix(self, p['topic_prefix'])
        in_qos = topics.input_qos(p['qos'], p['qos_depth'])   # ValueError names a bad kind
        out_qos = QoSProfile(depth=10)                         # reliable, volatile
        self._init_counters()
        input_subs = self._subscribe(in_qos, input_spec)
        self._advertise(out_qos)
        self._serve_whatif()
        self.budget_s = p['background_budget_ms'] * 1e-3
        self.publish_timer = self.create_timer(1.0 / p['publish_rate_Hz'], self._on_tick)
        self.diag_timer = self.create_timer(1.0 / p['diagnostics_rate_Hz'], self._on_diagnostics)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.view_error = ''
        self.view = self._start_view(view_at, p) if view_at is not None else None
        if self.view is not None:
            # the recorder's health, shown in the view beside the estimates
            self.create_subscription(String, self._topic(interface.RECORDER_HEALTH_TOPIC),
                                     self._on_recorder_health, topics.latched_qos())
        self._publish_alerts(force=True)
        self.readiness = Readiness(self, self._topic(interface.READY_TOPIC), input_subs,
                                   self.hardware_id, require_all=True,
                                   extra={'foxglove': self.view.url if self.view else None,
                                          'foxglove_error': self.view_error})
        self.get_logger().info(
            f"estimating {len(interface.ESTIMATES)} temperatures at {p['publish_rate_Hz']:g} Hz "
            f"from {self.prefix or '/'}/* ({p['qos']} QoS, depth {p['qos_depth']}); config "
            f"{p['config_file'] or 'reference_eha.yaml (shipped)'}")

    def _read_parameters(self) -> tuple:
        """Declare and read the parameters; return them and the view's address (or None)."""
        accept_whole_numbers(self, {name: d for name, (d, _) in PARAMETERS.items()})
        for name, (default, desc) in PARAMETERS.items():
            self.declare_parameter(name, default, desc)
        p = {name: self.get_parameter(name).value for name in PARAMETERS}
        if p['executor'] not in EXECUTORS:
            raise ValueError(f"parameter executor = {p['executor']!r}: expected one of "
                             f'{", ".join(EXECUTORS)}')
        view_at = None         # checked before the model's slow start
        if p['foxglove_address']:
            try:
                view_at = parse_address(p['foxglove_address'])
            except ValueError as exc:
                raise ValueError(f'parameter foxglove_address = {exc}') from None
        return p, view_at

    def _init_counters(self) -> None:
        """Zero the counters the diagnostics report besides the core's."""
        self.callback_errors: Dict[str, int] = {}
        self.waiting_for_clock = 0
        self.model_errors = 0
        self.model_error = ''
        self.model_failing = False
        self.background_errors = 0
        self.published = 0
        self.limits_published = 0      # ticks of current limits sent, and those as fallback
        self.limits_fallback = 0
        # callback start of the sample that closed a step -> its estimate published (ms)
        self.latency_ms: Deque[float] = deque(maxlen=3000)
        self._last_ns: Optional[int] = None          # stamp of the last published estimate
        self._last_published: Optional[Estimate] = None
        self._alert_key = None
        self._pending_events: List[str] = []
        # rejected counts at the last diagnostics
        self._diag_prev = dict.fromkeys(self.est.inputs, 0)
        self._implausible_prev = 0
        # the topic of every input and of every thermocouple (measured/<name>), as subscribed
        self.topic_names: Dict[str, str] = {}

    def _subscribe(self, in_qos: QoSProfile, input_spec: inputs.Inputs) -> list:
        """Subscribe to the inputs (raw), the ambient, the thermocouples and the acks."""
        # inputs, raw: decoded here in a fraction of rclpy's deserialisation; one
        # subscription per topic, whatever number of inputs it carries
        input_subs = []
        for dec in inputs.decoders(input_spec, self.est.inputs):
            topic = self._topic(dec.topic)
            cb = functools.partial(self._on_batch if dec.batched else self._on_input, dec)
            kind = topics.message_class(dec.message_type)
            input_subs.append(self.create_subscription(kind, topic, cb, in_qos, raw=True))
            self.topic_names.update(dict.fromkeys(dec.channels, topic))
        self.create_subscription(Temperature, self._topic(interface.AMBIENT_TOPIC),
                                 self._on_ambient, in_qos)
        for tc in interface.THERMOCOUPLES:
            key = f'{interface.MEASURED_PREFIX}/{tc}'
            self.topic_names[key] = self._topic(key)
            self.create_subscription(Temperature, self.topic_names[key],
                                     functools.partial(self._on_measured, tc), in_qos)
        self.create_subscription(String, self._topic(interface.ACK_TOPIC), self._on_ack,
                                 QoSProfile(depth=10))
        return input_subs

    def _advertise(self, out_qos: QoSProfile) -> None:
        """Create the publishers: estimates, state, its names (latched), alerts, diagnostics."""
        self.estimate_pubs = {
            name: self.create_publisher(
                Temperature, self._topic(f'{interface.ESTIMATE_PREFIX}/{name}'), out_qos)
            for name in interface.ESTIMATES}
        self._temperature_msg = Temperature()
        self._temperature_msg.header.frame_id = self.frame_id
        self.state_pub = self.create_publisher(Float64MultiArray,
                                               self._topic(interface.STATE_TOPIC), out_qos)
        # the name of each element of the state, once and latched: they do not change in a run
        names_topic = self._topic(interface.STATE_NAMES_TOPIC)
        self.state_names_pub = self.create_publisher(String, names_topic, topics.latched_qos())
        self.state_names_pub.publish(String(data=json.dumps(
            {'unit': 'K', 'names': list(self.est.model.quantities.state_names)})))
        self._state_label = f'state_K: names on {names_topic}'
        self.alert_pub = self.create_publisher(String, self._topic(interface.ALERT_TOPIC),
                                               topics.latched_qos())
        self.diag_pub = self.create_publisher(DiagnosticArray, interface.DIAGNOSTICS_TOPIC,
                                              QoSProfile(depth=10))
        # the drive's limits: reliable, a few deep (a drive reads every one it can)
        self.limits_pub = self.create_publisher(
            JointState, self._topic(interface.CURRENT_LIMITS_TOPIC), QoSProfile(depth=10))
        self.limit_pub = self.create_publisher(
            Float64, self._topic(interface.CURRENT_LIMIT_TOPIC), QoSProfile(depth=10))
        self._limits_msg = JointState()
        # the same limits for a drive that reads numbers only (interface.DriveLimits)
        self.drive_limits_pub = self.create_publisher(
            Float64MultiArray, self._topic(interface.DRIVE_LIMITS_TOPIC), QoSProfile(depth=10))

    def _serve_whatif(self) -> None:
        """Start the what-if worker; subscribe to the requests, advertise the answers."""
        self.whatif = WhatIfWorker(self.cfg, self.est.model.quantities.names)
        self.whatif.start()
        self.whatif_pub = self.create_publisher(
            String, self._topic(interface.WHATIF_RESPONSE_TOPIC), QoSProfile(depth=10))
        self.create_subscription(String, self._topic(interface.WHATIF_REQUEST_TOPIC),
                                 self._on_whatif_request, QoSProfile(depth=10))
        # steady: under sim time a paused /clock must not hold an answer back
        self.create_timer(WHATIF_POLL_S, self._poll_whatif,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))

    # ------------------------------------------------------------- helpers
    def _topic(self, name: str) -> str:
        """Return ``name`` with the topic prefix in place of interface.PREFIX."""
        return interface.prefixed(name, self.prefix)

    def _now_s(self) -> Optional[float]:
        """Return the ROS clock in seconds, or None while sim time has not started."""
        ns = self.clock.now_ns()
        return ns * 1e-9 if ns > 0 else None

    def _header_s(self, stamp: TimeMsg) -> Optional[float]:
        if stamp.sec == 0 and stamp.nanosec == 0:
            return self._now_s()
        return _stamp_s(stamp)

    def _start_view(self, address: tuple, p: Dict[str, object]) -> Optional[LiveView]:
        """
        Start the Foxglove view at ``address`` (host, port) with parameters ``p`` shown.

        An address in use is one error line and None: the node estimates without it.
        """
        host, port = address
        limits = {f'limits.{q}_C': v for q, v in self.est.limits_C.items()}
        alerts = {f'alerts.{r.quantity}.{k}': getattr(r, k) for r in self.est.alerts.rules
                  for k in ('warn_C', 'critical_C', 'hysteresis_K', 'min_duration_s', 'latch')}
        settable = {n: (PARAMETERS[n][1].floating_point_range[0].from_value,
                        PARAMETERS[n][1].floating_point_range[0].to_value)
                    for n in FOXGLOVE_SETTABLE}
        try:
            view = LiveView(host, port, estimates=interface.ESTIMATES, limited=LIMITED,
                            inputs=self.est.inputs, thermocouples=interface.THERMOCOUPLES,
                            inputs_rate_Hz=p['foxglove_inputs_rate_Hz'], prefix=self.prefix,
                            parameters={**p, **alerts, **limits}, settable=settable,
                            whatif_request_topic=self._topic(interface.WHATIF_REQUEST_TOPIC))
        except RuntimeError as exc:
            self.view_error = f'{host}:{port}: {exc}'
            self.get_logger().error(f'Foxglove view not started on {self.view_error}; '
                                    'estimating without it')
            return None
        self.get_logger().info(f'Foxglove view on {view.url}: open '
                               f'{app_url(host, view.port)}')
        return view

    def destroy_node(self) -> None:
        """Stop the Foxglove view and the what-if worker, then destroy the node."""
        if self.view is not None:
            self.view.close()
        self.whatif.close()
        super().destroy_node()

    def _failed(self, where: str, exc: BaseException) -> None:
        self.callback_errors[where] = self.callback_errors.get(where, 0) + 1
        self.get_logger().error(f'{where}: {type(exc).__name__}: {exc}',
                                throttle_duration_sec=5.0)

    def _input_failed(self, dec: inputs.TopicDecoder, exc: BaseException) -> None:
        """Count a failed input message against each input it carries; log it once."""
        for channel in dec.channels[1:]:
            self.callback_errors[channel] = self.callback_errors.get(channel, 0) + 1
        self._failed(dec.channels[0], exc)

    # ----------------------------------------------------------- callbacks
    def _on_input(self, dec: inputs.TopicDecoder, data: bytes) -> None:
        """Take a message of per-message samples: a Float64's stamped on arrival."""
        t_rx = time.perf_counter()
        try:
            stamp_ns, values = dec.decode(data)
            now_ns = self.clock.now_ns()
            if not stamp_ns:
                stamp_ns = now_ns          # no stamp, or a zero one: the clock
                if not stamp_ns:
                    self.waiting_for_clock += 1
                    return
            now = now_ns * 1e-9 if now_ns else None
            for channel, value in zip(dec.channels, values):
                self._take(channel, stamp_ns * 1e-9, value, now, t_rx)
        except Exception as exc:  # noqa: B902 - a callback never raises
            self._input_failed(dec, exc)

    def _on_batch(self, dec: inputs.TopicDecoder, data: bytes) -> None:
        """Take a batched block: every sample with its own stamp."""
        t_rx = time.perf_counter()
        try:
            stamps, values = dec.decode_batch(data)
            now = self._now_s()
            for k, channel in enumerate(dec.channels):
                self._take(channel, stamps, values[:, k], now, t_rx, self.est.take_many)
        except Exception as exc:  # noqa: B902
            self._input_failed(dec, exc)

    def _on_ambient(self, msg: Temperature) -> None:
        try:
            t = self._header_s(msg.header.stamp)
            if t is not None:
                self.est.add_ambient(t, float(msg.temperature))
        except Exception as exc:  # noqa: B902
            self._failed('ambient', exc)

    def _on_measured(self, name: str, msg: Temperature) -> None:
        try:
            t = self._header_s(msg.header.stamp)
            if t is not None:
                self.est.add_measured(name, t, float(msg.temperature))
        except Exception as exc:  # noqa: B902
            self._failed(f'measured/{name}', exc)

    def _on_recorder_health(self, msg: String) -> None:
        try:
            health = json.loads(msg.data)
            if isinstance(health, dict):
                self.view.offer_recorder(health)
        except Exception as exc:  # noqa: B902
            self._failed('recorder health', exc)

    def _on_whatif_request(self, msg: String) -> None:
        self._whatif_request(msg.data)

    def _whatif_request(self, text: str) -> None:
        """Start a what-if from the model as it is now, or answer at once why not."""
        try:
            est = self.est
            refused = self.whatif.submit(text, est.model if est.t_model is not None else None,
                                         est.ambient_K - C_TO_K, 'live estimator', est.t_model)
            if refused is not None:
                self._answer_whatif(refused)
        except Exception as exc:  # noqa: B902
            self._failed('whatif', exc)

    def _poll_whatif(self) -> None:
        """Take the view's what-if requests; publish the answer of one that finished."""
        try:
            for text in self.view.take_whatif_requests() if self.view is not None else ():
                self._whatif_request(text)
            answer = self.whatif.poll()
            if answer is not None:
                self._answer_whatif(answer)
        except Exception as exc:  # noqa: B902
            self._failed('whatif', exc)

    def _answer_whatif(self, answer: str) -> None:
        """Publish a what-if answer (JSON text), log it in a line, show it in the view."""
        self.whatif_pub.publish(String(data=answer))
        data = json.loads(answer)
        outcome = f"error: {data['error']}" if not data['ok'] else (
            f"{data['duty']}, {data['duration_s']:g} s in {data['wall_s']:.1f} s; time to "
            'limit: ' + ', '.join(f'{q} {"-" if t is None else f"{t:.0f} s"}'
                                  for q, t in data['time_to_limit_s'].items()))
        self.get_logger().info(f"what-if {data['id']!r}: {outcome}")
        if self.view is not None:
            self.view.offer_whatif(answer)

    def _on_ack(self, msg: String) -> None:
        try:
            quantity = msg.data.strip() or None
            try:
                events = self.est.acknowledge(quantity)
            except ValueError as exc:        # no rule for that quantity
                self.get_logger().warning(f'acknowledge {quantity!r} ignored: {exc}')
                return
            for e in events:
                self.get_logger().info(e.message)
            self._pending_events += [e.message for e in events]
            self._publish_alerts(force=True)
        except Exception as exc:  # noqa: B902
            self._failed('ack', exc)

    def _on_set_parameters(self, params) -> SetParametersResult:
        try:
            for param in params:
                if param.name == 'publish_rate_Hz':
                    self.publish_timer.timer_period_ns = int(1e9 / param.value)
                elif param.name == 'diagnostics_rate_Hz':
                    self.diag_timer.timer_period_ns = int(1e9 / param.value)
                elif param.name == 'background_budget_ms':
                    self.budget_s = param.value * 1e-3
                elif param.name == 'foxglove_inputs_rate_Hz' and self.view is not None:
                    self.view.inputs_rate_Hz = param.value
            if self.view is not None:
                self.view.show_parameters({q.name: q.value for q in params
                                           if q.name in PARAMETERS})
        except Exception as exc:  # noqa: B902
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _apply_view_requests(self) -> None:
        """Set the parameters Foxglove asked for, here on the node's thread, as ROS would."""
        for name, value in self.view.take_requests().items():
            result = self.set_parameters([Parameter(name, value=value)])[0]
            if not result.successful:
                self.get_logger().warning(f'Foxglove set {name} = {value:g}: refused: '
                                          f'{result.reason}')
                self.view.show_parameters({name: self.get_parameter(name).value})

    # ---------------------------------------------------------- publishing
    def _on_tick(self) -> None:
        """Step to the ROS clock (silent inputs go stale) and publish."""
        try:
            if self.view is not None:
                self._apply_view_requests()
            now = self._now_s()
            if now is None:
                return
            steady = time.monotonic()
            if self._tick_clock is not None and not self.clock.sim:
                ahead = (now - self._tick_clock[0]) - (steady - self._tick_clock[1])
                if ahead > self.cfg.estimator.clock_jump_s:
                    self.est.restart_time(now)      # the system clock was stepped forward
            self._tick_clock = (now, steady)
            t_model = self.est.t_model
            if t_model is not None and now - t_model < 2.0 * self.cfg.estimator.step_s:
                return          # the samples keep the model current: nothing to catch up
            self._step(now)
        except Exception as exc:  # noqa: B902
            self._failed('publish', exc)

    def _take(self, channel: str, stamp_s, value, now: Optional[float], t_rx: float,
              take=None) -> None:
        """
        Hand one sample to :meth:`Estimator.take`; publish the estimates it completes at once.

        ``now`` the ROS clock (s), ``t_rx`` the callback's start (perf_counter s);
        ``take``: :meth:`Estimator.take_many` for arrays of samples.
        A failure of the step is the model's (the node publishes on, see
        :meth:`_published`); one after the estimates were handed over, the slow
        work's; one before the step, the callback's (it propagates).
        """
        jumps = self.est.clock_jumps
        handed = []

        def publish(estimates: List[Estimate]) -> None:
            handed.append(True)
            self.model_failing = False
            self._published(estimates, now, t_rx, jumps)

        try:
            (take or self.est.take)(channel, stamp_s, value, now, publish=publish,
                                    budget_s=self.budget_s)
        except StepFailed as exc:
            self._model_failed(exc.__cause__)
            self._published([], now, t_rx, jumps)
        except Exception as exc:  # noqa: B902 - the slow work never stops the node
            if not handed:
                raise
            self._background_failed(exc)
        if handed:
            self._publish_limits()

    def _model_failed(self, exc: BaseException) -> None:
        self.model_errors += 1
        self.model_error = f'{type(exc).__name__}: {exc}'
        self.model_failing = True
        self.get_logger().error(f'model step failed: {self.model_error}',
                                throttle_duration_sec=5.0)

    def _background_failed(self, exc: BaseException) -> None:
        self.background_errors += 1
        self.get_logger().error(f'forecast/margin failed: {type(exc).__name__}: {exc}',
                                throttle_duration_sec=5.0)

    def _step(self, now: Optional[float]) -> None:
        """
        Step the model as far as the clock ``now`` allows and publish (the publish timer).

        The timer keeps the estimator going when the samples stop; then the
        slow work (:meth:`Estimator.prepare`, :meth:`Estimator.background`), as
        :meth:`Estimator.take` does after a sample that completed a step.
        """
        estimates: List[Estimate] = []
        jumps = self.est.clock_jumps
        try:
            estimates = self.est.advance(now)
            self.model_failing = False
        except Exception as exc:  # noqa: B902 - the model should not raise; never stop
            self._model_failed(exc)
        self._published(estimates, now, None, jumps)
        if not estimates:
            return
        try:
            self.est.prepare()
            if self.budget_s > 0.0:
                self.est.background(self.budget_s)
        except Exception as exc:  # noqa: B902 - the next step redoes it
            self._background_failed(exc)
        self._publish_limits()

    def _publish_limits(self) -> None:
        """
        Publish the current limits finished since the last call, oldest first.

        A tick waiting longer than ``estimator.limits.max_age_s`` of model
        time is given up (its fallback goes out instead); while the model
        itself is behind its inputs, a finished tick's limits are for a state
        already past, and go out as the fallback too.
        """
        try:
            lim = self.cfg.estimator.limits
            for limits in self.est.outlook.take_limits(self.est.t_model):
                if self.est.behind and limits.status == 'ok':
                    limits = limits.fallback(lim.fallback_current_A,
                                             'behind: the model is catching up with its inputs')
                self._send_limits(limits)
        except Exception as exc:  # noqa: B902
            self._failed('publish', exc)

    def _send_limits(self, limits: CurrentLimits) -> None:
        """Publish ``limits``: the JointState of every horizon, the binding Float64, the layout."""
        msg = self._limits_msg
        msg.header.stamp = _stamp_msg(int(round(limits.stamp_s * 1e9)))
        msg.header.frame_id = interface.limits_frame_id(limits.status, limits.reason)
        msg.name = list(limits.names)
        msg.position = list(limits.horizons_s)
        msg.effort = list(limits.limits_A)
        self.limits_pub.publish(msg)
        self.limit_pub.publish(Float64(data=float(limits.binding_A)))
        self.limits_published += 1
        shortest = min(range(len(limits.horizons_s)), key=limits.horizons_s.__getitem__)
        drive = interface.DriveLimits(
            stamp_ns=int(round(limits.stamp_s * 1e9)), sequence=self.limits_published,
            status=interface.limit_status(limits.status, limits.reason),
            binding_A=limits.binding_A, binding_horizon_s=limits.horizons_s[shortest],
            horizons_s=limits.horizons_s, limits_A=limits.limits_A)
        arr = Float64MultiArray(data=drive.to_data())
        arr.layout.dim = [MultiArrayDimension(label=drive.LABEL, size=len(arr.data),
                                              stride=len(arr.data))]
        self.drive_limits_pub.publish(arr)
        self.limits_fallback += limits.status != 'ok'

    def _published(self, estimates: List[Estimate], now: Optional[float],
                   t_rx: Optional[float], jumps: int) -> None:
        """
        Publish what a step made: the last estimate, the state, alerts, events, the view.

        With no estimate while the model fails, the last good one again,
        stamped ``now``; ``jumps``: the estimator's clock jumps before the step.
        ``t_rx`` is the callback's start (perf_counter s), for the latency figures.
        """
        try:
            if self.est.clock_jumps != jumps:
                self._last_ns = None         # the estimates' stamps start over with the clock
            for e in estimates:
                for text in e.notices:
                    self.get_logger().warning(text)
                    self._pending_events.append(text)
                for ev in e.alert_events:
                    log = self.get_logger().warning if ev.kind in ('raised', 'escalated') \
                        else self.get_logger().info
                    log(ev.message)
                    self._pending_events.append(ev.message)
            if estimates:
                self._publish_estimate(estimates[-1], estimates[-1].stamp_s)
                if t_rx is not None:
                    self.latency_ms.append((time.perf_counter() - t_rx) * 1e3)
                self._publish_state()
            elif self.model_failing and self._last_published is not None and now is not None:
                # keep the consumers alive on the last good estimate, stamped now
                if self._publish_estimate(self._last_published, now):
                    self._publish_state()
            if estimates or now is not None:
                self._publish_alerts()
            if estimates and self.view is not None:
                # after everything ROS gets: the view never delays an estimate
                self.view.offer(estimates[-1], dict(self.est.measured_C))
        except Exception as exc:  # noqa: B902
            self._failed('publish', exc)

    def _publish_estimate(self, est: Estimate, stamp_s: float) -> bool:
        """Publish the temperatures of ``est`` stamped ``stamp_s``; return whether they went."""
        ns = int(round(stamp_s * 1e9))
        if self._last_ns is not None and ns <= self._last_ns:
            return False                # never the same or an older stamp twice
        self._last_ns = ns
        self._last_published = est
        stamp = _stamp_msg(ns)
        msg = self._temperature_msg          # publish() copies it: one object will do
        msg.header.stamp = stamp
        for name, pub in self.estimate_pubs.items():
            msg.temperature = float(est.temperatures_C[name])
            msg.variance = float(est.uncertainty_K[name]) ** 2
            pub.publish(msg)
        self.published += 1
        return True

    def _publish_state(self) -> None:
        """Publish the model's state vector (after the estimates: no consumer waits on it)."""
        state = self.est.model.state
        arr = Float64MultiArray()
        arr.layout.dim = [MultiArrayDimension(label=self._state_label, size=state.size,
                                              stride=state.size)]
        arr.data = state.astype(float).tolist()
        self.state_pub.publish(arr)

    def _publish_alerts(self, force: bool = False) -> None:
        """Publish the alert summary (latched) when its levels or acknowledgements change."""
        summary = self.est.alerts.summary()
        gaps = self.est.gaps
        key = (int(summary['level']), gaps.open_since_s) + tuple(
            (q, d['reported'], d['active'], d['acknowledged'])
            for q, d in sorted(summary['quantities'].items()))
        if not force and key == self._alert_key and not self._pending_events:
            return
        self._alert_key = key
        summary['level'] = int(summary['level'])
        summary['hardware_id'] = self.hardware_id
        # the estimates of a data gap run on held inputs: say so beside the alerts
        summary['data_gaps'] = {'count': gaps.count, 'longest_s': gaps.longest_s,
                                'total_s': gaps.total_s, 'open_since_s': gaps.open_since_s,
                                'last': list(gaps.last) if gaps.last else None}
        summary['clock_jumps'] = self.est.clock_jumps
        summary['events'] = self._pending_events
        self._pending_events = []
        data = _json_safe(summary)
        self.alert_pub.publish(String(data=json.dumps(data)))
        if self.view is not None:
            self.view.offer_alerts(data)

    # --------------------------------------------------------- diagnostics
    def _on_diagnostics(self) -> None:
        try:
            now_ns = self.get_clock().now().nanoseconds
            est = self.est
            new_rejected = {n: est.health[n].rejected - self._diag_prev[n] for n in est.inputs}
            self._diag_prev = {n: est.health[n].rejected for n in est.inputs}
            implausible = sum(est.implausible_counts.values())
            new_implausible = implausible - self._implausible_prev
            self._implausible_prev = implausible
            counters = diagnostics.NodeCounters(
                hardware_id=self.hardware_id, published=self.published,
                model_errors=self.model_errors,
                model_error=self.model_error if self.model_failing else None,
                background_errors=self.background_errors,
                callback_errors=dict(self.callback_errors),
                waiting_for_clock=self.waiting_for_clock, latency_ms=self.latency_ms,
                view=self._view_text())
            arr = DiagnosticArray()
            arr.header.stamp = _stamp_msg(now_ns)
            arr.status = [
                DiagnosticStatus(level=bytes([s.level]), name=f'wet_eha_thermal: {s.name}',
                                 message=s.message, hardware_id=self.hardware_id,
                                 values=[KeyValue(key=k, value=str(v)) for k, v in s.values])
                for s in diagnostics.statuses(est, counters, now_ns * 1e-9, self.topic_names,
                                              new_rejected, new_implausible)]
            self.diag_pub.publish(arr)
            if self.view is not None:
                self.view.offer_health({n: (h.received, h.rejected)
                                        for n, h in est.health.items()})
        except Exception as exc:  # noqa: B902
            self._failed('diagnostics', exc)

    def _view_text(self) -> str:
        """Return the Foxglove view's state in words, for the diagnostics."""
        v = self.view
        if v is None:
            return f'not started: {self.view_error}' if self.view_error else 'off'
        text = (f'{v.url}, {len(v.watched())} channels watched; {v.shown} of {v.offered} '
                'estimates shown')
        return text + (f'; {v.errors} errors (last: {v.last_error})' if v.errors else '')

    def report(self) -> interface.NodeReport:
        """Return the run's counts as data: per input, estimates, gaps, errors."""
        inputs = {}
        for name in self.est.inputs:
            h = self.est.health[name]
            inputs[name] = interface.InputCounts(h.received, h.accepted, h.rejected,
                                                 h.stale_events)
        g = self.est.gaps
        return interface.NodeReport(node=NODE_NAME, inputs=inputs, figures={
            'estimates': self.published, 'steps': self.est.steps, 'data_gaps': g.count,
            'longest_gap_s': g.longest_s, 'clock_jumps': self.est.clock_jumps,
            'callback_errors': sum(self.callback_errors.values()),
            'model_errors': self.model_errors, 'limits_published': self.limits_published,
            'limits_fallback': self.limits_fallback,
            'limit_ticks_behind': self.est.outlook.limits_behind})

    def summary(self) -> str:
        """Return a one-line account of the run for a log: samples per input, gaps, jumps."""
        r = self.report()
        f = r.figures
        parts = [f'{name} {c.received} received, {c.accepted} accepted, {c.rejected} '
                 f'rejected, {c.stale_events} stale events' for name, c in r.inputs.items()]
        return (f'estimator summary: {f["estimates"]} estimates, {f["steps"]} steps; '
                + '; '.join(parts) + f'; data gaps {f["data_gaps"]} (longest '
                f'{f["longest_gap_s"]:.1f} s); clock jumps {f["clock_jumps"]}; callback errors '
                f'{f["callback_errors"]}, model errors {f["model_errors"]}')


_DESCRIPTION = ('Live thermal estimator of the wet EHA (ROS 2 node). ROS arguments follow '
                '--ros-args, e.g. --ros-args --params-file config/estimator.params.yaml '
                '-p publish_rate_Hz:=20 -p use_sim_time:=true')


def main(args: Optional[List[str]] = None) -> int:
    """Run the estimator node until Ctrl-C or shutdown; return the exit status."""
    def close(node: EstimatorNode) -> int:
        print(node.summary(), file=sys.stderr, flush=True)
        node.report().write(sys.stdout)
        return 0

    return run_node(args, 'wet-eha-thermal-estimator', _DESCRIPTION, EstimatorNode,
                    (ConfigError, NameValidationException, ParameterException, ValueError),
                    log_executor=True, close=close)


if __name__ == '__main__':
    sys.exit(main())
