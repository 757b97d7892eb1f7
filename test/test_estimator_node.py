"""
The rclpy estimator node, in this process: estimates, diagnostics, stale inputs, alerts.

A probe node publishes synthetic sensor topics (20 A, 800 rad/s, 1 MPa, a
fixed position, one sample per channel and millisecond, paced to the wall
clock) and listens to the estimator's outputs; both spin in one
EventsExecutor with timeouts, so no test can hang.
"""

import json
import math
import os
from pathlib import Path
import signal
import subprocess
import sys
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
from node_probe import NodeAndProbe, PATIENCE
import numpy as np
import pytest
import rclpy
from rclpy.exceptions import InvalidParameterValueException
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from ros_domains import claim_domain
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import FluidPressure, JointState, Temperature
from std_msgs.msg import Float64, Float64MultiArray, String
from test_foxglove_view import Client
from wet_eha_thermal import interface
from wet_eha_thermal.config import default_config_path
from wet_eha_thermal.inputs import AMBIENT, decoders, load_inputs, thermocouple_channel
from wet_eha_thermal.ros import topics
from wet_eha_thermal.ros.estimator_node import EstimatorNode
from wet_eha_thermal.units import C_TO_K
from wet_eha_thermal.view_channels import CHANNELS, view_topics
import yaml

pytestmark = pytest.mark.slow     # measured: see docs/development.md#tests-and-ci

# this module's own domain, this machine only; conftest puts it in ROS_DOMAIN_ID while it runs
DOMAIN_ID = claim_domain()
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

ROOT = Path(__file__).resolve().parents[1]
OK, WARN, ERROR, STALE = 0, 1, 2, 3
VALUES = {'current_A': 20.0, 'speed_rad_s': 800.0, 'p_a_Pa': 1.0e6, 'p_b_Pa': 1.0e6,
          'p_acc_Pa': 1.0e6, 'dp_Pa': 0.0, 'position_m': 0.002}


class Rig(NodeAndProbe):
    """
    The estimator under test, a probe node that feeds it and listens, one executor.

    Without ``whatif`` the node starts no what-if worker: a process that loads
    the model's kernels and runs a warm-up what-if (1.5 s of a core) beside
    tests that never ask it anything, and that time the node.
    """

    def __init__(self, context, overrides=(), sim_time=False, qos='sensor_data', whatif=False):
        super().__init__(context, EstimatorNode(context=context, parameter_overrides=[
            Parameter('diagnostics_rate_Hz', value=5.0), Parameter('qos', value=qos),
            Parameter('whatif', value=whatif), *overrides]),
            rclpy.create_node('estimator_test_probe', context=context))
        self.clock_ns = 1000 * 10**9 if sim_time else None
        self.in_qos = in_qos = topics.input_qos(qos, 100)
        self.pubs = {name: self.probe.create_publisher(
            FluidPressure if name in interface.PRESSURE_INPUTS else Float64,
            interface.INPUT_TOPICS[name], in_qos) for name in self.node.session.inputs}
        self.clock_pub = self.probe.create_publisher(Clock, '/clock', 10)
        self.ack_pub = self.probe.create_publisher(String, interface.ACK_TOPIC,
                                                   QoSProfile(depth=10))
        self.estimates = {'winding_hotspot': [], 'winding_mean': [], 'oil': []}
        for name, store in self.estimates.items():
            self.probe.create_subscription(Temperature, f'{interface.ESTIMATE_PREFIX}/{name}',
                                           store.append, 100)
        self.diagnostics = []
        self.probe.create_subscription(DiagnosticArray, interface.DIAGNOSTICS_TOPIC,
                                       self.diagnostics.append, 10)

    def publish_samples(self, skip=(), current=None):
        if self.clock_ns is not None:
            self.clock_ns += 1_000_000
            self.clock_pub.publish(Clock(clock=_time(self.clock_ns)))
            self.spin(0.0002)
            stamp = _time(self.clock_ns)
        else:
            stamp = self.probe.get_clock().now().to_msg()
        for name, pub in self.pubs.items():
            if name in skip:
                continue
            value = current if (name == 'current_A' and current is not None) \
                else VALUES[name]
            if name in interface.PRESSURE_INPUTS:
                msg = FluidPressure(fluid_pressure=value)
                msg.header.stamp = stamp
            else:
                msg = Float64(data=value)
            pub.publish(msg)

    def feed(self, seconds, until=None, skip=()):
        """Publish every input but ``skip`` at 1 kHz (``NodeAndProbe.paced``)."""
        return self.paced(lambda: self.publish_samples(skip), seconds, until)

    def status(self, name):
        """Return the named status of the last diagnostics received (None before any)."""
        if not self.diagnostics:
            return None
        for s in self.diagnostics[-1].status:
            if s.name == f'eha_thermal_estimator: {name}':
                return s
        raise KeyError(name)

    def level(self, name):
        s = self.status(name)
        return None if s is None else s.level[0]

    def values(self, name):
        return {kv.key: kv.value for kv in self.status(name).values}

    def all_ok(self):
        return self.diagnostics and all(s.level[0] == OK for s in self.diagnostics[-1].status)


def _time(ns):
    return rclpy.time.Time(nanoseconds=ns).to_msg()


def _stamps(msgs):
    return [m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for m in msgs]


@pytest.fixture
def rig(context):
    r = Rig(context)
    yield r
    r.close()


@pytest.fixture
def whatif_rig(context):
    """Return a :class:`Rig` whose node serves what-ifs, as it does by default."""
    r = Rig(context, whatif=True)
    yield r
    r.close()


