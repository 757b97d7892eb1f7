"""
Load benchmark of the estimator node: CPU against a bare subscriber, lost samples, latency.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_estimator.py
     [--minutes 10] [--pressure differential|ports] [--rate-Hz 1000] [--stage 6]
     [--depth 1000] [--executor events] [--warmup-s 5] [--busy-live-s 60] [--no-foxglove]
     [--batched-rate-Hz 4000] [--block-ms 10]

The issue's setting is "four sensor topics at 1 kHz each and estimates
published at 50 Hz": current, speed, one differential pressure and position
(``--pressure differential``, the default); ``--pressure ports`` publishes
six (both ports and the accumulator). Reliable QoS. Processes on a private
ROS domain (from the pid, or ``$WET_EHA_BENCH_DOMAIN_ID``):

- a publisher (this script with ``--role publisher``): the stage's kinetic
  signals, one sample per topic per timer tick, pressures stamped with their
  send time (the ROS clock just before publishing); it starts once every
  topic has matched its subscriber;
- first a bare subscriber (``--role bare``): the same topics, QoS and
  executor, empty callbacks, rclpy deserialising every message, an
  EventsExecutor turned by ``spin_once`` in a loop: what any rclpy node on
  these topics costs at least;
- then the estimator (``python -m wet_eha_thermal.ros.estimator_node``,
  reliable QoS, history ``--depth``, the reference configuration with
  ``estimator.pressure_inputs`` set by ``--pressure``); the publisher starts
  once it said it is ready (``/eha/ready``);
- then, unless ``--no-foxglove``, the estimator again with its Foxglove view
  on (``foxglove_address``) and a Foxglove WebSocket client in this process
  (a thread) subscribed to every channel of the view and reading all it gets:
  the view's cost is the difference between the two estimator runs;
- this process: follows the estimates, the first pressure topic (for the
  send times) and /diagnostics.

- then, unless ``--batched-rate-Hz 0``, the estimator once more with the
  same inputs in the batched form (:mod:`wet_eha_thermal.inputs`): one
  std_msgs/Float64MultiArray topic, ``/eha/daq``, carrying every input as a
  column, a block every ``--block-ms`` of samples at ``--batched-rate-Hz``
  (default 4 kHz in 10 ms blocks: 16 000 samples/s for four inputs), its
  ``inputs_file`` saying so; no end-to-end latency there (the blocks carry
  no send time).

Figures, all subscribers measured in this one run:

- CPU of the bare subscriber and of the estimator with its children (the
  what-if worker and its fork server): utime + stime of the process tree
  from ``/proc/<pid>/stat`` over the measured ``--minutes`` (after
  ``--warmup-s``), in % of one core, and their ratio;
- lost samples: per input, what the publisher sent minus what the estimator
  received (its diagnostics' ``received`` counter, read after the publisher
  stopped), and how many it rejected (late, backwards, out of range, future);
- latency added by the estimator: the node's own figure from its
  diagnostics, callback start of the sample that closed a step to its
  estimates published (p50/p99/max over its last 3000 estimates);
- end-to-end latency: for every estimate (stamp t1 = the end of its 20 ms
  step), the receive time here minus the send time of the first pressure
  sample stamped at or after t1 (the sample that closed the step); p50, p99
  and max. It adds two DDS hops and this process's own scheduling;
- stalls: over the whole run, warm-up and the estimator's cold start
  included, the runs of estimates more than ``STALL_MS`` late by that
  measure, when (s from the first estimate) and how late at worst.

Then, with ``--busy-live-s`` (default 60; 0 skips it), the busy-machine case:
``wet-eha-thermal live`` for that long while another process keeps one core
busy (a Python loop this script starts and stops), and the figures of its
summary: the samples the rig published and the estimator received, the stale
events, the start-up time.
"""

import argparse
from collections import deque
import json
import os
from pathlib import Path
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from typing import Optional

