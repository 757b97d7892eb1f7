"""
The estimator's wiring on a node: what the plain node starts at once and a managed one on activate.

An :class:`EstimatorRunner` is made from the node's parameters (configure:
the configuration and the inputs file loaded and checked, the session made,
the compiled model loaded and warmed); :meth:`~EstimatorRunner.start`
creates the subscriptions, publishers and timers (activate), and
:meth:`~EstimatorRunner.stop` sends the drive's last limits as the fallback
and removes them again (deactivate). The plain node
(:class:`~.estimator_node.EstimatorNode`) makes one and starts it; the
managed node (:class:`~.estimator_node.ManagedEstimatorNode`) does it step by
step, so the two cannot drift apart.

One :class:`~wet_eha_thermal.estimator.session.EstimatorSession` decides what
goes out, :mod:`wet_eha_thermal.messages` builds the messages (the bytes a
replay writes for the same estimates) and the runner publishes them. A
sample's path is one way down and back: callback -> ``session.take``
(``take_many`` for a batched block) -> the session's ``publish`` ->
:meth:`EstimatorRunner._publish` -> the publishers.

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
summary whenever it changes (latched; as JSON and as the drive's numbers on
``/eha/drive/alerts``, :class:`~wet_eha_thermal.interface.DriveAlerts`). The rest
of each tick's budget (``background_budget_ms``) goes to the limits, the forecast and the margin;
each tick's limits go out as the JointState, the binding Float64 and the
drive's numbers (``/eha/drive/limits``, :class:`~wet_eha_thermal.interface.DriveLimits`).
Every publisher takes its message type and QoS from ``interface.topic_table``,
as the recorder and the bag writers do.
The ambient temperature and the thermocouples are declared in the same file
(by default sensor_msgs/Temperature in degC on ``/eha/ambient`` and
``/eha/measured/<tc>``) and go to the session in degC: with the live
correction on the thermocouples correct the model, and /diagnostics carries
one status per thermocouple (used, held, dropped or stale).

Once every input subscription has matched a publisher, the runner says so on
``/eha/ready`` (latched); the simulated rig waits for that. A second timer
publishes /diagnostics, whose statuses :mod:`.diagnostics` makes from the
session's :meth:`~wet_eha_thermal.estimator.session.EstimatorSession.status`.
No callback ever raises: a failure is logged, counted and shown in the
diagnostics. With ``foxglove_address`` (HOST:PORT) the runner also serves the
Foxglove view (:mod:`.estimator_view`); what-ifs are served by
:mod:`.whatif_service`.
"""

from collections import deque
import functools
import gc
import time
from typing import Deque, Dict, Optional

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import SetParametersResult
from rclpy.duration import Duration
from rclpy.node import Node
from std_msgs.msg import String
from wet_eha_thermal import inputs, interface, messages
from wet_eha_thermal.config import load_config
from wet_eha_thermal.estimator.session import EstimatorSession, Output
from wet_eha_thermal.ros import diagnostics, topics
from wet_eha_thermal.ros.estimator_view import EstimatorView
from wet_eha_thermal.ros.runtime import FastClock, prepare_model_step, Readiness
from wet_eha_thermal.ros.whatif_service import WhatIfService
from wet_eha_thermal.units import C_TO_K

#: The limits' topics: a stopping runner waits until their last message is acknowledged...
LIMIT_TOPICS = (interface.CURRENT_LIMITS_TOPIC, interface.CURRENT_LIMIT_TOPIC,
                interface.DRIVE_LIMITS_TOPIC)
#: ... for at most this long (s)
LAST_LIMITS_WAIT_S = 1.0
#: A closing runner waits as long (s) at most for every output's last messages: a reader on
#: a busy machine is repaired on the writer's heartbeat (Fast DDS: every 3 s); under live's
#: 15 s from SIGINT to SIGTERM (live_children.SIGINT_WAIT_S). (The unequal counts of a live
#: recording once put on this wait were messages lost mid-run: see topics.OUTPUT_DEPTH)
LAST_MESSAGES_WAIT_S = 4.0