def open_loop_sigma(rig, name):
    """Return the estimator's propagated 1 sigma of ``name`` (K), without the fallback growth."""
    est = rig.node.session._est      # the estimator behind the session: its propagation
    return float(est.propagation.sigma_K()[est.model.quantities.names.index(name)])


def on_propagated_sigma(rig):
    """Return whether the last estimate of each name has the propagated variance exactly."""
    return all(msgs and msgs[-1].variance == pytest.approx(open_loop_sigma(rig, name) ** 2,
                                                           abs=1e-12)
               for name, msgs in rig.estimates.items())


def test_estimates_diagnostics_stale_speed_and_nan(rig):
    # fresh inputs: every status OK, estimates rising with strictly increasing stamps; the
    # last ones without a fallback's growth (a stall of this process, the probe's publisher
    # with it, makes a real data gap: the estimates after it are on the fallback a while)
    assert rig.feed(6.0, until=lambda: rig.all_ok() and len(rig.estimates['oil']) > 40
                    and on_propagated_sigma(rig)), str((
                        [(s.name, s.level, s.message) for s in rig.diagnostics[-1].status
                         if s.level[0] != OK],
                        {n: (m[-1].variance, open_loop_sigma(rig, n) ** 2)
                         for n, m in rig.estimates.items()}))
    for name, msgs in rig.estimates.items():
        stamps = _stamps(msgs)
        assert all(b > a for a, b in zip(stamps, stamps[1:])), name
        assert all(15.0 < m.temperature < 80.0 for m in msgs), name
        # the propagated sigma (zero at ambient, before the copies' first period ends),
        # more while an input is on its fallback (inputs may start one by one)
        assert all(m.variance >= open_loop_sigma(rig, name) ** 2 - 1e-12 for m in msgs), name
        assert msgs[-1].variance == pytest.approx(open_loop_sigma(rig, name) ** 2,
                                                  abs=1e-12), name
    hot = rig.estimates['winding_hotspot']
    assert hot[-1].temperature > hot[0].temperature and hot[-1].temperature > 20.05
    assert rig.level('estimate') == OK
    ttl = rig.values('estimate')['time_to_limit winding_hotspot [s]']
    assert ttl in ('pending', 'beyond horizon')

    # the speed topic falls silent: STALE with the held value, estimates keep coming
    n_before = len(hot)
    episodes = int(rig.values('input speed_rad_s')['stale_events'])   # 1 if it started late
    assert rig.feed(3.0, skip={'speed_rad_s'},
                    until=lambda: rig.level('input speed_rad_s') == STALE)
    rig.feed(0.6, skip={'speed_rad_s'})

    def only_speed_stale():
        """Tell whether the last report has the speed STALE and every other input OK."""
        # a stall of this process longer than the inputs' timeout makes them all stale
        return rig.level('input speed_rad_s') == STALE and all(
            rig.level(f'input {n}') == OK for n in rig.pubs if n != 'speed_rad_s')

    assert rig.feed(3.0, skip={'speed_rad_s'}, until=only_speed_stale), \
        str([(s.name, s.level, s.message) for s in rig.diagnostics[-1].status])
    speed = rig.status('input speed_rad_s')
    assert speed.level[0] == STALE
    assert speed.message.startswith('stale: holding last value 800 since ')
    assert speed.hardware_id == 'wet-eha-rig'
    assert rig.level('estimate') == OK
    assert 'on fallback: speed_rad_s' in rig.status('estimate').message
    assert rig.level('input current_A') == OK
    stamps = _stamps(hot)
    assert len(hot) > n_before + 5 and stamps[-1] - stamps[n_before - 1] > 0.25
    assert all(b > a for a, b in zip(stamps, stamps[1:]))
    # the uncertainty grows on the fallback
    assert hot[-1].variance > open_loop_sigma(rig, 'winding_hotspot') ** 2

    # it comes back: OK again, the stale episode counted
    assert rig.feed(3.0, until=lambda: rig.level('input speed_rad_s') == OK)
    assert int(rig.values('input speed_rad_s')['stale_events']) > episodes
    assert rig.feed(2.0, until=lambda: on_propagated_sigma(rig))

    # one NaN current sample: counted, the input WARNs in the report that counts it, then OK
    # (that report says STALE instead when a stall of this process outlasted the inputs'
    # timeout just then: another NaN sample, counted too)
    def counting(n, since):
        """Return the current's status in the first report from ``since`` that counts ``n``."""
        for report in rig.diagnostics[since:]:
            s = next(s for s in report.status if s.name.endswith(': input current_A'))
            if {kv.key: kv.value for kv in s.values}['non_finite'] == str(n):
                return s
        return None

    for n in range(1, 4):
        since = len(rig.diagnostics)
        rig.publish_samples(current=math.nan)
        assert rig.feed(2.0, until=lambda: counting(n, since) is not None)
        if counting(n, since).level[0] != STALE:
            break
    assert counting(n, since).level[0] == WARN, counting(n, since)
    assert rig.feed(2.0, until=lambda: rig.level('input current_A') == OK)


