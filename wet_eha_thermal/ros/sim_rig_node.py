"""
The simulated rig: a ROS 2 node that plays the reference EHA and its sensors.

Node ``eha_sim_rig``. From a duty (a reference stage or a duty CSV) the
kinetic model makes the sensor signals, computed vectorised in blocks of
``block_s`` and published one sample per topic per tick of a ``rate_Hz`` timer, so
that a receiver stamping on arrival (the estimator does, for the Float64
inputs) sees them spread as a real rig's would. A "truth" thermal model
(:class:`~wet_eha_thermal.model.eha.EHAModel`) is stepped by the rig itself
with the same, noise-free samples every block; its temperatures, through a
first-order sensor lag and noise, are the thermocouples.

Topics (``topic_prefix`` replaces ``/eha``; see :mod:`.topics`):

- the estimator's inputs of ``INPUT_TOPICS`` at ``rate_Hz``: Float64 for
  current, speed and position, FluidPressure (header stamp = the sample's
  scheduled time) for the three pressures, or for the one differential
  pressure when the configuration's ``estimator.pressure_inputs`` says so;
  QoS ``qos``;
- the ambient temperature (Temperature, degC) at 1 Hz;
- the thermocouples ``<prefix>/measured/<name>`` for every name of
  ``THERMOCOUPLES`` at ``thermocouple_rate_Hz``;
- ``/diagnostics`` at 1 Hz: samples published and skipped, timer jitter,
  publish lag, CPU, the truth model's hot-spot (and its peak), magnet and
  oil, and with ``honour_limit`` the drive's limit and clamp.

A drive that honours the limit (``honour_limit:=true``): the rig reads the
estimator's current limits as a real drive would, numbers at fixed places
(std_msgs/Float64MultiArray on ``<prefix>/drive/limits``,
:class:`~wet_eha_thermal.interface.DriveLimits`), and its simulated drive
carries at most the binding one where the duty asks for more (the load yields:
:meth:`~wet_eha_thermal.model.kinetics.KineticModel.sample_limited`); the
truth model heats with what the drive carried. Its watchdog, as a drive's
should be (:class:`~wet_eha_thermal.offline.simulated_rig.DriveLimit`): a
limit whose stamp (the sample time it belongs to) is older than
``limit_watchdog_s`` by the rig's clock, or none yet, gives way to
``limit_fallback_A``; a limit whose status code is not OK (the estimator's
fallback) is applied, never above ``limit_fallback_A``. The limit is taken
once per block (``block_s``). Counted: the time clamped, the first clamp
(duty time), the largest cut (demanded minus carried current), the time on
a fallback, the limit messages missed (gaps of their sequence).

Sensor noise (1 sigma, Gaussian, seeded by ``seed``; off with ``noise:=false``):
current 0.05 A (the reading is an RMS value, so its magnitude is kept),
speed 2 rad/s, pressures 20 kPa, position 10 um, thermocouples 0.2 K,
ambient 0.05 K. Thermocouples lag the truth with a first-order time
constant ``thermocouple_lag_s`` (1 s).

Start: the duty (sample 1) starts once every node named in ``wait_for`` has
said it is ready on ``/eha/ready`` (model warmed, inputs matched: see
:class:`~wet_eha_thermal.ros.runtime.Readiness`) and every input topic has
``wait_for_subscribers`` matched subscribers; after ``start_timeout_s`` it
starts anyway, with a warning that names who was not ready. It then says so on
``/eha/ready`` itself (``running``), which is where ``wet-eha-thermal live``
starts counting its duration.

Time: the sample schedule follows the node's clock, so under
``use_sim_time`` it follows /clock; nothing is published before the first
/clock message, and a clock that jumps backwards (a replay restarting)
re-anchors the schedule without restarting the duty. When the rig falls
behind (a slow tick) it publishes the due samples in one tick, at most
``MAX_BURST_S`` worth; samples older than that are skipped and counted.

Shutdown: one summary line (samples, timer jitter, publish lag, CPU) to
stderr for people, and the same figures as data (an
:class:`~wet_eha_thermal.interface.NodeReport` line) to stdout for ``live``.

Run: ``python -m wet_eha_thermal.ros.sim_rig_node [--executor events|single]
--ros-args -p stage:=3``.
"""