from diagnostic_msgs.msg import DiagnosticArray
import numpy as np
from procfs import tree_cpu_seconds
import rclpy
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import FluidPressure, Temperature
from std_msgs.msg import Float64, Float64MultiArray, String
from wet_eha_thermal import interface
from wet_eha_thermal.config import default_config_path, load_config
from wet_eha_thermal.estimator.intake import sensor_inputs, sensor_signal
from wet_eha_thermal.inputs import encode_batch, SI_UNIT
from wet_eha_thermal.model.duty import stage_duty
from wet_eha_thermal.model.kinetics import KineticModel, ThermalFeedback
from wet_eha_thermal.model.oil import get_oil
from wet_eha_thermal.ros import topics
from wet_eha_thermal.ros.runtime import make_executor
from wet_eha_thermal.view_channels import CHANNELS
import yaml

ROOT = Path(__file__).resolve().parents[1]
PARAMS_FILE = ROOT / 'config' / 'estimator.params.yaml'
#: The batched run's topic: a DAQ's block of every input, one column each.
BATCH_TOPIC = f'{interface.PREFIX}/daq'
INPUT_STATUS = interface.status_name('input ', interface.ESTIMATOR_NODE)
ESTIMATE_STATUS = interface.status_name('estimate', interface.ESTIMATOR_NODE)
LATENCY_KEY = 'step latency p50/p99/max [ms]'
VIEW_KEY = 'foxglove view'
#: an estimate received more than this after its closing sample was sent is late (a stall)
STALL_MS = 100.0


def bench_config(pressure: str):
    """Return the reference configuration with ``estimator.pressure_inputs`` = ``pressure``."""
    return load_config(overrides={'estimator.pressure_inputs': pressure})


def reliable(depth: int) -> QoSProfile:
    """Return reliable, volatile, keep-last ``depth``."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)


# ------------------------------------------------------------------ publisher
def _ticked(st: dict) -> bool:
    """Note a publisher tick's wall interval since the last; return whether publishing began."""
    wall = time.perf_counter()
    if st['last'] is not None:
        st['intervals'].append(wall - st['last'])
    st['last'] = wall
    return st['start'] is not None


def run_publisher(args) -> None:
    """Publish the inputs at ``args.rate_Hz`` for ``args.seconds``; print a JSON report."""
    cfg = bench_config(args.pressure)
    inputs = sensor_inputs(cfg)
    duty = stage_duty(cfg, args.stage)
    kin = KineticModel(cfg, get_oil(cfg.fluid.grade))
    n = max(1, int(round(duty.period_s * args.rate_Hz)))
    t = np.arange(1, n + 1) / args.rate_Hz
    s = kin.sample(duty, t, ThermalFeedback.uniform())
    rows = np.column_stack([sensor_signal(s, k) for k in inputs]).tolist()
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('bench_publisher')
    q = reliable(args.depth)
    if args.block_ms > 0:
        publish_blocks(args, node, q, np.array(rows))
        return
    pubs = [node.create_publisher(FluidPressure if k in interface.PRESSURE_INPUTS else Float64,
                                  interface.INPUT_TOPICS[k], q) for k in inputs]
    msgs = [FluidPressure() if k in interface.PRESSURE_INPUTS else Float64() for k in inputs]
    pressure = [k in interface.PRESSURE_INPUTS for k in inputs]
    clock = node.get_clock()
    st = {'k': 0, 'start': None, 'ticks': 0, 'intervals': [], 'last': None}
    period_ns = int(round(1e9 / args.rate_Hz))

    def tick() -> None:
        if not _ticked(st):
            return
        due = (time.monotonic_ns() - st['start']) // period_ns + 1
        while st['k'] < due:
            row = rows[st['k'] % n]
            topics.publish_inputs(pubs, msgs, pressure, row, clock.now().to_msg())
            st['k'] += 1

    node.create_timer(1.0 / args.rate_Hz, tick)
    publish_until_done(args, node, pubs, st)