def test_current_limits_for_the_drive_every_half_second_and_their_fallback(rig):
    limits, binding = [], []
    rig.probe.create_subscription(JointState, interface.CURRENT_LIMITS_TOPIC, limits.append, 50)
    rig.probe.create_subscription(Float64, interface.CURRENT_LIMIT_TOPIC, binding.append, 50)
    drive = []
    rig.probe.create_subscription(
        Float64MultiArray, interface.DRIVE_LIMITS_TOPIC,
        lambda m: drive.append(interface.DriveLimits.from_data(m.data)), 50)

    def ticks_apart():
        """Return whether 4 limits said ok, two of them at successive ticks (0.5 s apart)."""
        s = _stamps([m for m in limits if m.header.frame_id == 'ok'])
        return len(s) >= 4 and any(abs(b - a - 0.5) < 1e-6 for a, b in zip(s, s[1:]))

    # (a stall of the machine puts a data gap, and fallback ticks, between two ok ones)
    assert rig.feed(10.0, until=ticks_apart)
    ok = [m for m in limits if m.header.frame_id == 'ok']
    m = ok[-1]
    assert list(m.name) == ['continuous', '10s', '60s', '600s']
    assert list(m.position) == [math.inf, 10.0, 60.0, 600.0]
    assert all(0.0 <= a <= 45.0 for a in m.effort)
    assert m.effort[1] >= m.effort[2] >= m.effort[3] >= m.effort[0]
    # stamped with the sample time of the tick: 0.5 s apart, never backwards
    stamps = _stamps(limits)
    assert all(b > a for a, b in zip(stamps, stamps[1:]))
    assert _stamps(ok)[-1] == pytest.approx(rig.estimates['oil'][-1].header.stamp.sec
                                            + 1e-9 * rig.estimates['oil'][-1].header.stamp.nanosec,
                                            abs=1.0)
    # the scalar is the shortest horizon's, message for message
    assert [b.data for b in binding][-len(ok):] == [x.effort[1] for x in limits][-len(ok):]
    # the speed falls silent: the limits drop to the fallback and say why (a stall of the
    # machine may first make every input stale, as the product rightly says: wait past it)
    n = len(limits)
    why = 'fallback: stale inputs: speed_rad_s'
    assert rig.feed(4.0, skip={'speed_rad_s'},
                    until=lambda: any(x.header.frame_id == why for x in limits[n:]))
    stale = [x for x in limits[n:] if x.header.frame_id == why][-1]
    assert max(stale.effort) <= 10.0
    # the drive's numbers: the same limits, stamps and status as codes, counted in sequence
    rig.spin(0.2)
    by_stamp = {d.stamp_ns: d for d in drive}
    for m in limits:
        d = by_stamp[m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec]
        assert list(d.limits_A) == list(m.effort) and list(d.horizons_s) == list(m.position)
        assert d.binding_A == m.effort[1] and d.binding_horizon_s == 10.0
        assert (d.status == interface.LimitStatus.OK) == (m.header.frame_id == 'ok')
        if m.header.frame_id.startswith('fallback: stale inputs'):
            assert d.status == interface.LimitStatus.STALE_INPUTS
    assert by_stamp[stale.header.stamp.sec * 1_000_000_000
                    + stale.header.stamp.nanosec].status == interface.LimitStatus.STALE_INPUTS
    assert [d.sequence for d in drive] == list(range(drive[0].sequence,
                                                     drive[0].sequence + len(drive)))
    assert rig.feed(2.0, skip={'speed_rad_s'}, until=lambda: rig.values('estimate')[
        'current limits status'].startswith('fallback: stale inputs'))


def test_latched_alert_and_acknowledge(context, tmp_path):
    cfg = yaml.safe_load(default_config_path().read_text())
    cfg['estimator']['alerts']['winding_hotspot'].update(
        warn_C=20.1, critical_C=200.0, hysteresis_K=0.0, min_duration_s=0.0, latch=True)
    path = tmp_path / 'low_warn.yaml'
    path.write_text(yaml.safe_dump(cfg))
    rig = Rig(context, [Parameter('config_file', value=str(path))])
    try:
        assert rig.feed(8.0, until=lambda: rig.node.session.status().alert_level >= WARN)
        assert rig.feed(2.0, until=lambda: rig.level('estimate') == WARN)
        # a subscriber created after the alert still gets it (transient local)
        late = []
        sub = rig.probe.create_subscription(String, interface.ALERT_TOPIC,
                                            lambda m: late.append(json.loads(m.data)),
                                            topics.latched_qos())
        assert rig.feed(3.0, until=lambda: late)
        assert late[-1]['level_name'] == 'WARN'
        assert late[-1]['hardware_id'] == 'wet-eha-rig'
        hot = late[-1]['quantities']['winding_hotspot']
        assert hot['reported'] == 'WARN' and not hot['acknowledged']
        assert 'winding_hotspot WARN' in late[-1]['message']
        # and as numbers, latched too: the winding's block by index (quantity 0, stride 8)
        numbers = []
        rig.probe.create_subscription(Float64MultiArray, interface.DRIVE_ALERTS_TOPIC,
                                      lambda m: numbers.append(m.data.tolist()),
                                      topics.latched_qos())
        assert rig.feed(3.0, until=lambda: numbers)
        w = 7 + 8 * list(late[-1]['quantities']).index('winding_hotspot')
        assert numbers[-1][4] == 1.0 and numbers[-1][w:w + 4] == [
            interface.ESTIMATES.index('winding_hotspot'), 1.0, 1.0, 0.0]
        # the state's names are latched too: one per element of the state
        names, states = [], []
        rig.probe.create_subscription(String, interface.STATE_NAMES_TOPIC,
                                      lambda m: names.append(json.loads(m.data)),
                                      topics.latched_qos())
        rig.probe.create_subscription(Float64MultiArray, interface.STATE_TOPIC, states.append, 10)
        assert rig.feed(3.0, until=lambda: names and states)
        assert names[0]['unit'] == 'K' and len(names[0]['names']) == len(states[-1].data)
        assert 'case' in names[0]['names']
        assert interface.STATE_NAMES_TOPIC in states[-1].layout.dim[0].label
        # acknowledging changes the summary: still active, now acknowledged
        n = len(late)
        rig.ack_pub.publish(String(data='winding_hotspot'))
        assert rig.feed(3.0, until=lambda: len(late) > n)
        assert late[-1]['quantities']['winding_hotspot']['acknowledged']
        assert '(acknowledged)' in late[-1]['message']
        # the events since the summary before: a data gap's may follow the acknowledgement's
        assert any('acknowledged' in e for m in late[n:] for e in m['events'])
        assert rig.feed(3.0, until=lambda: numbers[-1][w + 3] == 1.0)
        assert numbers[-1][w + 1] == 1.0          # still reported WARN: it is still active
        # an unknown quantity is logged and ignored, never raised
        rig.ack_pub.publish(String(data='no_such_quantity'))
        rig.feed(0.3)
        rig.probe.destroy_subscription(sub)
    finally:
        rig.close()