class EstimatorRunner:
    """
    The estimator on ``node``: its session (made here) and, once started, its ROS wiring.

    ``p``: the node's parameters (``estimator_node.PARAMETERS``, read);
    ``view_at``: the Foxglove view's (host, port), or None; ``ranges``: each
    Foxglove-settable parameter's (low, high). Raises ConfigError or
    ValueError for a bad configuration or inputs file.
    """

    def __init__(self, node: Node, p: Dict[str, object], view_at, ranges) -> None:
        self.node, self.p, self._view_at, self._ranges = node, p, view_at, ranges
        self.cfg = load_config(p['config_file'] or None)
        self.input_spec = inputs.load_inputs(p['inputs_file'])
        self.hardware_id = p['hardware_id']
        self.prefix = p['topic_prefix']        # resolved: '' is the namespace
        self.in_qos = topics.input_qos(p['qos'], p['qos_depth'])  # ValueError names a bad kind
        self.session = EstimatorSession(self.cfg, outlook='background', publish=self._publish,
                                        budget_s=p['background_budget_ms'] * 1e-3,
                                        hardware_id=self.hardware_id)
        # before any subscription or publisher: a first step that compiled would keep
        # samples waiting for a minute or more
        prepare_model_step(node, self.cfg, estimator=True)
        # the model and the uncertainty's copies live as long as the node: out of the
        # collector's sight, a full collection walks the messages only (with them, about
        # 100 ms inside a sample's callback)
        gc.collect()
        gc.freeze()
        self.messages = messages.OutputMessages(p['frame_id'], messages.state_label(
            self._topic(interface.STATE_NAMES_TOPIC)))
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
        #: the publisher of each topic, by its name without the prefix; empty when stopped
        self.pubs: Dict[str, object] = {}
        self.view = EstimatorView(node, self.session, self._topic, self._failed)
        self.whatif: Optional[WhatIfService] = None
        self._made: Optional[Dict[str, set]] = None     # the node's entities before start

    # ------------------------------------------------------- start and stop
    @property
    def started(self) -> bool:
        """Tell whether the runner subscribes and publishes."""
        return self._made is not None

    def start(self) -> None:
        """Subscribe, advertise, start the timers, the view and the what-if service."""
        node, p = self.node, self.p
        self._made = {kind: set(getattr(node, kind)) for kind in
                      ('publishers', 'subscriptions', 'timers')}
        self.clock = FastClock(node)
        input_subs = self._subscribe()
        self._advertise()
        if self._view_at is not None:
            self.view.start(self._view_at, p, self._ranges, self.prefix)
        if p['whatif']:
            self.whatif = WhatIfService(node, self.session, self._topic, self.view.view,
                                        self._failed)
        self.publish_timer = node.create_timer(1.0 / p['publish_rate_Hz'], self._on_tick)
        self.diag_timer = node.create_timer(1.0 / p['diagnostics_rate_Hz'],
                                            self._on_diagnostics)
        self.session.announce()
        self.readiness = Readiness(node, self._topic(interface.READY_TOPIC), input_subs,
                                   self.hardware_id, require_all=True,
                                   extra={'foxglove': self.view.view.url if self.view.view
                                          else None, 'foxglove_error': self.view.error})
        node.get_logger().info(
            f"estimating {len(interface.ESTIMATES)} temperatures at {p['publish_rate_Hz']:g} Hz "
            f"from {self.prefix or '/'}/* ({p['qos']} QoS, depth {p['qos_depth']}); config "
            f"{p['config_file'] or 'reference_eha.yaml (shipped)'}")

    def stop(self, why: str) -> None:
        """
        Send the drive's last limits (the fallback, STOPPED, ``why``); remove the wiring.

        No sample is taken and nothing is published after this; the session
        keeps its state and counts for a later :meth:`start`.
        """
        if not self.started:
            return
        node = self.node
        for kind, destroy in (('timers', node.destroy_timer),
                              ('subscriptions', node.destroy_subscription)):
            for entity in set(getattr(node, kind)) - self._made[kind]:
                destroy(entity)
        self.session.stop_limits(why)
        # reliable: the drive gets the last one
        self._wait_acked(LIMIT_TOPICS, LAST_LIMITS_WAIT_S)
        for pub in set(node.publishers) - self._made['publishers']:
            node.destroy_publisher(pub)
        self.pubs = {}
        self.view.close()
        self.view = EstimatorView(node, self.session, self._topic, self._failed)
        if self.whatif is not None:
            self.whatif.close()
        self.whatif, self._made = None, None

    def close(self) -> None:
        """Let the last messages reach their readers; stop the view and the what-if worker."""
        # the node is going: a reader that lags (a recorder on a busy machine) would lose the
        # last ticks' messages of some topics and not of others with their writers
        self._wait_acked(self.pubs, LAST_MESSAGES_WAIT_S)
        self.view.close()
        if self.whatif is not None:
            self.whatif.close()

    def set_parameters(self, params) -> SetParametersResult:
        """Apply the parameters that may change at run time (the node's callback)."""
        try:
            for param in params:
                if param.name not in self.p:
                    continue
                self.p[param.name] = param.value        # a stopped runner takes it at start
                if param.name == 'background_budget_ms':
                    self.session.budget_s = param.value * 1e-3
                elif not self.started:
                    continue
                elif param.name == 'publish_rate_Hz':
                    self.publish_timer.timer_period_ns = int(1e9 / param.value)
                elif param.name == 'diagnostics_rate_Hz':
                    self.diag_timer.timer_period_ns = int(1e9 / param.value)
                elif param.name == 'foxglove_inputs_rate_Hz' and self.view.view is not None:
                    self.view.view.inputs_rate_Hz = param.value
            self.view.show_parameters({q.name: q.value for q in params if q.name in self.p})
        except Exception as exc:  # noqa: B902
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _subscribe(self) -> list:
        """Subscribe to the inputs (raw), the ambient, the thermocouples and the acks."""
        # inputs, raw: decoded here in a fraction of rclpy's deserialisation; one
        # subscription per topic, whatever number of inputs it carries
        # the ambient and the thermocouples too: a temperature in K, taken in degC
        s, node = self.session, self.node
        self._takers = {name: functools.partial(s.take, name) for name in s.inputs}
        self._takers[inputs.AMBIENT] = lambda t, v, now: s.add_ambient(t, v - C_TO_K)
        for tc in interface.THERMOCOUPLES:
            self._takers[inputs.thermocouple_channel(tc)] = functools.partial(
                lambda name, t, v, now: s.add_measured(name, t, v - C_TO_K), tc)
        input_subs = []
        for dec in inputs.decoders(self.input_spec, list(self._takers)):
            topic = self._topic(dec.topic)
            cb = functools.partial(self._on_batch if dec.batched else self._on_input, dec)
            kind = topics.message_class(dec.message_type)
            sub = node.create_subscription(kind, topic, cb, self.in_qos, raw=True)
            if any(c in s.inputs for c in dec.channels):
                input_subs.append(sub)
            self.topic_names.update(dict.fromkeys(dec.channels, topic))
        cls, qos = topics.profile_of(interface.ACK_TOPIC)
        node.create_subscription(cls, self._topic(interface.ACK_TOPIC), self._on_ack, qos)
        return input_subs

    def _advertise(self) -> None:
        """Create the publishers (types and QoS from topic_table); send the state's names."""
        self.pubs = {topic: self._publisher(topic) for topic in interface.ESTIMATOR_OUTPUTS}
        # the name of each element of the state, once and latched: they do not change in a run
        self._publisher(interface.STATE_NAMES_TOPIC).publish(messages.state_names(
            self.session.model.quantities.state_names))
        self.diag_pub = self._publisher(interface.DIAGNOSTICS_TOPIC)

    # ------------------------------------------------------------- helpers
    def _wait_acked(self, names, wait_s: float) -> None:
        """Wait until every reader acknowledged what ``names`` sent (``wait_s`` in all)."""
        end = time.monotonic() + wait_s
        for name in names:
            self.pubs[name].wait_for_all_acked(
                Duration(seconds=max(end - time.monotonic(), 0.0)))

    def _publisher(self, topic: str):
        """Return a new publisher of one of the interface's topics, under the prefix."""
        cls, qos = topics.profile_of(topic)
        return self.node.create_publisher(cls, self._topic(topic), qos)

    def _topic(self, name: str) -> str:
        """Return ``name`` with the topic prefix in place of interface.PREFIX."""
        return interface.prefixed(name, self.prefix)

    def _now_s(self) -> Optional[float]:
        """Return the ROS clock in seconds, or None while sim time has not started."""
        ns = self.clock.now_ns()
        return ns * 1e-9 if ns > 0 else None

    def _failed(self, where: str, exc: BaseException) -> None:
        self.callback_errors[where] = self.callback_errors.get(where, 0) + 1
        self.node.get_logger().error(f'{where}: {type(exc).__name__}: {exc}',
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
                self.node.get_logger().warning(f'acknowledge {quantity!r} ignored: {exc}')
        except Exception as exc:  # noqa: B902
            self._failed('ack', exc)

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
            log = self.node.get_logger()
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
            now_ns = self.node.get_clock().now().nanoseconds
            s = self.session
            new_rejected = {n: s.health[n].rejected - self._diag_prev[n] for n in s.inputs}
            self._diag_prev = {n: s.health[n].rejected for n in s.inputs}
            implausible = sum(s.implausible_counts.values())
            new_implausible = implausible - self._implausible_prev
            self._implausible_prev = implausible
            counters = diagnostics.NodeCounters(
                hardware_id=self.hardware_id, published=self.messages.published,
                callback_errors=dict(self.callback_errors),
                waiting_for_clock=self.waiting_for_clock, latency_ms=self.latency_ms,
                view=self.view.text())
            arr = DiagnosticArray()
            arr.header.stamp = topics.time_msg(now_ns)
            node, namespace = self.node.get_name(), self.node.get_namespace()
            arr.status = [
                DiagnosticStatus(level=bytes([d.level]),
                                 name=interface.status_name(d.name, node, namespace),
                                 message=d.message, hardware_id=self.hardware_id,
                                 values=[KeyValue(key=k, value=str(v)) for k, v in d.values])
                for d in diagnostics.statuses(s, counters, now_ns * 1e-9, self.topic_names,
                                              new_rejected, new_implausible)]
            self.diag_pub.publish(arr)
            self.view.offer_health()
        except Exception as exc:  # noqa: B902
            self._failed('diagnostics', exc)

    def report(self, node_name: str) -> interface.NodeReport:
        """Return the run's counts as data: per input, estimates, gaps, errors."""
        st = self.session.status()
        return interface.NodeReport(node=node_name, inputs=st.inputs, figures={
            'estimates': self.messages.published, 'steps': st.steps, 'data_gaps': st.gaps.count,
            'longest_gap_s': st.gaps.longest_s, 'clock_jumps': st.clock_jumps,
            'callback_errors': sum(self.callback_errors.values()),
            'model_errors': st.model_errors, 'limits_published': st.limits_published,
            'limits_fallback': st.limits_fallback,
            'limit_ticks_behind': st.limit_ticks_behind})


def summary(report: interface.NodeReport) -> str:
    """Return a one-line account of an estimator's run for a log: samples per input, gaps."""
    f = report.figures
    parts = [f'{name} {c.received} received, {c.accepted} accepted, {c.rejected} '
             f'rejected, {c.stale_events} stale events' for name, c in report.inputs.items()]
    return (f'estimator summary: {f["estimates"]} estimates, {f["steps"]} steps; '
            + '; '.join(parts) + f'; data gaps {f["data_gaps"]} (longest '
            f'{f["longest_gap_s"]:.1f} s); clock jumps {f["clock_jumps"]}; callback errors '
            f'{f["callback_errors"]}, model errors {f["model_errors"]}')