import json
import math
import sys
import time
from typing import Dict, List, Optional

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
import numpy as np
import rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import FluidPressure, Temperature
from std_msgs.msg import Float64, Float64MultiArray, String
from wet_eha_thermal.config import ConfigError, load_config
from wet_eha_thermal.interface import (AMBIENT_TOPIC, DIAGNOSTICS_TOPIC, DRIVE_LIMITS_TOPIC,
                                       INPUT_TOPICS, MEASURED_PREFIX, NodeReport, prefixed,
                                       PRESSURE_INPUTS, READY_TOPIC, RIG_NODE, status_name,
                                       THERMOCOUPLES)
from wet_eha_thermal.model.duty import DutyError, load_duty_csv, stage_duty, STAGES
from wet_eha_thermal.model.uncertainty import as_built
from wet_eha_thermal.offline.simulated_rig import (AMBIENT_SIGMA_K, DriveLimit, NOISE_SIGMA,
                                                   SimulatedRig, THERMOCOUPLE_SIGMA_K)
from wet_eha_thermal.ros.runtime import (declare_parameters, descriptor, prepare_model_step,
                                         run_node, shared_parameters)
from wet_eha_thermal.ros.topics import input_qos, latched_qos, publish_inputs, time_msg
from wet_eha_thermal.units import C_TO_K

NODE_NAME = RIG_NODE
#: Most sample time published in one tick when catching up (s); older samples are skipped.
MAX_BURST_S = 0.1
#: Default block of the kinetics and the truth model (s): with 20 ms blocks the rig took
#: 40-50 % of a core at 1 kHz, 90 % of it computing blocks (py-spy); 0.1 s blocks make a
#: fifth of the numpy calls, and the truth model steps at 0.1 s
RIG_BLOCK_S = 0.1
#: Tick intervals and publish lags kept for the jitter figures (a ring of this many).
STATS_WINDOW = 20000


class _Ring:
    """Fixed-size ring of floats for percentiles over the recent past."""

    def __init__(self, n: int) -> None:
        self.buf = np.zeros(n)
        self.n = 0

    def add(self, v: float) -> None:
        self.buf[self.n % self.buf.size] = v
        self.n += 1

    def values(self) -> np.ndarray:
        return self.buf[:min(self.n, self.buf.size)]

    def percentiles(self, qs) -> List[float]:
        v = self.values()
        return [float(x) for x in np.percentile(v, qs)] if v.size else [math.nan] * len(qs)