def test_one_differential_pressure_topic(context, tmp_path):
    cfg = yaml.safe_load(default_config_path().read_text())
    cfg['estimator']['pressure_inputs'] = 'differential'
    path = tmp_path / 'differential.yaml'
    path.write_text(yaml.safe_dump(cfg))
    rig = Rig(context, [Parameter('config_file', value=str(path))])
    try:
        assert set(rig.pubs) == {'current_A', 'speed_rad_s', 'dp_Pa', 'position_m'}
        assert rig.feed(6.0, until=lambda: rig.all_ok() and len(rig.estimates['oil']) > 20)
        names = [s.name for s in rig.diagnostics[-1].status]
        assert 'eha_thermal_estimator: input dp_Pa' in names
        assert 'eha_thermal_estimator: input p_a_Pa' not in names
        assert rig.values('input dp_Pa')['topic'] == '/eha/pressure_diff'
        # the counters are the last diagnostics message's: on a busy machine the first ones
        # came before 200 samples had been taken
        assert rig.feed(6.0, until=lambda: int(rig.values('input dp_Pa')['accepted']) > 200)
    finally:
        rig.close()


class JointStateBroadcasters:
    """Plays ros2_control's joint_state_broadcasters as ros2_control_rig.inputs.yaml has them."""

    # the SI values of VALUES in the rig's own units: A amplitude, bar gauge, the rod's sign
    MOTOR = {'velocity': VALUES['speed_rad_s'], 'effort': VALUES['current_A'] * math.sqrt(2.0)}
    ROD = -VALUES['position_m']
    GAUGE_BAR = {f'pressure_{n}': VALUES[f'p_{n}_Pa'] / 1e5 - 1.01325 for n in ('a', 'b', 'acc')}
    # the air and the frame's thermocouple, degC (the frame at what a cold start estimates)
    TEMPERATURES_C = {'ambient': 23.5, 'tc_frame': 23.5}

    def __init__(self, probe, dither_K=0.0):
        """``dither_K``: the frame's thermocouple reads alternately this much above and below."""
        self.probe = probe
        self.dither_K = dither_K
        self._sign = 1.0
        self.joints = probe.create_publisher(JointState, '/joint_states', 100)
        self.pressures = probe.create_publisher(
            JointState, '/pressure_state_broadcaster/joint_states', 100)
        self.temperatures = probe.create_publisher(
            JointState, '/temperature_state_broadcaster/joint_states', 10)

    def publish(self):
        stamp = self.probe.get_clock().now().to_msg()
        msg = JointState(name=['eha_rod', 'eha_motor'], position=[self.ROD, 12.0],
                         velocity=[0.0, self.MOTOR['velocity']],
                         effort=[0.0, self.MOTOR['effort']])
        msg.header.stamp = stamp
        self.joints.publish(msg)
        names = list(self.GAUGE_BAR)
        msg = JointState(name=names, effort=[self.GAUGE_BAR[n] for n in names])
        msg.header.stamp = stamp
        self.pressures.publish(msg)
        self._sign = -self._sign
        temperatures = dict(self.TEMPERATURES_C)
        temperatures['tc_frame'] += self._sign * self.dither_K
        names = list(temperatures)
        msg = JointState(name=names, effort=[temperatures[n] for n in names])
        msg.header.stamp = stamp
        self.temperatures.publish(msg)


def test_a_ros2_control_rig_connects_with_a_parameters_file(context):
    params = ROOT / 'config' / 'ros2_control_rig.params.yaml'
    node = EstimatorNode(context=context, cli_args=[
        '--ros-args', '--params-file', str(params), '-p', 'diagnostics_rate_Hz:=5.0'])
    rig = NodeAndProbe(context, node, rclpy.create_node('jsb_probe', context=context))
    try:
        # a live thermocouple's noise moves it: one frozen for half the stuck window (1.5 s of
        # readings) is 'held', a WARN, and all OK would have to come before that
        dither_K = 0.05
        jsb = JointStateBroadcasters(rig.probe, dither_K)
        estimates, diagnostics = [], []
        rig.probe.create_subscription(Temperature, f'{interface.ESTIMATE_PREFIX}/oil',
                                      estimates.append, 100)
        rig.probe.create_subscription(DiagnosticArray, interface.DIAGNOSTICS_TOPIC,
                                      diagnostics.append, 10)

        def all_ok():
            return diagnostics and all(s.level[0] == OK for s in diagnostics[-1].status)

        def enough():
            return all_ok() and len(estimates) > 20 and min(
                node.session.health[n].accepted for n in node.session.inputs) > 100

        end = time.monotonic() + 10.0 * PATIENCE
        next_t = time.monotonic()
        while time.monotonic() < end and not enough():
            if time.monotonic() >= next_t:
                jsb.publish()
                next_t = max(next_t + 0.001, time.monotonic() - 0.005)
            rig.spin(0.0005)
        assert enough(), str(([(s.name, s.level, s.message) for s in diagnostics[-1].status
                               if s.level[0] != OK] if diagnostics else None, len(estimates),
                              {n: node.session.health[n].accepted for n in node.session.inputs}))
        # each input read from its joint and field, converted to SI, with the header's stamp
        for name, value in VALUES.items():
            if name in node.session.inputs:
                h = node.session.health[name]
                assert h.last_value == pytest.approx(value, rel=1e-12), name
                assert h.rejected == 0, name
        topics_of = {s.name: {kv.key: kv.value for kv in s.values}.get('topic')
                     for s in diagnostics[-1].status}
        assert topics_of['eha_thermal_estimator: input speed_rad_s'] == '/joint_states'
        assert topics_of['eha_thermal_estimator: input p_acc_Pa'] == \
            '/pressure_state_broadcaster/joint_states'
        assert node.count_subscribers('/joint_states') == 1
        # the air and the thermocouple from their joints, in degC, at the message's stamp
        assert node.session.ambient_K == pytest.approx(23.5 + C_TO_K, rel=1e-12)
        assert node.session.measured_C['frame'][1] in (
            pytest.approx(23.5 - dither_K, rel=1e-12), pytest.approx(23.5 + dither_K, rel=1e-12))
        assert topics_of['eha_thermal_estimator: thermocouple frame'] == \
            '/temperature_state_broadcaster/joint_states'
        stamps = _stamps(estimates)
        assert all(b > a for a, b in zip(stamps, stamps[1:]))
    finally:
        rig.close()


