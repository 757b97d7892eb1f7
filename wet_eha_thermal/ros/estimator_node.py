"""
The live estimator as a ROS 2 node: sensor topics in; estimates, diagnostics and alerts out.

The node keeps the parameters, the subscriptions and the publishers; one
:class:`~wet_eha_thermal.estimator.session.EstimatorSession` decides what goes
out, :mod:`wet_eha_thermal.messages` builds the messages (the bytes a replay
writes for the same estimates) and the node publishes them. A sample's path is
one way down and back: callback -> ``session.take`` (``take_many`` for a
batched block) -> the session's ``publish`` -> :meth:`EstimatorNode._publish`
-> the publishers.

The input topics, as the ``inputs_file`` declares them
(:mod:`wet_eha_thermal.inputs`: Float64, FluidPressure, Temperature, JointState
by joint and field, or a batched block), are taken raw (CDR bytes), one
subscription per topic, and decoded in place; each sample, converted to SI,
goes to the session with its stamp (a Float64 has none: it takes the node's
ROS clock, so /clock under use_sim_time), and that is all the per-sample work;
a batched block goes in as arrays. A sample that can complete a model step
steps it at once, so the estimate leaves within the step's computing time. A
timer at ``publish_rate_Hz`` calls the session's ``tick`` with the ROS clock,
so the model keeps stepping on its fallbacks when inputs fall silent. No call
steps more than ``estimator.max_steps_per_call`` steps: after a stall the model
catches up over several calls. Each new estimate is published: one
sensor_msgs/Temperature per name in ``interface.ESTIMATES`` (stamped with the
estimate's sample time, strictly increasing), the state vector, and the alert
summary whenever it changes (latched). The rest of each tick's budget
(``background_budget_ms``) goes to the limits, the forecast and the margin;
each tick's limits go out as the JointState, the binding Float64 and the
drive's numbers (``/eha/drive/limits``, :class:`~wet_eha_thermal.interface.DriveLimits`).
The ambient temperature and the thermocouples are declared in the same file
(by default sensor_msgs/Temperature in degC on ``/eha/ambient`` and
``/eha/measured/<tc>``) and go to the session in degC: with the live
correction on the thermocouples correct the model, and /diagnostics carries
one status per thermocouple (used, held, dropped or stale).

Time: samples stamped more than ``estimator.max_future_s`` ahead of the clock
are rejected; the clock going back by more than ``estimator.clock_jump_s``
re-starts the model time; without sim time, the ROS clock moving ahead of the
steady clock by more than that between two ticks (the system clock stepped)
re-starts it too, so that the model never steps across a jump. Under sim time
a leap forward of /clock is taken as elapsed time. Data gaps (every input
silent) and clock jumps are logged, listed in the alert summary's events and
counted in /diagnostics.

Once the model is compiled and warmed and every input subscription has
matched a publisher, the node says so on ``/eha/ready`` (latched); the
simulated rig waits for that. A second timer publishes /diagnostics. No
callback ever raises: a failure is logged, counted and shown in the
diagnostics. At shutdown one summary line (samples received and rejected per
input, gaps, clock jumps) goes to stderr for people, and the same counts as
data (an :class:`~wet_eha_thermal.interface.NodeReport` line) to stdout.

With ``foxglove_address`` (HOST:PORT) the node also serves the Foxglove view
(:mod:`.estimator_view`); what-ifs are served by :mod:`.whatif_service`.

Run it with ``wet-eha-thermal-estimator --ros-args --params-file
config/estimator.params.yaml`` or ``python -m wet_eha_thermal.ros.estimator_node``.
"""

from collections import deque
import functools
import gc
import sys
import time
from typing import Deque, Dict, List, Optional

from builtin_interfaces.msg import Time as TimeMsg
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import SetParametersResult
from rclpy.exceptions import NameValidationException, ParameterException
from rclpy.node import Node
from rclpy.qos import QoSProfile
from sensor_msgs.msg import JointState, Temperature
from std_msgs.msg import Float64, Float64MultiArray, String
from wet_eha_thermal import inputs, interface, messages
from wet_eha_thermal.config import ConfigError, load_config
from wet_eha_thermal.estimator.session import EstimatorSession, Output
from wet_eha_thermal.live_view import parse_address
from wet_eha_thermal.ros import diagnostics, topics
from wet_eha_thermal.ros.estimator_view import EstimatorView, FOXGLOVE_SETTABLE
from wet_eha_thermal.ros.runtime import (declare_parameters, descriptor, FastClock,
                                         prepare_model_step, Readiness, run_node,
                                         shared_parameters)