class SimRigNode(Node):
    """The simulated rig: kinetics to sensor topics, truth model to thermocouples."""

    def __init__(self, **kwargs) -> None:
        super().__init__(NODE_NAME, **kwargs)
        p = self._declare_parameters()
        self.cfg = load_config(p['config_file'] or None)
        # the rig "as built": its truth drawn from the configuration's stated sigmas, so that
        # the estimator meets a rig it is not (0: the configuration itself)
        self.as_built_seed = p['as_built_seed']
        self.truth_cfg = as_built(self.cfg, self.as_built_seed or None)
        act = self.cfg.hydraulics.actuator
        if p['duty_file']:
            duty = load_duty_csv(p['duty_file'], act.area_m2, act.half_stroke_m)
        else:
            duty = stage_duty(self.cfg, p['stage'])
        self.rig = SimulatedRig(self.truth_cfg, duty, rate_Hz=p['rate_Hz'], noise=p['noise'],
                                seed=p['seed'], ambient_C=p['ambient_C'],
                                thermocouple_lag_s=p['thermocouple_lag_s'],
                                block_s=p['block_s'])
        self.truth = self.rig.truth
        self.drive: Optional[DriveLimit] = None
        self.limit_source = 'open loop'
        self.limit_fallback_s = 0.0         # duty time the drive spent on a fallback limit
        # before any subscription or publisher: a first step that compiled would keep
        # samples waiting for half a minute
        prepare_model_step(self, self.truth_cfg)
        self.n_block = self.rig.n_block
        self.period_s = self.rig.period_s
        self.period_ns = int(round(self.period_s * 1e9))
        self.noise = p['noise']
        self.hardware_id = p['hardware_id']
        self.wait_for_subscribers = p['wait_for_subscribers']
        self.wait_for = set(p['wait_for'])
        self.start_timeout_s = p['start_timeout_s']
        self.ready_nodes: Dict[str, dict] = {}      # node name -> its ready message
        self.started_after_s: Optional[float] = None
        self._make_publishers(p)
        if p['honour_limit']:
            self._follow_limits(p)
        self._reset_schedule()
        self.create_timer(self.period_s, self._tick)
        self.create_timer(1.0, self._publish_ambient)
        self.create_timer(1.0 / p['thermocouple_rate_Hz'], self._publish_thermocouples)
        self.create_timer(1.0, self._publish_diagnostics)
        self.get_logger().info(self._start_text(p, duty.name if p['duty_file'] else
                                                f'stage {p["stage"]}'))

    def _make_publishers(self, p: Dict[str, object]) -> None:
        """Make the publishers of the inputs, ambient, thermocouples, diagnostics and readiness."""
        prefix = p['topic_prefix']
        # a second of samples: a reliable reader that stalls catches up instead of losing them
        q = input_qos(p['qos'], depth=max(10, int(round(1.0 / self.period_s))))
        # the inputs the configured estimator takes (three pressures or one differential)
        self.inputs = self.rig.inputs
        self.pubs = {}
        for name in self.inputs:
            kind = FluidPressure if name in PRESSURE_INPUTS else Float64
            self.pubs[name] = self.create_publisher(kind, prefixed(INPUT_TOPICS[name], prefix), q)
        self.msgs = {name: (FluidPressure() if name in PRESSURE_INPUTS else Float64())
                     for name in self.inputs}
        for name in set(PRESSURE_INPUTS) & set(self.inputs):
            self.msgs[name].header.frame_id = NODE_NAME
            self.msgs[name].variance = NOISE_SIGMA[name] ** 2 if self.noise else 0.0
        self.ambient_pub = self.create_publisher(Temperature, prefixed(AMBIENT_TOPIC, prefix), 10)
        self.tc_pubs = {name: self.create_publisher(
            Temperature, prefixed(f'{MEASURED_PREFIX}/{name}', prefix), 10)
            for name in THERMOCOUPLES}
        self.diag_pub = self.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, 10)
        self.ready_topic = prefixed(READY_TOPIC, prefix)
        self.ready_pub = self.create_publisher(String, self.ready_topic, latched_qos())
        self.create_subscription(String, self.ready_topic, self._on_ready, latched_qos())

    def _follow_limits(self, p: Dict[str, object]) -> None:
        """Make the drive honour the current limits the estimator publishes."""
        # by default the conservative value the estimator falls back to: one number
        self.drive = DriveLimit(p['limit_watchdog_s'], p['limit_fallback_A']
                                or self.cfg.estimator.limits.fallback_current_A)
        # best effort: the watchdog, not the transport, deals with a lost limit
        self.create_subscription(Float64MultiArray,
                                 prefixed(DRIVE_LIMITS_TOPIC, p['topic_prefix']),
                                 lambda msg: self.drive.take(msg.data), qos_profile_sensor_data)

    def _reset_schedule(self) -> None:
        """Set the schedule before the first sample and the publishing statistics to zero."""
        # schedule: sample k (1, 2, ...) has duty time k * period and is due at t0 + k * period
        self.t0_ns: Optional[int] = None
        self.last_now_ns = 0
        self.k_next = 1
        self.block: Optional[List[List[float]]] = None
        self.block_first = 1        # sample number of the block's first row
        self.published = 0
        self.skipped = 0
        self.restarts = 0
        self.ticks = 0
        self.intervals = _Ring(STATS_WINDOW)
        self.lags = _Ring(STATS_WINDOW)
        self.block_ms = _Ring(2000)
        self.max_interval_s = 0.0
        self.max_lag_s = 0.0
        self._last_tick_wall: Optional[float] = None
        self.started_wall = time.monotonic()
        self.started_cpu = time.process_time()
        self._diag_mark = (self.started_wall, self.started_cpu)

    def _start_text(self, p: Dict[str, object], what: str) -> str:
        """Return the log line that says what the rig runs, how, and against which truth."""
        return (
            f'rig: {what} at {1.0 / self.period_s:g} Hz ({self.n_block} samples per '
            f'{self.rig.block_s * 1e3:g} ms block), noise {"on" if self.noise else "off"}, '
            f'ambient {p["ambient_C"]:g} degC, qos {p["qos"]}, topics under '
            f'{p["topic_prefix"]}; '
            + (f'the truth is a rig as built (draw {self.as_built_seed} of the configured '
               'uncertainty)' if self.truth_cfg is not self.cfg else
               'the truth is the configuration itself')
            + (f'; the drive honours the current limit (watchdog {p["limit_watchdog_s"]:g} s, '
               f'fallback {self.drive.fallback_A:g} A)' if self.drive is not None else ''))

    # ------------------------------------------------------------ parameters
    def _declare_parameters(self) -> Dict[str, object]:
        stages = sorted(STAGES)
        specs = {
            'stage': (6, descriptor('reference stage 1-6 (ignored with duty_file)',
                                    stages[0], stages[-1])),
            'duty_file': ('', descriptor('duty CSV (time_s, flow_L_min, load_MPa); '
                                         'empty: use the stage')),
            'rate_Hz': (1000.0, descriptor('sensor sample rate, Hz', 50.0, 10000.0)),
            'noise': (True, descriptor('add sensor noise')),
            'seed': (1, descriptor('seed of the noise', 0, 2 ** 31 - 1)),
            'ambient_C': (20.0, descriptor('ambient temperature, degC', -40.0, 60.0)),
            'thermocouple_rate_Hz': (10.0, descriptor('thermocouple rate, Hz', 0.1, 100.0)),
            'thermocouple_lag_s': (1.0, descriptor('thermocouple time constant, s', 0.0, 60.0)),
            'block_s': (RIG_BLOCK_S, descriptor(
                'samples are computed (kinetics, truth model step) in blocks this long, s',
                0.005, 1.0)),
            'config_file': ('', descriptor('YAML configuration; empty: the reference rig')),
            'as_built_seed': (1, descriptor(
                'the truth model is the configuration with every uncertain parameter (and '
                'structural choice) of its uncertainty section drawn with this seed: a rig '
                'as built, not as configured; 0: the configuration itself', 0, 2 ** 31 - 1)),
            'wait_for_subscribers': (0, descriptor(
                'start the duty once every input topic has this many matched subscribers',
                0, 100)),
            # declared by type: rclpy takes an empty list for a byte array
            'wait_for': (Parameter.Type.STRING_ARRAY, descriptor(
                'nodes that must say they are ready on /eha/ready before the duty starts '
                '(e.g. [eha_thermal_estimator, eha_recorder])')),
            'start_timeout_s': (120.0, descriptor(
                'longest wait for wait_for and wait_for_subscribers before starting anyway, s',
                0.0, 3600.0)),
            'honour_limit': (False, descriptor(
                'the simulated drive carries at most the current limit the estimator publishes '
                'on <topic_prefix>/current_limits')),
            'limit_watchdog_s': (2.0, descriptor(
                'a limit stamped longer ago than this by the rig clock gives way to '
                'limit_fallback_A, s (default: 4 periods of the 2 Hz limits)', 0.1, 60.0)),
            'limit_fallback_A': (0.0, descriptor(
                'the current the drive carries at most without a valid limit (none yet, too '
                "old, the estimator's fallback), A RMS; 0: the configuration's "
                'estimator.limits.fallback_current_A', 0.0, 1000.0)),
        }
        values = declare_parameters(
            self, {**specs, **shared_parameters('qos', 'topic_prefix', 'hardware_id')})
        values['wait_for'] = list(values['wait_for'] or [])
        return values

    # -------------------------------------------------------------- kinetics
    def _next_block(self, now_ns: int) -> None:
        """Compute the next block of samples (the rig steps its truth model over it)."""
        t_start = time.perf_counter()
        if self.drive is not None:
            self._take_limit(now_ns)
        first = self.block_first if self.block is None else self.block_first + self.n_block
        block = self.rig.next_block()
        self.block = np.column_stack([block[name] for name in self.inputs]).tolist()
        self.block_first = first
        self.block_ms.add((time.perf_counter() - t_start) * 1e3)

    # ----------------------------------------------------------------- ticks
    def _tick(self) -> None:
        wall = time.perf_counter()
        if self._last_tick_wall is not None:
            dt = wall - self._last_tick_wall
            self.intervals.add(dt)
            self.max_interval_s = max(self.max_interval_s, dt)
        self._last_tick_wall = wall
        self.ticks += 1
        now_ns = self.get_clock().now().nanoseconds
        if now_ns == 0:
            return                      # sim time before the first /clock
        if self.t0_ns is None:
            if not self._subscribers_ready():
                return
            self.t0_ns = now_ns - self.period_ns * self.k_next
        elif now_ns < self.last_now_ns:
            # the clock jumped back: keep the duty going from here
            self.t0_ns = now_ns - self.period_ns * self.k_next
            self.restarts += 1
        self.last_now_ns = now_ns
        due = (now_ns - self.t0_ns) // self.period_ns
        max_burst = max(1, int(MAX_BURST_S / self.period_s))
        if due - self.k_next >= max_burst:
            skip = due - max_burst + 1 - self.k_next
            self.skipped += skip
            self.k_next += skip
        pubs = [self.pubs[n] for n in self.inputs]
        msgs = [self.msgs[n] for n in self.inputs]
        is_pressure = [n in PRESSURE_INPUTS for n in self.inputs]
        while self.k_next <= due:
            k = self.k_next
            while self.block is None or k >= self.block_first + self.n_block:
                self._next_block(now_ns)
            row = self.block[k - self.block_first]
            sched_ns = self.t0_ns + k * self.period_ns
            publish_inputs(pubs, msgs, is_pressure, row, time_msg(sched_ns))
            lag = (now_ns - sched_ns) * 1e-9
            self.lags.add(lag)
            self.max_lag_s = max(self.max_lag_s, lag)
            self.published += 1
            self.k_next += 1

    def _take_limit(self, now_ns: int) -> None:
        """Give the drive the limit of ``now_ns`` for the next block; log where it comes from."""
        limit_A, source = self.drive.applied(now_ns)
        self.rig.current_limit_A = limit_A
        if source != 'estimator':
            self.limit_fallback_s += self.rig.block_s
        # the kind of source, not its text: an age that grows is not news
        if source.split(':')[0] != self.limit_source.split(':')[0]:
            # rclpy ties one severity to each call site: two calls
            if source == 'estimator':
                self.get_logger().info(f'drive limit {limit_A:.1f} A: {source}')
            else:
                self.get_logger().warning(f'drive limit {limit_A:.1f} A: {source}')
        self.limit_source = source

    def _on_ready(self, msg: String) -> None:
        try:
            data = json.loads(msg.data)
        except ValueError:
            return
        if isinstance(data, dict) and data.get('ready') and isinstance(data.get('node'), str):
            self.ready_nodes[data['node']] = data

    def _subscribers_ready(self) -> bool:
        """
        Tell whether the duty may start: the awaited nodes ready, the inputs matched.

        Samples published before a subscriber has matched never reach it, and
        a node still compiling or warming up would fall behind at once; the
        duty starts when both are settled, or after ``start_timeout_s``
        regardless (with a warning naming what was missing). Says so on the
        ready topic.
        """
        waiting = sorted(self.wait_for - set(self.ready_nodes))
        matched = min(pub.get_subscription_count() for pub in self.pubs.values())
        short = matched < self.wait_for_subscribers
        waited = time.monotonic() - self.started_wall
        if (waiting or short) and waited <= self.start_timeout_s:
            return False
        if waiting or short:
            self.get_logger().warning(
                f'starting the duty after {waited:.1f} s without: '
                + ', '.join((['not ready: ' + ', '.join(waiting)] if waiting else [])
                            + ([f'{matched} of {self.wait_for_subscribers} subscribers on some '
                                'input'] if short else [])))
        self.started_after_s = waited
        self.ready_pub.publish(String(data=json.dumps({
            'node': self.get_name(), 'ready': True, 'running': True,
            'hardware_id': self.hardware_id, 'waited_s': round(waited, 3),
            'ready_nodes': sorted(self.ready_nodes)})))
        self.get_logger().info(f'duty started after {waited:.1f} s of start-up'
                               + (f' ({", ".join(sorted(self.wait_for))} ready)'
                                  if self.wait_for and not waiting else ''))
        return True

    def _publish_ambient(self) -> None:
        now = self.get_clock().now()
        if now.nanoseconds == 0:
            return
        msg = Temperature()
        msg.header.stamp = now.to_msg()
        msg.header.frame_id = NODE_NAME
        msg.temperature = self.rig.ambient_reading_C()
        msg.variance = AMBIENT_SIGMA_K ** 2 if self.noise else 0.0
        self.ambient_pub.publish(msg)

    def _publish_thermocouples(self) -> None:
        now = self.get_clock().now()
        if now.nanoseconds == 0 or self.block is None:
            return
        stamp = now.to_msg()
        variance = THERMOCOUPLE_SIGMA_K ** 2 if self.noise else 0.0
        for name, value in self.rig.thermocouples_C().items():
            msg = Temperature()
            msg.header.stamp = stamp
            msg.header.frame_id = f'{NODE_NAME}/{name}'
            msg.temperature = value
            msg.variance = variance
            self.tc_pubs[name].publish(msg)

    # ------------------------------------------------------------ statistics
    def statistics(self) -> Dict[str, float]:
        """Return the rig's figures: samples, timer jitter, publish lag (ms), CPU (%)."""
        wall = time.monotonic() - self.started_wall
        cpu = time.process_time() - self.started_cpu
        i50, i99 = self.intervals.percentiles([50, 99])
        l50, l99 = self.lags.percentiles([50, 99])
        b50, b99 = self.block_ms.percentiles([50, 99])
        return {'run_s': wall, 'samples_published': self.published,
                'samples_skipped': self.skipped, 'clock_restarts': self.restarts,
                'duty_time_s': (self.k_next - 1) * self.period_s,
                'tick_interval_p50_ms': i50 * 1e3, 'tick_interval_p99_ms': i99 * 1e3,
                'tick_interval_max_ms': self.max_interval_s * 1e3,
                'publish_lag_p50_ms': l50 * 1e3, 'publish_lag_p99_ms': l99 * 1e3,
                'publish_lag_max_ms': self.max_lag_s * 1e3,
                'block_p50_ms': b50, 'block_p99_ms': b99,
                'cpu_percent': 100.0 * cpu / wall if wall > 0 else 0.0,
                'truth_winding_hotspot_peak_C': self.rig.peak_hotspot_K - C_TO_K,
                'as_built_seed': float(self.as_built_seed if self.truth_cfg is not self.cfg
                                       else 0),
                **self.limit_figures()}

    def limit_figures(self) -> Dict[str, float]:
        """Return the drive's limit and clamp (none in open loop): A, s of duty time, counts."""
        if self.drive is None:
            return {}
        rig = self.rig
        return {'limit_A': math.nan if rig.current_limit_A is None else rig.current_limit_A,
                'limit_clamped_s': rig.clamped_samples * rig.period_s,
                'limit_first_clamp_s': rig.first_clamp_s,
                'limit_largest_cut_A': rig.largest_cut_A,
                'limit_fallback_s': self.limit_fallback_s,
                'limits_received': self.drive.received, 'limits_rejected': self.drive.rejected,
                'limits_missed': self.drive.missed}

    def report(self) -> NodeReport:
        """Return the run's counts and figures as data: what ``live`` summarises."""
        figures = self.statistics()
        published = figures.pop('samples_published')
        figures['input_topics'] = len(self.inputs)
        return NodeReport(node=NODE_NAME, samples_published=published, figures=figures)

    def summary(self) -> str:
        """Return a one-line account of the run (samples, jitter, lag, CPU) for a log."""
        report = self.report()
        clamp = clamp_text(report.figures)
        return f'rig summary: {figures_text(report)}' + (f'; {clamp}' if clamp else '')

    def _publish_diagnostics(self) -> None:
        s = self.statistics()
        wall, cpu = time.monotonic(), time.process_time()
        w0, c0 = self._diag_mark
        self._diag_mark = (wall, cpu)
        s['cpu_percent_last_s'] = 100.0 * (cpu - c0) / max(wall - w0, 1e-9)
        if self.block is not None:
            out = self.truth.outputs()
            s['truth_winding_hotspot_C'] = out['winding_hotspot'] - C_TO_K
            s['truth_winding_mean_C'] = out['winding_mean'] - C_TO_K
            s['truth_magnet_C'] = out['magnet'] - C_TO_K
            s['truth_oil_C'] = out['oil'] - C_TO_K
        if self.drive is not None:
            s['limit_source'] = self.limit_source
        st = DiagnosticStatus(name=status_name('rig', self.get_name(), self.get_namespace()),
                              hardware_id=self.hardware_id)
        late = s['publish_lag_p99_ms'] > 10.0 or self.skipped > 0
        st.level = DiagnosticStatus.WARN if late else DiagnosticStatus.OK
        st.message = 'falling behind the schedule' if late else 'running'
        st.values = [KeyValue(key=k, value=(f'{v:.4g}' if isinstance(v, float) else str(v)))
                     for k, v in s.items()]
        arr = DiagnosticArray(status=[st])
        arr.header.stamp = self.get_clock().now().to_msg()
        self.diag_pub.publish(arr)