def test_use_sim_time_stamps_follow_clock(context):
    rig = Rig(context, [Parameter('use_sim_time', value=True)], sim_time=True)
    try:
        def enough():
            return len(rig.estimates['oil']) >= 10

        end = time.monotonic() + 8.0 * PATIENCE
        while time.monotonic() < end and not enough():
            rig.publish_samples()
            rig.spin(0.0003)
        stamps = _stamps(rig.estimates['oil'])
        assert len(stamps) >= 10
        assert all(b > a for a, b in zip(stamps, stamps[1:]))
        assert 1000.0 < stamps[0] and stamps[-1] <= rig.clock_ns * 1e-9 + 1e-9
    finally:
        rig.close()


def test_params_file_and_ranges(context):
    params = ROOT / 'config' / 'estimator.params.yaml'
    node = EstimatorNode(context=context, cli_args=[
        '--ros-args', '--params-file', str(params), '-p', 'publish_rate_Hz:=20',
        '-p', 'whatif:=false'])
    try:
        assert node.get_parameter('publish_rate_Hz').value == 20.0
        # no what-if worker, and no what-if topics
        assert node.runner.whatif is None
        assert not [e.topic_name for e in [*node.publishers, *node.subscriptions]
                    if 'whatif' in e.topic_name]
        assert node.get_parameter('qos').value == 'sensor_data'
        assert node.get_parameter('executor').value == 'events'
        assert node.runner.publish_timer.timer_period_ns == 50_000_000
        d = node.describe_parameter('publish_rate_Hz')
        assert d.floating_point_range[0].to_value == 500.0 and d.description
    finally:
        node.destroy_node()
    with pytest.raises(InvalidParameterValueException):
        EstimatorNode(context=context,
                      parameter_overrides=[Parameter('publish_rate_Hz', value=1000.0)])


def _run_main(*args, interrupt_after=None):
    """
    Run the node's main; return (exit status, what it printed).

    With ``interrupt_after`` the node gets SIGINT once it has printed that
    text: it first loads (or, on a cold cache, compiles) the model step, which
    takes from a second to over a minute, so a fixed wait would be a race. It
    then has 12 s times PATIENCE to stop: a quiet machine's node stops in 0.4 to
    0.6 s, but one run among other test workers beside a busy core once had
    printed nothing after 15 s (a deadline for a fact, the exit, never a pace).
    """
    env = dict(os.environ, OPENBLAS_NUM_THREADS='1', PYTHONUNBUFFERED='1')
    proc = subprocess.Popen([sys.executable, '-m', 'wet_eha_thermal.ros.estimator_node', *args],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
    lines, seen = [], threading.Event()

    def read():
        for line in proc.stdout:
            lines.append(line)
            if interrupt_after is not None and interrupt_after in line:
                seen.set()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    if interrupt_after is not None:
        seen.wait(timeout=180.0)          # a cold compile takes up to about 90 s here
        proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=12.0 * PATIENCE if interrupt_after is not None else 180)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        reader.join(timeout=5)
        pytest.fail(f'the node did not stop: {"".join(lines)}')
    reader.join(timeout=5)
    return proc.returncode, ''.join(lines)


def test_main_runs_and_stops_cleanly_on_ctrl_c():
    rc, text = _run_main('--executor', 'events', '--ros-args', '--params-file',
                         'config/estimator.params.yaml', '-p', 'publish_rate_Hz:=20',
                         '-p', 'topic_prefix:=/eha_main_test',
                         interrupt_after='spinning with the events executor')
    assert rc == 0, text
    assert 'spinning with the events executor' in text and 'Traceback' not in text
    # its counts as data for live, besides the summary line for people
    report = interface.NodeReport.find(text.splitlines())
    assert report is not None and report.node == interface.ESTIMATOR_NODE, text
    assert set(report.inputs) >= {'current_A', 'speed_rad_s'} and 'estimates' in report.figures
    rc, text = _run_main('--ros-args', '-p', 'qos:=fast')
    assert rc == 2 and 'qos' in text and 'Traceback' not in text