from wet_eha_thermal.ros.whatif_service import WhatIfService
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
    'publish_rate_Hz': (50.0, descriptor(
        'rate of the estimate, state and alert publication (and of advance(now))', 1.0, 500.0,
        read_only=False)),
    'background_budget_ms': (2.0, descriptor(
        'wall time per publish tick given to the forecast and the margin', 0.0, 50.0,
        read_only=False)),
    'diagnostics_rate_Hz': (1.0, descriptor('rate of /diagnostics', 0.1, 10.0, read_only=False)),
    'frame_id': ('eha', descriptor('frame_id of the published temperatures')),
    **shared_parameters('qos', 'qos_depth', 'topic_prefix', 'hardware_id', 'executor'),
    'foxglove_address': ('', descriptor(
        'Foxglove WebSocket server of the live view (wet_eha_thermal/live_view.py), HOST:PORT, '
        "e.g. 127.0.0.1:8765 (port 0: any free one); '' = no server")),
    'foxglove_inputs_rate_Hz': (20.0, descriptor(
        'rate of the inputs, input health and thermocouples in the Foxglove view (averaged '
        'over windows of sample time)', 1.0, 50.0, read_only=False)),
}


def _stamp_msg(ns: int) -> TimeMsg:
    return TimeMsg(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


class EstimatorNode(Node):
    """Thermal estimator node: subscribes to the rig's sensors, publishes estimates."""

    def __init__(self, **kwargs) -> None:
        super().__init__(NODE_NAME, **kwargs)
        p, view_at = self._read_parameters()
        self.cfg = load_config(p['config_file'] or None)
        input_spec = inputs.load_inputs(p['inputs_file'])
        self.hardware_id = p['hardware_id']
        self._status_name = functools.partial(interface.status_name, node=self.get_name(),
                                              namespace=self.get_namespace())
        self.session = EstimatorSession(self.cfg, outlook='background', publish=self._publish,
                                        budget_s=p['background_budget_ms'] * 1e-3,
                                        hardware_id=self.hardware_id)
        # before any subscription or publisher: a first step that compiled would keep
        # samples waiting for a minute or more
        prepare_model_step(self, self.cfg, estimator=True)
        # the model and the uncertainty's copies live as long as the node: out of the
        # collector's sight, a full collection walks the messages only (with them, about
        # 100 ms inside a sample's callback)
        gc.collect()
        gc.freeze()
        self.clock = FastClock(self)
        self.prefix = p['topic_prefix']        # resolved: '' is the namespace
        in_qos = topics.input_qos(p['qos'], p['qos_depth'])   # ValueError names a bad kind
        self._init_counters()
        self.messages = messages.OutputMessages(p['frame_id'], messages.state_label(
            self._topic(interface.STATE_NAMES_TOPIC)))
        input_subs = self._subscribe(in_qos, input_spec)
        self._advertise(QoSProfile(depth=10))       # reliable, volatile
        self.view = EstimatorView(self, self.session, self._topic, self._failed)
        if view_at is not None:
            self.view.start(view_at, p, {n: (PARAMETERS[n][1].floating_point_range[0].from_value,
                                             PARAMETERS[n][1].floating_point_range[0].to_value)
                                         for n in FOXGLOVE_SETTABLE}, self.prefix)
        self.whatif = WhatIfService(self, self.session, self._topic, self.view.view, self._failed)
        self.publish_timer = self.create_timer(1.0 / p['publish_rate_Hz'], self._on_tick)
        self.diag_timer = self.create_timer(1.0 / p['diagnostics_rate_Hz'], self._on_diagnostics)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.session.announce()
        self.readiness = Readiness(self, self._topic(interface.READY_TOPIC), input_subs,
                                   self.hardware_id, require_all=True,
                                   extra={'foxglove': self.view.view.url if self.view.view
                                          else None, 'foxglove_error': self.view.error})
        self.get_logger().info(
            f"estimating {len(interface.ESTIMATES)} temperatures at {p['publish_rate_Hz']:g} Hz "
            f"from {self.prefix or '/'}/* ({p['qos']} QoS, depth {p['qos_depth']}); config "
            f"{p['config_file'] or 'reference_eha.yaml (shipped)'}")

    def _read_parameters(self) -> tuple:
        """Declare and read the parameters; return them and the view's address (or None)."""
        p = declare_parameters(self, PARAMETERS)
        view_at = None         # checked before the model's slow start
        if p['foxglove_address']:
            try:
                view_at = parse_address(p['foxglove_address'])
            except ValueError as exc:
                raise ValueError(f'parameter foxglove_address = {exc}') from None
        return p, view_at

    def _init_counters(self) -> None:
        """Zero the counters the diagnostics report besides the session's."""
        self.callback_errors: Dict[str, int] = {}
        self.waiting_for_clock = 0
        # callback start of the sample that closed a step -> its estimate published (ms)
        self.latency_ms: Deque[float] = deque(maxlen=3000)
        self._t_rx: Optional[float] = None      # the running callback's start (perf_counter)
        # rejected counts at the last diagnostics
        self._diag_prev = dict.fromkeys(self.session.inputs, 0)
        self._implausible_prev = 0
        # the topic of every input and of every thermocouple (measured/<name>), as subscribed
        self.topic_names: Dict[str, str] = {}

    def _subscribe(self, in_qos: QoSProfile, input_spec: inputs.Inputs) -> list:
        """Subscribe to the inputs (raw), the ambient, the thermocouples and the acks."""
        # inputs, raw: decoded here in a fraction of rclpy's deserialisation; one
        # subscription per topic, whatever number of inputs it carries
        # the ambient and the thermocouples too: a temperature in K, taken in degC
        s = self.session
        self._takers = {name: functools.partial(s.take, name) for name in s.inputs}
        self._takers[inputs.AMBIENT] = lambda t, v, now: s.add_ambient(t, v - C_TO_K)
        for tc in interface.THERMOCOUPLES:
            self._takers[inputs.thermocouple_channel(tc)] = functools.partial(
                lambda name, t, v, now: s.add_measured(name, t, v - C_TO_K), tc)
        input_subs = []
        for dec in inputs.decoders(input_spec, list(self._takers)):
            topic = self._topic(dec.topic)
            cb = functools.partial(self._on_batch if dec.batched else self._on_input, dec)
            kind = topics.message_class(dec.message_type)
            sub = self.create_subscription(kind, topic, cb, in_qos, raw=True)
            if any(c in s.inputs for c in dec.channels):
                input_subs.append(sub)
            self.topic_names.update(dict.fromkeys(dec.channels, topic))
        self.create_subscription(String, self._topic(interface.ACK_TOPIC), self._on_ack,
                                 QoSProfile(depth=10))
        return input_subs

    def _advertise(self, out_qos: QoSProfile) -> None:
        """Create the publishers: estimates, state, its names (latched), alerts, limits."""
        pubs = {topic: (Temperature, out_qos) for topic in messages.ESTIMATE_TOPICS}
        pubs[interface.STATE_TOPIC] = (Float64MultiArray, out_qos)
        pubs[interface.ALERT_TOPIC] = (String, topics.latched_qos())
        # the drive's limits: reliable, a few deep (a drive reads every one it can)
        pubs[interface.CURRENT_LIMITS_TOPIC] = (JointState, QoSProfile(depth=10))
        pubs[interface.CURRENT_LIMIT_TOPIC] = (Float64, QoSProfile(depth=10))
        # the same limits for a drive that reads numbers only (interface.DriveLimits)
        pubs[interface.DRIVE_LIMITS_TOPIC] = (Float64MultiArray, QoSProfile(depth=10))
        #: the publisher of each topic, by its name without the prefix
        self.pubs = {topic: self.create_publisher(cls, self._topic(topic), qos)
                     for topic, (cls, qos) in pubs.items()}
        # the name of each element of the state, once and latched: they do not change in a run
        self.state_names_pub = self.create_publisher(
            String, self._topic(interface.STATE_NAMES_TOPIC), topics.latched_qos())
        self.state_names_pub.publish(messages.state_names(
            self.session.model.quantities.state_names))
        self.diag_pub = self.create_publisher(DiagnosticArray, interface.DIAGNOSTICS_TOPIC,
                                              QoSProfile(depth=10))

    # ------------------------------------------------------------- helpers
    def _topic(self, name: str) -> str:
        """Return ``name`` with the topic prefix in place of interface.PREFIX."""
        return interface.prefixed(name, self.prefix)

    def _now_s(self) -> Optional[float]:
        """Return the ROS clock in seconds, or None while sim time has not started."""
        ns = self.clock.now_ns()
        return ns * 1e-9 if ns > 0 else None

    def destroy_node(self) -> None:
        """Stop the Foxglove view and the what-if worker, then destroy the node."""
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
        self._t_rx = time.perf_counter()
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
                self._takers[channel](stamp_ns * 1e-9, value, now)
        except Exception as exc:  # noqa: B902 - a callback never raises
            self._input_failed(dec, exc)

    def _on_batch(self, dec: inputs.TopicDecoder, data: bytes) -> None:
        """Take a batched block: every sample with its own stamp."""
        self._t_rx = time.perf_counter()
        try:
            stamps, values = dec.decode_batch(data)
            now = self._now_s()
            for k, channel in enumerate(dec.channels):
                if channel in self.session.inputs:
                    self.session.take_many(channel, stamps, values[:, k], now)
                else:               # a temperature in a block: rare, sample by sample
                    for t, v in zip(stamps.tolist(), values[:, k].tolist()):
                        self._takers[channel](t, v, now)
        except Exception as exc:  # noqa: B902
            self._input_failed(dec, exc)

    def _on_ack(self, msg: String) -> None:
        try:
            quantity = msg.data.strip() or None
            try:
                self.session.acknowledge(quantity)
            except ValueError as exc:        # no rule for that quantity
                self.get_logger().warning(f'acknowledge {quantity!r} ignored: {exc}')
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
                    self.session.budget_s = param.value * 1e-3
                elif param.name == 'foxglove_inputs_rate_Hz' and self.view.view is not None:
                    self.view.view.inputs_rate_Hz = param.value
            self.view.show_parameters({q.name: q.value for q in params if q.name in PARAMETERS})
        except Exception as exc:  # noqa: B902
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _on_tick(self) -> None:
        """Step to the ROS clock (silent inputs go stale) and publish."""
        self._t_rx = None
        try:
            self.view.apply_requests()
            now = self._now_s()
            if now is not None:
                # under sim time a leap of /clock is elapsed time, not a stepped clock
                self.session.tick(now, None if self.clock.sim else time.monotonic())
        except Exception as exc:  # noqa: B902
            self._failed('publish', exc)

    # ---------------------------------------------------------- publishing
    def _publish(self, out: Output) -> None:
        """Publish what the session made (its ``publish``): log, messages, then the view."""
        try:
            log = self.get_logger()
            for level, text in out.log:
                # one call site per severity: rclpy refuses to change it at a call site
                if level == 'error':
                    log.error(text, throttle_duration_sec=5.0)
                elif level == 'warning':
                    log.warning(text)
                else:
                    log.info(text)
            for topic, data, _ in self.messages.build(out):
                self.pubs[topic].publish(data)
            if out.estimates and self._t_rx is not None:
                self.latency_ms.append((time.perf_counter() - self._t_rx) * 1e3)
            # after everything ROS gets: the view never delays an estimate
            self.view.offer(out)
        except Exception as exc:  # noqa: B902
            self._failed('publish', exc)

    # --------------------------------------------------------- diagnostics
    def _on_diagnostics(self) -> None:
        try:
            now_ns = self.get_clock().now().nanoseconds
            s = self.session
            new_rejected = {n: s.health[n].rejected - self._diag_prev[n] for n in s.inputs}
            self._diag_prev = {n: s.health[n].rejected for n in s.inputs}
            implausible = sum(s.implausible_counts.values())
            new_implausible = implausible - self._implausible_prev
            self._implausible_prev = implausible
            counters = diagnostics.NodeCounters(
                hardware_id=self.hardware_id, published=self.messages.published,
                model_errors=s.model_errors,
                model_error=s.model_error if s.model_failing else None,
                background_errors=s.background_errors, callback_errors=dict(self.callback_errors),
                waiting_for_clock=self.waiting_for_clock, latency_ms=self.latency_ms,
                view=self.view.text())
            arr = DiagnosticArray()
            arr.header.stamp = _stamp_msg(now_ns)
            arr.status = [
                DiagnosticStatus(level=bytes([d.level]), name=self._status_name(d.name),
                                 message=d.message, hardware_id=self.hardware_id,
                                 values=[KeyValue(key=k, value=str(v)) for k, v in d.values])
                for d in diagnostics.statuses(s, counters, now_ns * 1e-9, self.topic_names,
                                              new_rejected, new_implausible)]
            self.diag_pub.publish(arr)
            self.view.offer_health()
        except Exception as exc:  # noqa: B902
            self._failed('diagnostics', exc)

    def report(self) -> interface.NodeReport:
        """Return the run's counts as data: per input, estimates, gaps, errors."""
        s = self.session
        inputs = {name: interface.InputCounts(h.received, h.accepted, h.rejected,
                                              h.stale_events) for name, h in s.health.items()}
        return interface.NodeReport(node=NODE_NAME, inputs=inputs, figures={
            'estimates': self.messages.published, 'steps': s.steps, 'data_gaps': s.gaps.count,
            'longest_gap_s': s.gaps.longest_s, 'clock_jumps': s.clock_jumps,
            'callback_errors': sum(self.callback_errors.values()),
            'model_errors': s.model_errors, 'limits_published': s.limits_published,
            'limits_fallback': s.limits_fallback,
            'limit_ticks_behind': s.outlook_counts['limits_behind']})

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
