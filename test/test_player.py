"""
Bag player: payloads, QoS, /clock, an estimator on sim time, loops, cut and foreign files.

The player runs as a subprocess (its command line, as users run it) on this
module's own ROS domain; a probe node and an estimator with use_sim_time
spin in this process in one EventsExecutor, with timeouts.
"""

import os
from pathlib import Path
import signal
import subprocess
import sys
import time

import pytest
import rclpy
from rclpy.experimental import EventsExecutor
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from rclpy.task import Future
from rclpy.time import Time
from ros_domains import claim_domain
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import FluidPressure, Temperature
from std_msgs.msg import Float64, String
from wet_eha_thermal import interface
from wet_eha_thermal.bag.reader import iter_raw, open_bag
from wet_eha_thermal.bag.writer import BagWriter, qos_profiles
from wet_eha_thermal.interface import FLOAT64, FLUID_PRESSURE
from wet_eha_thermal.ros import topics
from wet_eha_thermal.ros.estimator_node import EstimatorNode
from wet_eha_thermal.ros.player import (LOOP_GAP_NS, main, PlayerNode, recorded_qos,
                                        shift_header_stamp)

pytestmark = pytest.mark.slow     # measured: see docs/development.md#tests-and-ci

# this module's own domain, this machine only; conftest puts it in ROS_DOMAIN_ID while it runs
DOMAIN_ID = claim_domain()
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

ROOT = Path(__file__).resolve().parents[1]
T0_NS = 1_700_000_000 * 10**9
PERIOD_NS = 5_000_000                 # 200 Hz inputs
INPUTS = ('current_A', 'speed_rad_s', 'p_a_Pa', 'p_b_Pa', 'p_acc_Pa', 'position_m')
VALUES = {'current_A': 20.0, 'speed_rad_s': 800.0, 'p_a_Pa': 1.2e6, 'p_b_Pa': 1.0e6,
          'p_acc_Pa': 1.0e6, 'position_m': 0.002}
ALERT = '{"level": 0, "message": "OK"}'
REMAP = {interface.ALERT_TOPIC: '/bag/alerts'}


def _stamp(ns):
    return Time(nanoseconds=ns).to_msg()


def write_bag(path, duration_s):
    """Write the estimator's inputs at 200 Hz (receive times 10 us apart) and one alert."""
    with BagWriter(path, flush_interval_s=0.25) as bag:
        for name in INPUTS:
            bag.add_topic(interface.INPUT_TOPICS[name],
                          FLUID_PRESSURE if name in interface.PRESSURE_INPUTS else FLOAT64,
                          qos_profiles(topics.input_qos('reliable', 100)))
        bag.add_topic(interface.ALERT_TOPIC, 'std_msgs/msg/String',
                      qos_profiles(topics.latched_qos()))
        for i in range(round(duration_s * 1e9 / PERIOD_NS) + 1):
            for k, name in enumerate(INPUTS):
                log_ns = T0_NS + i * PERIOD_NS + k * 10_000
                value = VALUES[name] * (1.0 + 0.01 * (i % 7))
                if name in interface.PRESSURE_INPUTS:
                    msg = FluidPressure(fluid_pressure=value)
                    msg.header.stamp = _stamp(log_ns)
                else:
                    msg = Float64(data=value)
                bag.write(interface.INPUT_TOPICS[name], serialize_message(msg), log_ns)
            if i == 20:
                bag.write(interface.ALERT_TOPIC, serialize_message(String(data=ALERT)),
                          T0_NS + i * PERIOD_NS + 90_000)
    return path


def same_payloads(received, recorded):
    """Return whether the messages are the recorded CDR (DDS pads it to 4 bytes)."""
    return len(received) == len(recorded) and all(
        r[:len(b)] == b and not r[len(b):].strip(b'\0') and len(r) - len(b) < 4
        for r, b in zip(received, recorded))


def bag_payloads(path):
    out = {}
    for m in iter_raw(path):
        out.setdefault(m.topic, []).append(m.data)
    return out


@pytest.fixture(scope='module')
def bag3(tmp_path_factory):
    return write_bag(tmp_path_factory.mktemp('bags') / 'inputs.mcap', 3.0)