def test_model_failure_keeps_publishing_and_reports_error(rig):
    assert rig.feed(5.0, until=lambda: len(rig.estimates['oil']) > 10)

    def broken(now_s=None):
        raise FloatingPointError('injected')

    def broken_push(*args):
        raise RuntimeError('injected')

    rig.node.session._est.advance = broken
    rig.node.session._est.push = broken_push
    n = len(rig.estimates['oil'])
    assert rig.feed(3.0, until=lambda: rig.level('estimate') == ERROR
                    and len(rig.estimates['oil']) > n + 10)
    assert 'model step failed' in rig.status('estimate').message
    stamps = _stamps(rig.estimates['oil'])
    assert all(b > a for a, b in zip(stamps, stamps[1:]))
    assert int(rig.values('input current_A')['callback_errors']) > 0
    # a rate change at run time takes effect; read-only parameters refuse
    assert rig.node.set_parameters([Parameter('publish_rate_Hz', value=10.0)])[0].successful
    assert rig.node.runner.publish_timer.timer_period_ns == 100_000_000
    assert not rig.node.set_parameters([Parameter('qos', value='reliable')])[0].successful


def test_thermocouple_corrects_the_estimate_and_goes_stale(context):
    # the shipped configuration has the live correction on: frame readings 1 K above the
    # (cold) model pull its frame estimate up and shrink the published variance. On sim
    # time, 1 ms per sample however fast the machine lets the probe publish, and reliable:
    # correcting and going stale are facts of sample time, and a loaded machine that stalls
    # the probe or the node (a 1.1 s stall once failed a wall-paced version) changes nothing
    rig = Rig(context, [Parameter('use_sim_time', value=True)], sim_time=True, qos='reliable')
    try:
        frame = []
        rig.probe.create_subscription(Temperature, f'{interface.ESTIMATE_PREFIX}/frame',
                                      frame.append, 100)
        pub = rig.probe.create_publisher(Temperature, f'{interface.MEASURED_PREFIX}/frame',
                                         rig.in_qos)
        rng = np.random.default_rng(1)
        sent = []           # the readings' stamps (s)

        def feed(until, readings=True):
            """Publish samples, a reading each 0.1 s of sample time, until ``until()``."""
            end = time.monotonic() + 120.0      # a deadline, never a rate
            while time.monotonic() < end:
                rig.publish_samples()
                if readings and rig.clock_ns % 100_000_000 == 0:
                    msg = Temperature(temperature=21.0 + float(rng.normal(0.0, 0.2)))
                    msg.header.stamp = _time(rig.clock_ns)
                    pub.publish(msg)
                    sent.append(rig.clock_ns * 1e-9)
                rig.spin(0.0003)
                if until():
                    return True
            return False

        def corrected():
            return (rig.diagnostics and rig.values('thermocouple frame')['status'] == 'ok'
                    and frame and frame[-1].variance < 1.5 ** 2
                    and frame[-1].temperature > 20.5)

        assert feed(corrected), (frame[-1:], rig.values('thermocouple frame'))
        status = rig.status('thermocouple frame')
        assert status.level[0] == OK and status.message == 'correcting the model'
        assert int(rig.values('thermocouple frame')['used']) > 0
        assert rig.values('estimate')['correction'] == 'on, correcting with: frame'
        assert rig.level('thermocouple winding') == OK          # no reading yet: not an error
        assert rig.status('thermocouple winding').message == 'no reading yet'
        # silent for the stale timeout (2 s of sample time): STALE, not used, and the
        # estimates keep coming: stamped past the timeout, in order
        timeout_s = rig.node.runner.cfg.estimator.correction.stale_timeout_s
        n = len(frame)
        assert feed(lambda: rig.level('thermocouple frame') == STALE, readings=False)
        assert rig.clock_ns * 1e-9 > sent[-1] + timeout_s
        assert rig.values('thermocouple frame')['stale_events'] == '1'
        assert feed(lambda: frame and _stamps(frame[-1:])[0] > sent[-1] + timeout_s,
                    readings=False)
        stamps = _stamps(frame[n - 1:])
        assert all(b > a for a, b in zip(stamps, stamps[1:]))
    finally:
        rig.close()


def test_foxglove_view_shows_the_published_estimates(context):
    rig = Rig(context, overrides=[Parameter('foxglove_address', value='127.0.0.1:0')])
    client = None
    try:
        view = rig.node.runner.view.view           # the node's Foxglove glue, and its LiveView
        assert view is not None and view.port > 0
        client = Client(view.port)
        client.read(lambda: len(client.channels) == len(CHANNELS))
        names = view_topics()
        client.subscribe([names['temperatures'], names['alerts']])
        published = {}

        def matched():
            """Return whether a view message carries an estimate published on ROS."""
            client.drain()
            published.update({(m.header.stamp.sec, m.header.stamp.nanosec): m
                              for m in rig.estimates['winding_hotspot']})
            return any((m['timestamp']['sec'], m['timestamp']['nsec']) in published
                       for _, m in client.messages(names['temperatures'])[-5:])

        assert rig.feed(10.0, until=matched)
        _, m = next((t, m) for t, m in reversed(client.messages(names['temperatures']))
                    if (m['timestamp']['sec'], m['timestamp']['nsec']) in published)
        ros = published[m['timestamp']['sec'], m['timestamp']['nsec']]
        assert m['winding_hotspot']['estimate_C'] == ros.temperature
        assert m['winding_hotspot']['sigma_K'] ** 2 == pytest.approx(ros.variance)
        assert rig.feed(5.0, until=lambda: client.drain() or client.messages(names['alerts']))
        assert client.last[names['alerts']]['oil']['reported'] == 'OK'
        # a safe parameter set from Foxglove is set on the node (on its own thread)
        client.ws.send(json.dumps({'op': 'setParameters', 'id': 's', 'parameters': [
            {'name': 'publish_rate_Hz', 'value': 10.0}]}))
        assert rig.feed(5.0, until=lambda: rig.node.get_parameter('publish_rate_Hz').value
                        == 10.0)
        assert rig.node.runner.publish_timer.timer_period_ns == 100_000_000
        assert rig.feed(5.0, until=lambda: rig.level('estimate') is not None
                        and 'ws://127.0.0.1:' in rig.values('estimate')['foxglove view'])
        # a second estimator on the same address runs without the view, and says why
        other = EstimatorNode(context=context, parameter_overrides=[
            Parameter('foxglove_address', value=f'127.0.0.1:{view.port}'),
            Parameter('topic_prefix', value='/eha_taken_port'), Parameter('whatif', value=False)])
        try:
            assert other.runner.view.view is None and 'in use' in other.runner.view.error
        finally:
            other.destroy_node()
    finally:
        if client is not None:
            client.close()
        rig.close()