def figures_text(report: NodeReport) -> str:
    """Return the figures of the rig's report in words: samples, jitter, lag, block, CPU."""
    s = report.figures
    return (f'{s["run_s"]:.1f} s, {report.samples_published} samples x '
            f'{s["input_topics"]:.0f} topics ({s["samples_skipped"]:.0f} skipped), tick interval '
            f'p50/p99/max {s["tick_interval_p50_ms"]:.3f}/{s["tick_interval_p99_ms"]:.3f}/'
            f'{s["tick_interval_max_ms"]:.1f} ms, publish lag p50/p99/max '
            f'{s["publish_lag_p50_ms"]:.3f}/{s["publish_lag_p99_ms"]:.3f}/'
            f'{s["publish_lag_max_ms"]:.1f} ms, block (kinetics + truth step) p50/p99 '
            f'{s["block_p50_ms"]:.2f}/{s["block_p99_ms"]:.2f} ms, CPU '
            f'{s["cpu_percent"]:.1f} % of a core')


def clamp_text(figures: Dict[str, float]) -> str:
    """Return the drive's limit and clamp in words, from the rig's figures ('' in open loop)."""
    if 'limit_clamped_s' not in figures:
        return ''
    s = figures
    if s['limit_clamped_s'] > 0.0:
        share = 100.0 * s['limit_clamped_s'] / max(s['duty_time_s'], 1e-9)
        clamp = (f'clamped {s["limit_clamped_s"]:.1f} s of {s["duty_time_s"]:.1f} s '
                 f'({share:.0f} %), first at {s["limit_first_clamp_s"]:.1f} s, largest cut '
                 f'{s["limit_largest_cut_A"]:.1f} A')
    else:
        clamp = 'never clamped'
    return (f'drive limit {s["limit_A"]:.1f} A at the end, {clamp}; '
            f'{s["limit_fallback_s"]:.1f} s on a fallback limit; {s["limits_received"]:.0f} '
            f'limits received ({s["limits_rejected"]:.0f} rejected)')


def main(args: Optional[List[str]] = None) -> int:
    """Run the simulated rig until Ctrl-C (or SIGTERM); return the exit status."""
    def close(node: SimRigNode) -> int:
        print(node.summary(), file=sys.stderr, flush=True)
        node.report().write(sys.stdout)
        return 0

    return run_node(args, 'wet-eha-thermal-rig', 'Simulated wet-EHA rig (ROS 2 node '
                    'eha_sim_rig); parameters go after --ros-args, e.g. --ros-args -p stage:=3',
                    SimRigNode, (ConfigError, DutyError, ValueError,
                                 rclpy.exceptions.InvalidParameterValueException,
                                 rclpy.exceptions.InvalidParameterTypeException),
                    error_prefix='error', close=close)


if __name__ == '__main__':
    sys.exit(main())