def publish_blocks(args, node, q, rows: np.ndarray) -> None:
    """Publish the inputs in blocks of ``--block-ms`` on BATCH_TOPIC, serialised by numpy."""
    pub = node.create_publisher(Float64MultiArray, BATCH_TOPIC, q)
    clock = node.get_clock()
    n = rows.shape[0]
    dt = 1.0 / args.rate_Hz
    per_block = max(1, int(round(args.block_ms * 1e-3 * args.rate_Hz)))
    st = {'k': 0, 'start': None, 'ticks': 0, 'intervals': [], 'last': None}
    period_ns = int(round(1e9 * per_block / args.rate_Hz))

    def tick() -> None:
        if not _ticked(st):
            return
        elapsed_ns = time.monotonic_ns() - st['start']
        if 't0_s' not in st:
            # the ROS time of the start: sample k is stamped by the schedule, t0_s + (k + 1) dt,
            # as a DAQ's clock stamps it, however late its block leaves
            st['t0_s'] = (clock.now().nanoseconds - elapsed_ns) * 1e-9
        due = (elapsed_ns // period_ns + 1) * per_block
        while st['k'] < due:
            idx = np.arange(st['k'], st['k'] + per_block) % n
            pub.publish(encode_batch(st['t0_s'] + (st['k'] + 1) * dt, dt, rows[idx]))
            st['k'] += per_block

    node.create_timer(per_block / args.rate_Hz, tick)
    publish_until_done(args, node, [pub], st)


def publish_until_done(args, node, pubs, st) -> None:
    """Spin the publisher's timer from the subscribers' match for ``--seconds``; report."""
    executor = make_executor(args.executor)
    executor.add_node(node)
    stop = []
    signal.signal(signal.SIGINT, lambda *a: stop.append(1))
    signal.signal(signal.SIGTERM, lambda *a: stop.append(1))
    # start when every topic has its subscriber (reliable, volatile: nothing before the match)
    t_wait = time.monotonic()
    while not stop and min(p.get_subscription_count() for p in pubs) < 1:
        executor.spin_once(timeout_sec=0.05)
        if time.monotonic() - t_wait > 60.0:
            print(json.dumps({'error': 'no subscriber after 60 s'}), flush=True)
            return
    t_match = time.monotonic() - t_wait
    end = time.monotonic() + 0.5
    while not stop and time.monotonic() < end:
        executor.spin_once(timeout_sec=0.05)
    st['start'] = time.monotonic_ns()
    st['intervals'].clear()
    print(json.dumps({'started': True, 'match_s': t_match}), flush=True)
    cpu0, wall0 = time.process_time(), time.monotonic()
    end = wall0 + args.seconds
    while not stop and time.monotonic() < end:
        executor.spin_once(timeout_sec=0.05)
    st['start'] = None
    wall = time.monotonic() - wall0
    iv = np.array(st['intervals']) * 1e3
    print(json.dumps({
        'sent': st['k'], 'seconds': wall, 'cpu_percent': 100 * (time.process_time() - cpu0) / wall,
        'tick_p50_ms': float(np.percentile(iv, 50)), 'tick_p99_ms': float(np.percentile(iv, 99)),
        'tick_max_ms': float(iv.max())}), flush=True)
    # let the last samples be acknowledged before the writers go away
    end = time.monotonic() + 2.0
    while time.monotonic() < end:
        executor.spin_once(timeout_sec=0.05)
    node.destroy_node()
    rclpy.try_shutdown()


# ----------------------------------------------------------------------- bare
def run_bare(args) -> None:
    """Subscribe to the inputs with empty callbacks until SIGINT; print a JSON report."""
    inputs = sensor_inputs(bench_config(args.pressure))
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('bench_bare_subscriber')
    count = [0]

    def on_message(msg) -> None:
        count[0] += 1

    for k in inputs:
        node.create_subscription(FluidPressure if k in interface.PRESSURE_INPUTS else Float64,
                                 interface.INPUT_TOPICS[k], on_message, reliable(args.depth))
    executor = make_executor(args.executor)
    executor.add_node(node)
    stop = []
    signal.signal(signal.SIGINT, lambda *a: stop.append(1))
    signal.signal(signal.SIGTERM, lambda *a: stop.append(1))
    while not stop:
        executor.spin_once(timeout_sec=0.1)
    print(json.dumps({'received': count[0]}), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


# -------------------------------------------------------------------- monitor
class Monitor:
    """Estimates, pressure send times and the estimator's input counters."""

    def __init__(self, node, pressure_topic: Optional[str]) -> None:
        self.stamps = deque(maxlen=200000)     # pressure send times (ns), increasing
        self.pending = deque()                 # (estimate stamp ns, receive ns)
        self.latency_ms = []
        self.latency_rx_s = []                 # when each was received here (s)
        self.estimates = 0
        self.counters = {}
        self.latency_text = None
        self.view_text = None
        self.diag_count = 0
        self.subscriptions = [] if pressure_topic is None else [
            node.create_subscription(FluidPressure, pressure_topic, self.on_p, reliable(1000))]
        self.subscriptions += [
            node.create_subscription(Temperature, f'{interface.ESTIMATE_PREFIX}/winding_hotspot',
                                     self.on_estimate, reliable(100)),
            node.create_subscription(DiagnosticArray, interface.DIAGNOSTICS_TOPIC, self.on_diag,
                                     reliable(20))]

    def close(self, node) -> None:
        """Stop following (the next phase has its own monitor)."""
        for sub in self.subscriptions:
            node.destroy_subscription(sub)

    def on_p(self, msg) -> None:
        self.stamps.append(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)
        self.resolve()

    def on_estimate(self, msg) -> None:
        rx = time.time_ns()
        self.estimates += 1
        self.pending.append((msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec,
                             rx))
        self.resolve()

    def resolve(self) -> None:
        while self.pending and self.stamps and self.stamps[-1] >= self.pending[0][0]:
            t1, rx = self.pending.popleft()
            closing = None
            for s in reversed(self.stamps):    # the first stamp >= t1, from the recent end
                if s < t1:
                    break
                closing = s
            self.latency_ms.append((rx - closing) * 1e-6)
            self.latency_rx_s.append(rx * 1e-9)

    def on_diag(self, msg) -> None:
        self.diag_count += 1
        for st in msg.status:
            if st.name.startswith(INPUT_STATUS):
                self.counters[st.name[len(INPUT_STATUS):]] = {v.key: v.value for v in st.values}
            elif st.name == ESTIMATE_STATUS:
                values = {v.key: v.value for v in st.values}
                self.latency_text = values.get(LATENCY_KEY, self.latency_text)
                self.view_text = values.get(VIEW_KEY, self.view_text)


def spin_for(executor, seconds: float, until=None) -> bool:
    """Spin for ``seconds`` or until ``until()`` is true; return whether it became true."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        executor.spin_once(timeout_sec=0.05)
        if until is not None and until():
            return True
    return False


def start(cmd, env, log, **kw) -> subprocess.Popen:
    """Start a child in its own session (so that a signal reaches it alone)."""
    return subprocess.Popen(cmd, env=env, stderr=log, start_new_session=True, **kw)


def stop(procs) -> None:
    """SIGINT the children, then SIGKILL what is left after 8 s."""
    for proc in procs:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGINT)
    for proc in procs:
        try:
            proc.wait(timeout=8.0)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


class Publisher:
    """The publisher child and its JSON lines on stdout."""

    def __init__(self, cmd, env, log) -> None:
        self.proc = start(cmd, env, log, stdout=subprocess.PIPE)
        os.set_blocking(self.proc.stdout.fileno(), False)
        self.out = ''

    def read(self) -> str:
        try:
            chunk = os.read(self.proc.stdout.fileno(), 65536)
        except BlockingIOError:
            chunk = b''
        self.out += chunk.decode()
        return self.out

    def lines(self):
        return [json.loads(line) for line in self.read().strip().splitlines()]


def measure(args, executor, sub, pub, mon=None):
    """Warm up, then measure the CPU of ``sub`` over ``--minutes``; return the figures."""
    if not spin_for(executor, 120.0, lambda: 'started' in pub.read()):
        raise SystemExit('the publisher did not start within 120 s')
    t_start = time.monotonic()
    spin_for(executor, args.warmup_s)
    cpu0, w0 = tree_cpu_seconds(sub.pid), time.monotonic()
    lat_from = len(mon.latency_ms) if mon else 0
    est0 = mon.estimates if mon else 0
    spin_for(executor, max(args.minutes * 60.0 - (time.monotonic() - t_start - args.warmup_s),
                           0.0))
    cpu1, w1 = tree_cpu_seconds(sub.pid), time.monotonic()
    if not spin_for(executor, 30.0, lambda: pub.read().count('\n') >= 2):
        raise SystemExit('the publisher did not report')
    out = {'cpu': 100.0 * (cpu1 - cpu0) / (w1 - w0), 'seconds': w1 - w0,
           'report': pub.lines()[-1], 'match_s': pub.lines()[0]['match_s']}
    if mon:
        out['latency'] = np.array(mon.latency_ms[lat_from:])
        out['estimates'] = mon.estimates - est0
    return out


class Viewer:
    """A Foxglove client on a thread: subscribes to every channel, reads and counts it all."""

    def __init__(self, port: int) -> None:
        from websockets.sync.client import connect    # a test dependency, as this script is

        self.ws = connect(f'ws://127.0.0.1:{port}', subprotocols=['foxglove.sdk.v1'],
                          proxy=None, close_timeout=1.0).__enter__()
        channels = {}
        while len(channels) < len(CHANNELS):
            msg = json.loads(self.ws.recv(timeout=10.0))
            if msg['op'] == 'advertise':
                channels.update({c['id']: c['topic'] for c in msg['channels']})
        self.ws.send(json.dumps({'op': 'subscribe', 'subscriptions': [
            {'id': k, 'channelId': k} for k in channels]}))
        self.messages = self.bytes = 0
        self.stopped = False
        self.seconds = time.monotonic()      # how long it read, once closed
        self.thread = threading.Thread(target=self.read, daemon=True)
        self.thread.start()

    def read(self) -> None:
        while not self.stopped:
            try:
                frame = self.ws.recv(timeout=0.2)
            except TimeoutError:
                continue
            if isinstance(frame, bytes):
                self.messages += 1
                self.bytes += len(frame)

    def close(self) -> None:
        self.stopped = True
        self.thread.join()
        self.seconds = time.monotonic() - self.seconds
        self.ws.__exit__(None, None, None)


def free_port() -> int:
    """Return a TCP port free on 127.0.0.1 now."""
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        return sock.getsockname()[1]


def run_estimator(args, executor, node, ready, cmd, pub_cmd, env, log, pressure_topic,
                  view_port=None):
    """
    Measure the estimator ``cmd`` under the publisher; return ``(figures, monitor)``.

    With ``view_port``, a :class:`Viewer` reads the estimator's Foxglove view throughout.
    """
    mon = Monitor(node, pressure_topic)
    ready.clear()
    est = start(cmd, env, log, stdout=log)
    pub = Publisher(pub_cmd, env, log)     # it waits for the estimator's subscriptions
    viewer = None
    try:
        if not spin_for(executor, 120.0, lambda: any('"ready": true' in r for r in ready)):
            raise SystemExit('the estimator did not say it is ready within 120 s')
        if view_port is not None:
            viewer = Viewer(view_port)
        fig = measure(args, executor, est, pub, mon)
        # two more diagnostics so that the counters include the last samples
        d0 = mon.diag_count
        spin_for(executor, 5.0, lambda: mon.diag_count >= d0 + 2)
        if viewer is not None:
            viewer.close()
            fig['viewed'] = (viewer.messages, viewer.bytes, viewer.seconds)
            viewer = None
    finally:
        if viewer is not None:
            viewer.close()
        stop([pub.proc, est])
        mon.close(node)
    return fig, mon


def print_estimator(fig, mon, inputs, what: str) -> None:
    """Print the figures of one estimator run."""
    sent = fig['report']['sent']
    print(f'{what}: CPU {fig["cpu"]:.1f} % of one core over {fig["seconds"]:.1f} s '
          f'(utime+stime of its process tree, /proc/<pid>/stat); {fig["estimates"]} '
          f'estimates received, {fig["estimates"] / fig["seconds"]:.1f} per s')
    lost_total = 0
    for name in inputs:
        c = mon.counters.get(name, {})
        rx = int(c.get('received', 0))
        rejected = sum(int(c.get(k, 0)) for k in ('late', 'backwards', 'out_of_range',
                                                  'non_finite', 'future', 'overflow'))
        lost_total += sent - rx
        print(f'  {name:<12} sent {sent}, received {rx}, lost {sent - rx} '
              f'({100.0 * (sent - rx) / max(sent, 1):.3f} %), rejected {rejected} '
              f'(late {c.get("late", "?")}, backwards {c.get("backwards", "?")})')
    print(f'  lost samples: {lost_total} of {sent * len(inputs)} '
          f'({100.0 * lost_total / max(sent * len(inputs), 1):.4f} %) with reliable QoS over '
          f'{fig["report"]["seconds"]:.1f} s of publishing')
    print('  latency added by the estimator (its diagnostics: callback of the closing sample '
          f'-> estimates published), p50/p99/max: {mon.latency_text or "not reported"}')
    lat = fig['latency']
    if lat.size:
        p50, p99 = np.percentile(lat, [50, 99])
        print(f'  end-to-end latency, closing sample sent -> its estimate received here: p50 '
              f'{p50:.2f} ms, p99 {p99:.2f} ms, max {lat.max():.2f} ms over {lat.size} '
              'estimates')
    print_stalls(mon)
    r = fig['report']
    print(f'  publisher: CPU {r["cpu_percent"]:.1f} % of a core, tick interval p50/p99/max '
          f'{r["tick_p50_ms"]:.3f}/{r["tick_p99_ms"]:.3f}/{r["tick_max_ms"]:.1f} ms')
    if 'viewed' in fig:
        n, size, seconds = fig['viewed']
        print(f'  Foxglove client: {n} messages, {size / 1e6:.1f} MB in {seconds:.0f} s '
              f'({n / seconds:.0f} msg/s, {size / seconds / 1e3:.0f} kB/s); the view: '
              f'{mon.view_text}')


def stalls(rx_s, latency_ms, late_ms: float = STALL_MS, join_s: float = 0.5):
    """
    Return the stalls: runs of estimates ``late_ms`` late, as (first, last receipt s, worst ms).

    Late estimates received within ``join_s`` of each other are one stall.
    """
    out = []
    for t, ms in zip(rx_s, latency_ms):
        if ms <= late_ms:
            continue
        if out and t - out[-1][1] <= join_s:
            out[-1] = (out[-1][0], t, max(out[-1][2], ms))
        else:
            out.append((t, t, ms))
    return out


def print_stalls(mon) -> None:
    """Print where the estimates came late over the whole run, warm-up included."""
    if not mon.latency_rx_s:
        return
    found = stalls(mon.latency_rx_s, mon.latency_ms)
    t0 = mon.latency_rx_s[0]
    where = ', '.join(f'{a - t0:.1f}-{b - t0:.1f} s (worst {ms:.0f} ms)'
                      for a, b, ms in found[:6]) + (' ...' if len(found) > 6 else '')
    print(f'  stalls, the whole run (estimates more than {STALL_MS:g} ms after their closing '
          f'sample was sent; s from the first estimate): {len(found)}'
          + (f': {where}' if found else ''))


def busy_live(seconds: float, env) -> None:
    """Run ``wet-eha-thermal live`` with one core kept busy; print its figures."""
    busy = subprocess.Popen([sys.executable, '-c', 'while True: pass'],
                            start_new_session=True)
    try:
        with tempfile.TemporaryDirectory() as folder:
            cli = Path(sys.executable).parent / 'wet-eha-thermal'
            cmd = [str(cli)] if cli.exists() else [sys.executable, '-m', 'wet_eha_thermal.cli']
            res = subprocess.run(cmd + ['live', '--duration', f'{seconds:g}'], env=env,
                                 cwd=folder, capture_output=True, text=True,
                                 timeout=seconds + 300)
    finally:
        os.killpg(busy.pid, signal.SIGKILL)    # a SIGINT would print its traceback
        busy.wait()
    lines = res.stdout.splitlines()
    keep = ('run ', 'samples ', 'stale events ', 'rig figures ', 'estimates ')
    print(f'busy machine: `wet-eha-thermal live --duration {seconds:g}` with one core kept '
          f'busy by another process (exit status {res.returncode}):')
    for line in lines:
        if line.strip().startswith(keep):
            print('  ' + line.strip())
    if res.returncode:
        print('  ' + res.stderr.strip().replace('\n', '\n  '))


def main() -> None:
    """Run the benchmark and print the figures."""
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--minutes', type=float, default=10.0,
                   help='measured time of each subscriber (default 10)')
    p.add_argument('--pressure', choices=('differential', 'ports'), default='differential',
                   help='one differential pressure (four topics, the default) or both ports '
                        'and the accumulator (six topics)')
    p.add_argument('--rate-Hz', type=float, default=1000.0, help='rate of every input')
    p.add_argument('--stage', type=int, default=6, help='reference stage of the signals')
    p.add_argument('--depth', type=int, default=1000,
                   help='reliable history depth (default 1000, as the estimator)')
    p.add_argument('--executor', choices=('events', 'single'), default='events')
    p.add_argument('--warmup-s', type=float, default=5.0)
    p.add_argument('--busy-live-s', type=float, default=60.0,
                   help='length of the busy-machine live run (0: skip it)')
    p.add_argument('--no-foxglove', action='store_true',
                   help='skip the run with the Foxglove view and a client')
    p.add_argument('--batched-rate-Hz', type=float, default=4000.0,
                   help='rate of every input in the batched run (0: skip it)')
    p.add_argument('--block-ms', type=float, default=10.0,
                   help='length of a block of the batched run (ms of samples)')
    p.add_argument('--role', choices=('main', 'publisher', 'bare'), default='main',
                   help=argparse.SUPPRESS)
    p.add_argument('--seconds', type=float, default=0.0, help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.role == 'publisher':
        run_publisher(args)
        return
    if args.role == 'bare':
        run_bare(args)
        return

    domain = int(os.environ.get('WET_EHA_BENCH_DOMAIN_ID', 100 + os.getpid() % 133))
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               PYTHONUNBUFFERED='1')
    env.setdefault('OPENBLAS_NUM_THREADS', '1')
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    measure_s = args.minutes * 60.0
    inputs = sensor_inputs(bench_config(args.pressure))
    tmp = Path(os.environ.get('TMPDIR', '/tmp'))
    config_file = tmp / f'bench_estimator_{domain}.yaml'
    data = yaml.safe_load(default_config_path().read_text())
    data['estimator']['pressure_inputs'] = args.pressure
    config_file.write_text(yaml.safe_dump(data))
    est_cmd = [sys.executable, '-m', 'wet_eha_thermal.ros.estimator_node', '--executor',
               args.executor, '--ros-args']
    if PARAMS_FILE.is_file():
        est_cmd += ['--params-file', str(PARAMS_FILE)]
    est_cmd += ['-p', 'qos:=reliable', '-p', f'qos_depth:={args.depth}',
                '-p', f'config_file:={config_file}']
    common = ['--rate-Hz', str(args.rate_Hz), '--stage', str(args.stage), '--depth',
              str(args.depth), '--executor', args.executor, '--pressure', args.pressure,
              '--block-ms', '0']
    pub_cmd = [sys.executable, __file__, '--role', 'publisher', '--seconds',
               str(args.warmup_s + measure_s)] + common
    bare_cmd = [sys.executable, __file__, '--role', 'bare'] + common
    batch_common = common + ['--rate-Hz', str(args.batched_rate_Hz), '--block-ms',
                             str(args.block_ms)]     # the later ones win
    batch_pub_cmd = [sys.executable, __file__, '--role', 'publisher', '--seconds',
                     str(args.warmup_s + measure_s)] + batch_common
    inputs_file = tmp / f'bench_estimator_{domain}.inputs.yaml'
    inputs_file.write_text(yaml.safe_dump({'inputs': {
        name: {'topic': BATCH_TOPIC, 'message_type': interface.FLOAT64_ARRAY, 'column': k,
               'columns': len(inputs), 'unit': unit}
        for k, (name, unit) in enumerate((n, SI_UNIT[n]) for n in inputs)}}))
    print(f'Estimator benchmark: {len(inputs)} inputs ({", ".join(inputs)}) at '
          f'{args.rate_Hz:g} Hz each, reliable QoS depth {args.depth}, stage {args.stage} '
          f'signals, estimates at 50 Hz, {args.executor} executor; {args.minutes:g} min '
          f'measured per subscriber after a {args.warmup_s:g} s warm-up, ROS domain {domain}')
    print('command: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_estimator.py '
          + ' '.join(sys.argv[1:]), flush=True)
    log = open(tmp / f'bench_estimator_{domain}.log', 'wb')
    rclpy.init(domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('bench_monitor')
    executor = make_executor(args.executor)
    executor.add_node(node)
    ready = []
    node.create_subscription(String, interface.READY_TOPIC, lambda m: ready.append(m.data),
                             topics.latched_qos())
    try:
        # 1. the bare subscriber
        bare = start(bare_cmd, env, log, stdout=subprocess.PIPE)
        pub = Publisher(pub_cmd, env, log)
        bare_fig = measure(args, executor, bare, pub)
        stop([pub.proc, bare])
        bare_rx = json.loads(bare.stdout.read().decode().strip().splitlines()[-1])['received']
        # 2. the estimator, once it is ready (model warmed, inputs matched); 3. the same
        # with its Foxglove view and a client reading every channel of it
        pressure_topic = interface.INPUT_TOPICS[next(k for k in inputs
                                                     if k in interface.PRESSURE_INPUTS)]
        est_fig, mon = run_estimator(args, executor, node, ready, est_cmd, pub_cmd, env, log,
                                     pressure_topic)
        if not args.no_foxglove:
            port = free_port()
            view_fig, view_mon = run_estimator(
                args, executor, node, ready,
                est_cmd + ['-p', f'foxglove_address:=127.0.0.1:{port}'], pub_cmd, env, log,
                pressure_topic, view_port=port)
        if args.batched_rate_Hz > 0:
            batch_fig, batch_mon = run_estimator(
                args, executor, node, ready, est_cmd + ['-p', f'inputs_file:={inputs_file}'],
                batch_pub_cmd, env, log, None)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        log.close()

    print(f'bare subscriber CPU: {bare_fig["cpu"]:.1f} % of one core over '
          f'{bare_fig["seconds"]:.1f} s; it received {bare_rx} of '
          f'{bare_fig["report"]["sent"] * len(inputs)} samples')
    print_estimator(est_fig, mon, inputs, 'estimator')
    print(f'ratio estimator / bare subscriber: {est_fig["cpu"] / bare_fig["cpu"]:.2f}')
    if not args.no_foxglove:
        print_estimator(view_fig, view_mon, inputs,
                        'estimator with its Foxglove view, one client reading every channel')
        print(f'cost of the Foxglove view: {view_fig["cpu"] - est_fig["cpu"]:+.1f} points of '
              f'one core ({view_fig["cpu"]:.1f} % against {est_fig["cpu"]:.1f} %)', flush=True)
    if args.batched_rate_Hz > 0:
        print_estimator(batch_fig, batch_mon, inputs,
                        f'estimator, batched inputs at {args.batched_rate_Hz:g} Hz in '
                        f'{args.block_ms:g} ms blocks on {BATCH_TOPIC}')
        print(f'ratio batched estimator / bare subscriber: '
              f'{batch_fig["cpu"] / bare_fig["cpu"]:.2f}; batched / per-message estimator: '
              f'{batch_fig["cpu"] / est_fig["cpu"]:.2f}')
    if args.busy_live_s > 0:
        busy_live(args.busy_live_s, dict(os.environ))


if __name__ == '__main__':
    main()