def test_whatif_is_answered_while_the_estimates_go_on(whatif_rig):
    """
    A three-minute what-if runs beside the estimator, whose estimates keep up with the samples.

    Three minutes of stage 6 take a few seconds of the worker on a quiet machine: a stall of
    the node for the what-if's time would exceed the 0.5 s gap bound several times over
    (ten minutes checked the same at three times the cost).
    """
    rig = whatif_rig
    answers, arrivals = [], []
    rig.probe.create_subscription(String, interface.WHATIF_RESPONSE_TOPIC,
                                  lambda m: answers.append(json.loads(m.data)),
                                  QoSProfile(depth=10))

    def arrived(m):     # when, and how far the estimate trails the clock its samples carry
        now = rig.probe.get_clock().now().nanoseconds * 1e-9
        arrivals.append((time.monotonic(), now - _stamps([m])[0]))

    rig.probe.create_subscription(Temperature, f'{interface.ESTIMATE_PREFIX}/frame', arrived, 100)
    pub = rig.probe.create_publisher(String, interface.WHATIF_REQUEST_TOPIC,
                                     QoSProfile(depth=10))
    end = time.monotonic() + 10.0 * PATIENCE
    while pub.get_subscription_count() == 0 and time.monotonic() < end:
        rig.spin(0.01)
    # no sample yet: nothing to start from, said at once
    pub.publish(String(data='{"id": "early", "stage": 6, "duration_s": 60}'))
    end = time.monotonic() + 10.0 * PATIENCE
    while not answers and time.monotonic() < end:
        rig.spin(0.01)
    assert answers and answers[0]['id'] == 'early' and 'no state yet' in answers[0]['error']
    assert rig.feed(10.0, until=lambda: len(arrivals) > 100)
    before = len(arrivals)
    rig.feed(2.0)
    t0 = time.monotonic()
    lag_before = max(lag for _, lag in arrivals[before:])
    pub.publish(String(data='{"id": "long", "stage": 6, "duration_s": 180}'))
    pub.publish(String(data='{"id": "second", "stage": 6, "duration_s": 60}'))
    assert rig.feed(120.0, until=lambda: any(a['id'] == 'long' for a in answers))
    t1 = time.monotonic()
    by_id = {a['id']: a for a in answers}
    assert "busy: what-if 'long'" in by_id['second']['error']
    long = by_id['long']
    assert long['ok'] and long['time_s'][-1] == 180.0 and long['source'] == 'live estimator'
    assert long['start_stamp_s'] is not None and set(long['temperatures_C']) == set(
        interface.ESTIMATES)
    during = [(t, lag) for t, lag in arrivals if t0 <= t <= t1]
    gaps = np.diff([t for t, _ in during])
    lag_during = max(lag for _, lag in during)
    print(f'what-if of 3 min of stage 6: {t1 - t0:.1f} s wall ({long["wall_s"]:.1f} s in the '
          f'worker); {len(during)} estimates, each behind its newest sample by at most '
          f'{lag_before * 1e3:.0f} ms before and {lag_during * 1e3:.0f} ms during; longest gap '
          f'{gaps.max() * 1e3:.0f} ms')
    # no stall (a what-if worked in the node would hold the estimates for its own time), and
    # the estimates kept up with the samples: on a busy machine the node and this probe, one
    # executor, slow alike, so a rate in wall time would measure the machine, not the node.
    # The lag has the gaps' bound: a machine busy enough to slow the worker (68 s of wall for
    # its 30 s at load 4.6) slowed the node too (1.007 s of lag), while a stall for the
    # what-if makes the lag the worker's whole time
    bound_s = max(0.5, 0.25 * long['wall_s'])
    assert len(during) > 10 and gaps.max() < bound_s and lag_during < max(1.0, bound_s)


def test_whatif_command_asks_the_running_estimator(whatif_rig, tmp_path, capsys):
    """``wet-eha-thermal whatif`` without --bag gets its answer from the node over ROS."""
    rig = whatif_rig
    from wet_eha_thermal import cli

    assert rig.feed(10.0, until=lambda: len(rig.estimates['oil']) > 20)
    done = []
    worker = threading.Thread(target=lambda: done.append(cli.main([
        'whatif', '--stage', '3', '--duration', '30', '--timeout', '60',
        '--out', str(tmp_path)])))
    worker.start()
    assert rig.feed(60.0, until=lambda: done)
    worker.join(timeout=5.0)
    assert done == [0]
    text = capsys.readouterr().out
    assert 'What-if from live estimator (its state at sample time ' in text
    assert '): stage 3' in text and 'not within the run' in text
    stamp = float(text.split('sample time ')[1].split(' s)')[0])
    first = np.genfromtxt(tmp_path / 'whatif.csv', delimiter=',', names=True)[0]
    assert first['time_s'] == 0.0
    # it starts from the estimate the node published for that sample time
    at = next(m for m in rig.estimates['oil'] if abs(_stamps([m])[0] - stamp) < 1e-5)
    assert first['oil_C'] == pytest.approx(at.temperature, abs=1e-4)