class Probe:
    """Raw subscribers to every topic of a bag, /clock, optionally an estimator on sim time."""

    def __init__(self, context, bag, estimator=False):
        self.node = rclpy.create_node('player_test_probe', context=context)
        self.executor = EventsExecutor(context=context)
        self.executor.add_node(self.node)
        self.raw = {}
        for topic, entry in open_bag(bag).topics.items():
            qos = (topics.latched_qos() if topic == interface.ALERT_TOPIC   # needs transient local
                   else QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
            # the estimator publishes alerts too: the bag's are remapped (see play)
            self.node.create_subscription(topics.message_class(entry.type_name),
                                          REMAP.get(topic, topic),
                                          self.raw.setdefault(topic, []).append, qos, raw=True)
        self.clock_ns = []
        self.node.create_subscription(
            Clock, '/clock', lambda m: self.clock_ns.append(
                m.clock.sec * 1_000_000_000 + m.clock.nanosec),
            QoSProfile(depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT))
        self.estimates = []
        self.estimator = None
        if estimator:
            self.estimator = EstimatorNode(context=context, parameter_overrides=[
                Parameter('use_sim_time', value=True), Parameter('whatif', value=False)])
            self.executor.add_node(self.estimator)
            self.node.create_subscription(
                Temperature, f'{interface.ESTIMATE_PREFIX}/winding_hotspot',
                self.estimates.append, 1000)
        self._never = Future()

    def spin(self, seconds):
        self.executor.spin_until_future_complete(self._never, timeout_sec=seconds)

    def play(self, bag, *args, stop_when=None, timeout_s=30.0):
        """
        Run the player on ``bag`` while spinning; return (exit status, stderr).

        With ``stop_when`` the player gets SIGTERM once that returns true (or
        at ``timeout_s``): its start-up, discovery included, takes from half a
        second to several on a busy machine, so a fixed wait would be a race.
        """
        env = dict(os.environ, OPENBLAS_NUM_THREADS='1', PYTHONUNBUFFERED='1')
        proc = subprocess.Popen(
            [sys.executable, '-m', 'wet_eha_thermal.ros.player', str(bag), '--wait-subscribers',
             '--remap', *(f'{k}:={v}' for k, v in REMAP.items()), *args],
            cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        start = time.monotonic()
        while proc.poll() is None and time.monotonic() - start < timeout_s:
            self.spin(0.01)
            if stop_when is not None and (stop_when()
                                          or time.monotonic() - start > timeout_s - 1.0):
                proc.send_signal(signal.SIGTERM)
                stop_when = None
        try:
            _, err = proc.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            _, err = proc.communicate()
            pytest.fail(f'the player did not stop: {err}')
        self.spin(0.3)     # what is still on its way
        return proc.returncode, err

    def close(self):
        self.executor.shutdown()
        if self.estimator is not None:
            self.estimator.destroy_node()
        self.node.destroy_node()


@pytest.fixture(scope='module')
def played(context, bag3):
    """Play the 3 s bag at rate 2 to raw subscribers and an estimator with use_sim_time."""
    probe = Probe(context, bag3, estimator=True)
    try:
        start = time.monotonic()
        rc, err = probe.play(bag3, '--rate', '2')
        probe.wall_s = time.monotonic() - start
        probe.rc, probe.err = rc, err
        yield probe
    finally:
        probe.close()


def test_every_message_with_identical_payload_and_clock_to_the_end(played, bag3):
    assert played.rc == 0, played.err
    assert 'done:' in played.err and 'Traceback' not in played.err
    expected = bag_payloads(bag3)
    assert set(expected) == {interface.INPUT_TOPICS[n] for n in INPUTS} | {interface.ALERT_TOPIC}
    for topic, payloads in expected.items():
        assert len(played.raw[topic]) == len(payloads), topic
        assert same_payloads(played.raw[topic], payloads), topic
    info = open_bag(bag3)
    clock = played.clock_ns
    assert clock[0] == info.start_time_ns and clock[-1] == info.end_time_ns
    assert all(b >= a for a, b in zip(clock, clock[1:]))
    # /clock between the bursts too, not only at the start and the end; how many depends on
    # how often the busy machine woke the player and on a best-effort, depth-1 subscription
    # (its pace on a driven clock: test_step_follows_the_scaled_timeline_...)
    assert len(clock) > 2
    assert 1.5 < played.wall_s


def test_estimator_on_sim_time_stamps_within_the_bag(played, bag3):
    info = open_bag(bag3)
    stamps = [m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for m in played.estimates]
    # 50 Hz estimates over the 3 s of the bag when the estimator keeps up, but a sim-time
    # timer that falls behind fires once for the ticks it missed (this process also takes
    # every message raw): 21 once at load 11. The claim is where they are stamped
    assert len(stamps) >= 2, played.estimator.session.health
    assert all(b > a for a, b in zip(stamps, stamps[1:]))
    assert info.start_time_ns * 1e-9 <= stamps[0] and stamps[-1] <= info.end_time_ns * 1e-9
    assert all(15.0 < m.temperature < 80.0 for m in played.estimates)
    # /clock came first: no sample had to wait for it
    assert played.estimator.runner.waiting_for_clock == 0
    assert all(h.received > 0 for h in played.estimator.session.health.values())


def test_step_follows_the_scaled_timeline_and_the_clock_jumps_back_in_loops(context, tmp_path):
    bag = write_bag(tmp_path / 'tiny.mcap', 0.01)      # 3 sample times, 5 ms apart
    info = open_bag(bag)
    span_ns = info.end_time_ns - info.start_time_ns   # 10 ms and the 50 us of receive times
    probe = Probe(context, bag)
    player = PlayerNode(info, rate=2.0, loop=True, clock_hz=10.0, delay_s=0.0,
                        context=context)
    try:
        t0_s = player.anchor_s
        times_s = []
        now_s = t0_s - 0.001                  # before the start: /clock holds the start time
        for _ in range(7):
            wake_s = player.step(now_s)
            probe.spin(0.05)
            times_s.append((wake_s - t0_s) * 1e3)
            now_s = wake_s
        # at rate 2 the samples (5 ms apart) are due every 2.5 ms; six topics in one burst
        pass_ms = (span_ns + LOOP_GAP_NS) * 1e-6 / 2.0
        assert times_s == pytest.approx([0.0, 2.5, 5.0, pass_ms, pass_ms + 2.5, pass_ms + 5.0,
                                         2 * pass_ms])
        assert player.published == 6 * 6 and player.passes == 3
        start = info.start_time_ns
        last = [start + k * PERIOD_NS + 50_000 for k in range(3)]   # last of each burst
        assert probe.clock_ns == [start, *last, *last]               # back to the start
    finally:
        player.destroy_node()
        probe.close()


def test_loop_with_offset_keeps_time_increasing_and_stops_on_sigterm(context, tmp_path):
    bag = write_bag(tmp_path / 'short.mcap', 0.5)
    info = open_bag(bag)
    span_ns = info.end_time_ns - info.start_time_ns
    p_a_topic = interface.INPUT_TOPICS['p_a_Pa']
    n = info.topics[p_a_topic].message_count
    probe = Probe(context, bag)

    def into_pass_three():
        return (len(probe.raw.get(p_a_topic, ())) > 2 * n and probe.clock_ns
                and probe.clock_ns[-1] > info.end_time_ns + span_ns)

    try:
        rc, err = probe.play(bag, '--rate', '2', '--loop', '--loop-offset', '--quiet',
                             stop_when=into_pass_three)
    finally:
        probe.close()
    assert rc == 0 and 'Traceback' not in err, err
    clock = probe.clock_ns
    assert all(b >= a for a, b in zip(clock, clock[1:]))
    assert clock[-1] > info.end_time_ns + span_ns             # at least two passes
    # pass 2: the header stamps are shifted by the span and the gap, the rest is unchanged
    p_a = probe.raw[p_a_topic]
    assert len(p_a) > 2 * n
    first, second = (deserialize_message(p_a[i], FluidPressure)
                     for i in (0, n))
    shift_ns = span_ns + 1_000_000
    assert (Time.from_msg(second.header.stamp).nanoseconds
            == Time.from_msg(first.header.stamp).nanoseconds + shift_ns)
    assert second.fluid_pressure == first.fluid_pressure
    recorded = bag_payloads(bag)[p_a_topic][0]
    assert same_payloads([p_a[n]], [shift_header_stamp(recorded, shift_ns)])


def test_cut_bag_plays_up_to_the_cut_with_a_warning(context, bag3, tmp_path):
    cut = tmp_path / 'cut.mcap'
    data = bag3.read_bytes()
    cut.write_bytes(data[:len(data) * 6 // 10])
    expected = bag_payloads(cut)
    assert 0 < sum(map(len, expected.values())) < sum(map(len, bag_payloads(bag3).values()))
    probe = Probe(context, bag3)
    try:
        rc, err = probe.play(cut, '--rate', '2', '--quiet')
    finally:
        probe.close()
    assert rc == 0, err
    assert 'warning: the bag is cut' in err and 'Traceback' not in err
    for topic, payloads in expected.items():
        assert same_payloads(probe.raw[topic], payloads), topic
    assert probe.clock_ns[-1] == open_bag(cut).end_time_ns


@pytest.mark.parametrize('content, message', [
    (b'', 'empty file'),
    (b'PK\x03\x04 a zip archive', 'not an MCAP file'),
    (None, 'cannot open bag'),
])
def test_not_a_bag_is_one_error_exit_2(tmp_path, capsys, content, message):
    path = tmp_path / 'x.mcap'
    if content is not None:
        path.write_bytes(content)
    assert main([str(path)]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count('\n') == 1 and 'Traceback' not in err


def test_bad_options_exit_2(bag3, capsys):
    assert main([str(bag3), '--topics', '/nowhere']) == 2
    assert 'topics not in the bag: /nowhere' in capsys.readouterr().err
    assert main([str(bag3), '--loop-offset']) == 2
    with pytest.raises(SystemExit) as exc:
        main([str(bag3), '--rate', '0'])
    assert exc.value.code == 2


def test_recorded_qos():
    latched = recorded_qos(
        '- history: keep_last\n  depth: 1\n  reliability: reliable\n'
        '  durability: transient_local\n')
    assert latched == topics.latched_qos()
    mixed = recorded_qos('- {reliability: 1, durability: 1, depth: 0}\n'
                         '- {reliability: best_effort, durability: volatile, depth: 5}\n')
    assert mixed.reliability == ReliabilityPolicy.BEST_EFFORT and mixed.depth == 5
    assert recorded_qos('') == topics.input_qos('reliable', 100)
    assert recorded_qos('[]') == recorded_qos(': not yaml [')