def test_whatif_command_says_when_no_estimator_answers(tmp_path, capsys, monkeypatch):
    from wet_eha_thermal import cli
    from wet_eha_thermal.ros import whatif_client

    # discovery on this machine's loopback takes well under a second
    monkeypatch.setattr(whatif_client, 'FIND_TIMEOUT_S', 2.0)
    assert cli.main(['whatif', '--stage', '6', '--topic-prefix', '/nobody_here',
                     '--out', str(tmp_path)]) == 2
    assert 'no estimator subscribes to /nobody_here/whatif/request' in capsys.readouterr().err


def test_a_replay_writes_what_the_node_published_for_the_same_samples(
        context, record_rig_log, tmp_path):
    # a recording of the rig (the topics a live run records) goes through the node, each
    # sample on its callback with the clock at its log time (the stamp a Float64 got live),
    # and through replay: every estimator topic the same, message by message
    from collections import defaultdict
    import functools

    from mcap.reader import make_reader
    from rclpy.serialization import deserialize_message
    from wet_eha_thermal.bag.reader import iter_raw
    from wet_eha_thermal.offline import replay as rp

    bag = record_rig_log(tmp_path / 'rig.mcap', 6.0, seed=5)
    # an alert raised half-way (the winding's warning at its temperature then: a run
    # without the limits, which the temperatures do not depend on, finds it)
    plan = rp.plan_replay(bag)
    first = rp.replay(plan, output_rate_Hz=50.0, outlook=False)
    data = yaml.safe_load(plan.config_yaml)
    data['estimator']['alerts']['winding_hotspot'].update(
        warn_C=float(first.temperatures_C['winding_hotspot'][len(first.stamp_s) // 2]),
        critical_C=400.0, min_duration_s=0.1)
    cfg_file = tmp_path / 'rig.yaml'
    cfg_file.write_text(yaml.safe_dump(data))
    plan = rp.plan_replay(bag, config_path=cfg_file)
    result = rp.replay(plan, output_rate_Hz=50.0)
    mcap = rp.write_mcap(result, tmp_path / 'estimates.mcap')
    replayed = defaultdict(list)
    with open(mcap, 'rb') as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
            replayed[channel.topic].append(message.data)

    node = EstimatorNode(context=context, parameter_overrides=[
        Parameter('config_file', value=str(cfg_file)), Parameter('whatif', value=False)])
    try:
        published = defaultdict(list)
        for topic, pub in node.runner.pubs.items():
            pub.publish = functools.partial(lambda t, msg: published[t].append(msg), topic)
        clock = {'ns': 0}
        node.runner.clock.now_ns = lambda: clock['ns']
        # the node's callback with the decoders of the default inputs, ambient and
        # thermocouples (the rig's topics)
        channels = list(node.session.inputs) + [AMBIENT] + [
            thermocouple_channel(tc) for tc in interface.THERMOCOUPLES]
        decoder = {dec.topic: dec for dec in decoders(load_inputs(''), channels)}
        topics_read = list(plan.inputs.values()) + [plan.ambient] + list(
            plan.thermocouples.values())
        for m in iter_raw(bag, topics_read):
            clock['ns'] = m.log_time_ns
            node.runner._on_input(decoder[m.topic], m.data)
            while node.session.work(1.0):       # the limits never wait (replay's are inline)
                pass
        assert not node.runner.callback_errors and node.session.status().model_errors == 0
    finally:
        node.destroy_node()
    for topic in [f'{interface.ESTIMATE_PREFIX}/{n}' for n in interface.ESTIMATES] + [
            interface.STATE_TOPIC, interface.CURRENT_LIMITS_TOPIC, interface.CURRENT_LIMIT_TOPIC,
            interface.DRIVE_LIMITS_TOPIC]:
        assert len(published[topic]) == len(replayed[topic]) > 0, topic
        assert published[topic] == replayed[topic], topic
    assert len(published[interface.STATE_TOPIC]) == len(result.stamp_s) > 250
    assert len(replayed[interface.CURRENT_LIMITS_TOPIC]) >= 10
    # the alert summaries: the node's since its first (published at its start), a
    # replay's since its own first; the same levels, acknowledgements and events, in the
    # same order (one summary per call: each at the last estimate of its call)

    def key(data):
        s = json.loads(deserialize_message(data, String).data)
        return (s['level'], s['events'], s['data_gaps'], s['clock_jumps'],
                {q: (d['reported'], d['active'], d['acknowledged'])
                 for q, d in s['quantities'].items()})

    live = [key(d) for d in published[interface.ALERT_TOPIC]]
    replay = [key(d) for d in replayed[interface.ALERT_TOPIC][1:]]
    assert live == replay and live[-1][0] == 1 and live[0][1], live
    # the drive's numbers of each summary, numbered alike (the node's first went out at
    # its start): the same sequence, levels, acknowledgements, thresholds and changes

    def numbers(data):
        a = interface.DriveAlerts.from_data(
            deserialize_message(data, Float64MultiArray).data.tolist())
        return (a.sequence, a.level, [(q.quantity, q.reported, q.active, q.acknowledged,
                                       q.warn_C, q.critical_C, q.since_s) for q in a.quantities])

    live = [numbers(d) for d in published[interface.DRIVE_ALERTS_TOPIC]]
    replay = [numbers(d) for d in replayed[interface.DRIVE_ALERTS_TOPIC][1:]]
    assert live == replay and live[0][0] == 2 and live[-1][1] == 1, live
