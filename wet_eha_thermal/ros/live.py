"""
The live digital twin in one command: simulated rig, estimator and a status line.

:func:`run` starts three child processes together, the recorder
(:mod:`.recorder_node`, unless ``record`` is off), the estimator
(:mod:`.estimator_node`) and the simulated rig (:mod:`.sim_rig_node`), on a
private ROS domain (``WET_EHA_LIVE_DOMAIN_ID``, or the first domain with no
ROS node on this machine from one picked by the process id; discovery
limited to this machine), and a small node in this process that follows the
ready topic, the estimates, the alerts and /diagnostics and prints one status
line about twice a second (updated in place on a terminal, one line every few
seconds otherwise). The estimator also serves the Foxglove view
(:mod:`wet_eha_thermal.live_view`) at ``foxglove`` (127.0.0.1:8765 by
default); :func:`run` prints the address to open. An address already in use
is one line on stderr, and the run goes on without the view: the twin
matters more than its display.

First it compiles the model's and the estimator's numba kernels (or loads
them from numba's cache: about a second), so that the children load them
instead of compiling them side by side. The rig starts its duty only once
the estimator and the recorder have said on ``/eha/ready`` that they are
ready (model loaded and warmed, every input matched), so no sample is
published before they listen, however long the start-up takes on this
machine; ``duration_s`` counts from that start. A
start-up longer than ``START_TIMEOUT_S`` ends the run with a message naming
who was not ready. After ``duration_s``, or on Ctrl-C / SIGTERM, it stops the
children (SIGINT, then SIGTERM, then SIGKILL, each after a timeout; the
recorder last, so that it keeps everything the others sent), prints a summary
(samples the rig published and the estimator received, from their own
shutdown lines; the recording's path and message count) and returns the exit
status: 0 when every child ran to the end, shut down cleanly and estimates
came, 1 otherwise (with the last lines a failed child printed). The recording
(the rosbag2 bag directory ``runs/live_<UTC time>`` by default) holds the
configuration and the estimator's parameters file, so the run can be
replayed from it alone.

The children run in their own session, so a Ctrl-C on the terminal reaches
this process only and the shutdown stays in order; they also get SIGKILL
from the kernel should this process die without cleaning up, so no child
outlives it.
"""

import ctypes
from dataclasses import dataclass, field, replace
import json
import math
import os
from pathlib import Path
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from typing import Dict, List, Optional, TextIO, Tuple

from diagnostic_msgs.msg import DiagnosticArray
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import Temperature
from std_msgs.msg import String
from wet_eha_thermal import interface
from wet_eha_thermal.bag.reader import BagError, open_bag
from wet_eha_thermal.config import load_config
from wet_eha_thermal.estimator.warmup import compile_estimator
from wet_eha_thermal.interface import ESTIMATOR_NODE, RECORDER_NODE, RIG_NODE
from wet_eha_thermal.live_view import address_text, app_url
from wet_eha_thermal.ros import topics
from wet_eha_thermal.ros.recorder_node import default_output

#: Environment variable that fixes the ROS domain of a live run (0..232).
DOMAIN_ENV = 'WET_EHA_LIVE_DOMAIN_ID'
#: Domains picked from the process id: 100..232 (Fast DDS ports allow up to 232).
DOMAIN_FIRST, DOMAIN_LAST = 100, 232
#: Domains tried when picking one, and how long each is watched for other nodes (s).
DOMAIN_TRIES, DOMAIN_PROBE_S = 8, 0.5
#: Estimates followed by the status line and the peaks.
WATCHED = ('winding_hotspot', 'winding_mean', 'magnet', 'oil')
#: Seconds between status lines: on a terminal (updated in place) and in a log.
TTY_PERIOD_S, LOG_PERIOD_S = 0.5, 5.0
#: Shutdown timeouts (s) after SIGINT, then after SIGTERM.
SIGINT_WAIT_S, SIGTERM_WAIT_S = 6.0, 3.0
#: Longest start-up (processes, model warm-up, discovery) before the rig's duty (s): the
#: rig starts anyway after it, the run ends with an error a little later.
START_TIMEOUT_S = 120.0
#: History depth of the recorder's subscriptions (1 s of a 1 kHz topic).
RECORDER_DEPTH = 1000
ESTIMATE_STATUS = 'wet_eha_thermal: estimate'
RECORDER_STATUS = 'wet_eha_thermal: recorder'
INPUT_STATUS = 'wet_eha_thermal: input '
RIG_STATUS = 'eha_sim_rig: rig'
PARAMS_FILE = Path(__file__).resolve().parents[2] / 'config' / 'estimator.params.yaml'
LIVE_LAYOUT = Path(__file__).resolve().parents[2] / 'layouts' / 'live.json'


@dataclass
class LiveOptions:
    """What to run: a stage or a duty file, for how long, at which sample rate."""

    stage: Optional[int] = 6
    duty: Optional[Path] = None
    duration_s: float = 60.0
    rate_Hz: float = 1000.0
    config: Optional[Path] = None
    noise: bool = True
    executor: str = 'events'
    record: bool = True
    record_path: Optional[Path] = None      # None: the bag directory runs/live_<UTC time>
    # splits of the recording, as ros2 bag record's --max-bag-size and --max-bag-duration
    max_bag_size_B: int = interface.LIVE_SPLIT_BYTES
    max_bag_duration_s: float = interface.LIVE_SPLIT_DURATION_S
    foxglove: Optional[Tuple[str, int]] = ('127.0.0.1', 8765)    # None: no Foxglove view


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


def child_commands(opts: LiveOptions, hardware_id: str,
                   record_path: Optional[Path] = None) -> Dict[str, List[str]]:
    """
    Return the command lines of the children: ``{'rig': [...], 'estimator': [...], ...}``.

    With ``record_path``, also ``'recorder'``: it takes the estimator's
    parameters file and configuration (to store them) and always the events
    executor (the single-threaded one loses messages above about 2 k msg/s).
    """
    py = sys.executable
    waits = waited_nodes(record_path is not None)
    rig = [py, '-m', 'wet_eha_thermal.ros.sim_rig_node', '--executor', opts.executor,
           '--ros-args', '-p', f'rate_Hz:={float(opts.rate_Hz)!r}',
           '-p', f'noise:={"true" if opts.noise else "false"}', '-p', 'qos:=reliable',
           # the duty starts once the estimator and the recorder are warm and hear every
           # input: before that, samples would be lost or wait behind a start-up
           '-p', f'wait_for:=[{", ".join(waits)}]',
           '-p', f'wait_for_subscribers:={len(waits)}',
           '-p', f'start_timeout_s:={START_TIMEOUT_S!r}']
    if opts.duty is not None:
        rig += ['-p', f'duty_file:={Path(opts.duty).resolve()}']
    else:
        rig += ['-p', f'stage:={int(opts.stage)}']
    est = [py, '-m', 'wet_eha_thermal.ros.estimator_node', '--executor', opts.executor,
           '--ros-args']
    if PARAMS_FILE.is_file():
        est += ['--params-file', str(PARAMS_FILE)]
    est += ['-p', 'qos:=reliable', '-p', f'hardware_id:={hardware_id}']
    if opts.foxglove is not None:
        est += ['-p', f'foxglove_address:={address_text(*opts.foxglove)}']
    rec = [py, '-m', 'wet_eha_thermal.ros.recorder_node', '--executor', 'events', '--ros-args']
    if PARAMS_FILE.is_file():
        rec += ['--params-file', str(PARAMS_FILE), '-p', f'params_file:={PARAMS_FILE}']
    # its own depth, not the file's 100: a 20 ms stall of the recorder would lose samples
    rec += ['-p', 'qos:=reliable', '-p', f'qos_depth:={RECORDER_DEPTH}',
            '-p', f'hardware_id:={hardware_id}', '-p', f'output:={record_path}',
            '-p', f'split_bytes:={int(opts.max_bag_size_B)}',
            '-p', f'split_duration_s:={float(opts.max_bag_duration_s)!r}']
    if opts.config is not None:
        cfg = str(Path(opts.config).resolve())
        rig += ['-p', f'config_file:={cfg}']
        est += ['-p', f'config_file:={cfg}']
        rec += ['-p', f'config_file:={cfg}']
    commands = {'rig': rig, 'estimator': est}
    if record_path is not None:
        commands['recorder'] = rec
    return commands


def address_taken(host: str, port: int) -> Optional[str]:
    """Return why ``host:port`` cannot be listened on now, or None when it can."""
    family = socket.AF_INET6 if ':' in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as sock:
        # as the server binds: a port a finished run left in TIME_WAIT is free
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((host, port))
        except OSError as exc:
            return exc.strerror or str(exc)
    return None


def foxglove_lines(host: str, port: int) -> List[str]:
    """Return the lines that tell where to watch the live view in Foxglove."""
    url = f'ws://{address_text(host, port)}'
    # an install from a wheel has no source tree: colcon puts the layouts in share/
    layout = LIVE_LAYOUT if LIVE_LAYOUT.is_file() else 'layouts/live.json of the sources'
    return [f'Foxglove view: open {app_url(host, port)}',
            f'  (Foxglove desktop: Open connection > Foxglove WebSocket > {url}); layout: '
            f'Import from file {layout}']


def waited_nodes(recording: bool) -> List[str]:
    """Return the nodes the rig waits for before its duty (the recorder when recording)."""
    return [ESTIMATOR_NODE] + ([RECORDER_NODE] if recording else [])


def _die_with_parent() -> None:
    """Ask the kernel to SIGKILL this (child) process when its parent dies (Linux)."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, int(signal.SIGKILL), 0, 0, 0)     # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


class Child:
    """One child process in its own session, its output in a log file."""

    def __init__(self, name: str, cmd: List[str], env: Dict[str, str], log_dir: Path) -> None:
        self.name = name
        self.log_path = log_dir / f'{name}.log'
        self._log = open(self.log_path, 'wb')
        self.proc = subprocess.Popen(cmd, env=env, stdin=subprocess.DEVNULL, stdout=self._log,
                                     stderr=subprocess.STDOUT, start_new_session=True,
                                     preexec_fn=_die_with_parent)
        self.signals: List[str] = []     # what it took to stop it
        #: what its exit statuses other than 0 mean when it stopped as asked (by SIGINT)
        self.meanings: Dict[int, str] = {}

    def running(self) -> bool:
        """Return whether the process is still running."""
        return self.proc.poll() is None

    def signal(self, sig: int) -> None:
        """Send ``sig`` to the child's process group (nothing if it already ended)."""
        if self.running():
            self.signals.append(signal.Signals(sig).name)
            try:
                os.killpg(self.proc.pid, sig)
            except ProcessLookupError:
                pass

    def close(self) -> None:
        """Close the log file."""
        self._log.close()

    def tail(self, n: int = 15) -> List[str]:
        """Return the last ``n`` lines of its output."""
        try:
            text = self.log_path.read_text(errors='replace')
        except OSError:
            return []
        return text.splitlines()[-n:]

    def clean(self) -> bool:
        """Return whether it exited by itself with status 0 after at most a SIGINT."""
        return self.proc.returncode == 0 and not (set(self.signals) - {'SIGINT'})

    def describe(self) -> str:
        """Return how it ended, in words."""
        rc = self.proc.returncode
        if rc is None:
            return 'still running'
        how = f'exit status {rc}' if rc >= 0 else f'killed by {signal.Signals(-rc).name}'
        if self.clean():
            return f'exited cleanly ({how})'
        if rc in self.meanings and not set(self.signals) - {'SIGINT'}:
            return f'exited ({how}: {self.meanings[rc]})'
        if not self.signals:
            return f'ended by itself ({how})'
        return f'did not exit cleanly ({how}; sent {", ".join(self.signals)})'


def stop_children(children: List[Child]) -> None:
    """Stop every child: SIGINT, then SIGTERM, then SIGKILL, each after a timeout."""
    for sig, wait_s in ((signal.SIGINT, SIGINT_WAIT_S), (signal.SIGTERM, SIGTERM_WAIT_S),
                        (signal.SIGKILL, 5.0)):
        for c in children:
            c.signal(sig)
        deadline = time.monotonic() + wait_s
        for c in children:
            try:
                c.proc.wait(timeout=max(deadline - time.monotonic(), 0.01))
            except subprocess.TimeoutExpired:
                pass
        if not any(c.running() for c in children):
            return


@dataclass
class TwinState:
    """What the monitor has seen of the estimator and the rig."""

    temps: Dict[str, float] = field(default_factory=dict)
    peaks: Dict[str, float] = field(default_factory=dict)
    sigma_K: Optional[float] = None
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
    rig_started: Optional[float] = None                       # when the duty started
    hardware_id: str = field(default_factory=lambda: f'wet-eha-live-{os.getpid()}')

    # --------------------------------------------------------------- updates
    def on_estimate(self, name: str, temperature_C: float, variance: float, stamp_s: float,
                    rx: float) -> None:
        """Take one estimate message."""
        self.temps[name] = temperature_C
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
            if st.name.startswith('wet_eha_thermal: ') and st.hardware_id != self.hardware_id:
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
            elif st.name == RECORDER_STATUS:
                self.on_recorder(level_name(st.level), st.message, kv)

    def on_recorder(self, level: str, message: str, values: Dict[str, str]) -> None:
        """Take the recorder's status: level (OK, WARN, ERROR), message and values."""
        if level != self.recorder_level and level in ('WARN', 'ERROR'):
            self.recorder_faults.append(f'{level}: {message}')
        self.recorder_level, self.recorder_message, self.recorder = level, message, values

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

    # ---------------------------------------------------------------- output
    def limit_text(self) -> str:
        """Return the nearest limit crossing of the forecast, or why there is none."""
        if not self.time_to_limit:
            return 'pending'
        found = []
        for q, text in self.time_to_limit.items():
            try:
                found.append((float(text), q))
            except ValueError:
                pass
        if found:
            s, q = min(found)
            return f'{q} in {_duration(s)}'
        if all(t == 'beyond horizon' for t in self.time_to_limit.values()):
            return 'beyond horizon'
        return 'pending'

    def starting_line(self, waited_s: float, waits: List[str]) -> str:
        """Return the status line of the start-up: who the rig still waits for."""
        missing = [n for n in waits if n not in self.ready]
        what = ('waiting for ' + ', '.join(missing) + ' (starting, warming the model, '
                'matching the inputs)') if missing else 'everyone ready, the rig starts'
        return f'start-up {waited_s:5.1f} s | {what}'

    def status_line(self, elapsed_s: float, duration_s: float) -> str:
        """Return the one-line status."""
        if not self.estimates:
            return f't {elapsed_s:5.1f}/{duration_s:g} s | waiting for the first estimate ...'

        def t(name: str) -> str:
            v = self.temps.get(name)
            return f'{v:6.1f}' if v is not None else '   ---'

        margin = f'{self.margin} A' if _is_number(self.margin) else self.margin
        alert = self.alert_level if self.alert_message in ('OK', '') else \
            f'{self.alert_level}: {self.alert_message}'
        return (f't {elapsed_s:5.1f}/{duration_s:g} s | winding hot-spot {t("winding_hotspot")}'
                f' mean {t("winding_mean")} | magnet {t("magnet")} | oil {t("oil")} degC | '
                f'margin {margin} | limit: {self.limit_text()} | alerts {alert} | '
                f'stale: {self.fallback}' + self.recorder_text())

    def recorder_text(self) -> str:
        """Return the recorder's part of the status line ('' when not recording)."""
        if not self.recorder_level:
            return ''
        if self.recorder_level == 'OK':
            written = self.recorder.get('bytes written', '')
            return f' | rec OK {_mib_text(written)}'
        return f' | REC {self.recorder_level}: {self.recorder_message}'


def level_name(level) -> str:
    """Return a DiagnosticStatus level's name (rclpy gives a byte field as 1-byte bytes)."""
    value = level[0] if isinstance(level, (bytes, bytearray)) else int(level)
    return ('OK', 'WARN', 'ERROR', 'STALE')[value] if 0 <= value <= 3 else str(value)


def _mib_text(n_bytes: str) -> str:
    """Return a byte count (text) in MiB, or the text as it is when it is no number."""
    try:
        return f'{int(n_bytes) / 2 ** 20:.1f} MiB'
    except ValueError:
        return n_bytes


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _what(opts: LiveOptions) -> str:
    return f'duty file {opts.duty}' if opts.duty is not None else f'stage {opts.stage}'


def _duration(s: float) -> str:
    if s < 120.0:
        return f'{s:.0f} s'
    if s < 7200.0:
        return f'{s / 60.0:.0f} min'
    return f'{s / 3600.0:.1f} h'


class StatusPrinter:
    """One status line: rewritten in place on a terminal, a line every few seconds otherwise."""

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream
        self.tty = stream.isatty()
        self.period = TTY_PERIOD_S if self.tty else LOG_PERIOD_S
        self.next = 0.0
        self.width = 0
        self.had_estimate = False

    def update(self, now: float, line: str, has_estimate: bool) -> None:
        """Show ``line`` if it is time (at once for the first estimate)."""
        first = has_estimate and not self.had_estimate
        self.had_estimate = self.had_estimate or has_estimate
        if now < self.next and not first:
            return
        self.next = now + self.period
        if self.tty:
            cols = shutil.get_terminal_size((160, 24)).columns - 1
            line = line[:cols]
            self.stream.write('\r' + line.ljust(self.width))
            self.width = len(line)
        else:
            self.stream.write(line + '\n')
        self.stream.flush()

    def finish(self) -> None:
        """End the in-place line on a terminal."""
        if self.tty and self.width:
            self.stream.write('\n')
            self.stream.flush()


def _monitor_node(context, state: TwinState):
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
    node.create_subscription(String, interface.READY_TOPIC,
                             lambda m: state.on_ready(m.data, time.monotonic()),
                             topics.latched_qos(depth=10))
    return node


def recording_text(path: Path) -> str:
    """Return what a finished recording holds, in words."""
    try:
        bag = open_bag(path)
    except (OSError, BagError) as exc:
        return f'{path}: not readable ({exc})'
    size_MiB = sum(f.stat().st_size for f in bag.files) / 2 ** 20
    text = (f'{path}: {bag.message_count} messages on {len(bag.topics)} topics, '
            f'{size_MiB:.1f} MiB')
    return text + (f' (cut: {bag.problem})' if bag.truncated else '')


_COUNTS = re.compile(r'(\w+) (\d+) received, (\d+) accepted, (\d+) rejected, '
                     r'(\d+) stale events')


def _summary_line(child: Optional[Child], tag: str) -> str:
    """Return what follows ``tag`` on the last line of the child's log that has it ('')."""
    lines = [ln for ln in child.tail(60) if tag in ln] if child is not None else []
    return lines[-1].split(tag, 1)[1].strip() if lines else ''


def sample_counts(estimator: Optional[Child], rig: Optional[Child]) -> Dict[str, object]:
    """
    Return the samples the rig published and the estimator received, from their last lines.

    ``published`` (per input, the rig's count), ``received``, ``rejected`` and
    ``stale`` (per input, the estimator's counts at its shutdown); empty where
    a child printed no summary.
    """
    out: Dict[str, object] = {}
    figures = _summary_line(rig, 'rig summary:')
    m = re.search(r'(\d+) samples x', figures)
    if m:
        out['published'] = int(m.group(1))
    figures = _summary_line(estimator, 'estimator summary:')
    found = _COUNTS.findall(figures)
    if found:
        out['received'] = {n: int(r) for n, r, _, _, _ in found}
        out['rejected'] = {n: int(x) for n, _, _, x, _ in found}
        out['stale'] = {n: int(st) for n, _, _, _, st in found}
    return out


def recorder_health_text(state: TwinState) -> str:
    """Return the recorder's last status for the summary: level, what it dropped and why."""
    if not state.recorder_level:
        return 'no report from the recorder'
    kv = state.recorder
    text = (f'{state.recorder_level} at the end ({state.recorder_message}); '
            f'{kv.get("messages written", "?")} messages written, '
            f'{kv.get("messages dropped", "?")} dropped, {kv.get("errors", "?")} errors; '
            f'{len(state.recorder_faults)} fault report(s) during the run')
    return text


def summary(opts: LiveOptions, state: TwinState, children: List[Child], run_s: float,
            domain: int, stopped_by: str, recording: Optional[Path] = None,
            start_s: float = 0.0) -> List[str]:
    """
    Return the lines of the end-of-run summary.

    ``run_s``: the duty's length (s), after ``start_s`` of start-up; ``recording``:
    the recorder's bag (directory or file).
    """
    out = ['', 'Live twin summary',
           f'  run             {run_s:.1f} s of duty after {start_s:.1f} s of start-up '
           f'({stopped_by}); {_what(opts)} on the simulated rig at {opts.rate_Hz:g} Hz, noise '
           f'{"on" if opts.noise else "off"}, ROS domain {domain}']
    if state.estimates and state.first_rx is not None:
        span = max(state.last_rx - state.first_rx, 1e-9)
        rate = (state.estimates - 1) / span if state.estimates > 1 else 0.0
        sample_span = state.last_stamp - state.first_stamp
        out.append(f'  estimates       {state.estimates} received, {rate:.1f} per s over '
                   f'{span:.1f} s ({sample_span:.1f} s of sample time)')
        peaks = ', '.join(f'{n.replace("_", " ")} {state.peaks[n]:.1f}' for n in WATCHED
                          if n in state.peaks)
        out.append(f'  peak estimates  {peaks} degC')
        ends = ', '.join(f'{n.replace("_", " ")} {state.temps[n]:.1f}' for n in WATCHED
                         if n in state.temps)
        sigma = f' (1 sigma {state.sigma_K:.1f} K)' if state.sigma_K is not None else ''
        out.append(f'  at the end      {ends} degC{sigma}')
        truth = {k: state.rig.get(f'truth_{k}_C') for k in WATCHED}
        if all(v is not None and _is_number(v) for v in truth.values()):
            diff = ', '.join(f'{n.replace("_", " ")} {float(truth[n]):.1f} '
                             f'({state.temps[n] - float(truth[n]):+.1f})' for n in WATCHED
                             if n in state.temps)
            out.append(f'  rig truth       {diff} degC (estimate - truth in brackets; last '
                       'rig report)')
        out.append(f'  margin, limits  margin current {state.margin} A RMS; time to limit: '
                   f'{state.limit_text()}')
    else:
        out.append('  estimates       none received')
    line = f'  alerts raised   {state.raised}'
    if state.alert_message not in ('OK', ''):
        line += f'; now {state.alert_level}: {state.alert_message}'
    out.append(line)
    for e in state.alert_events[-5:]:
        out.append(f'                  {e}')
    rig = next((c for c in children if c.name == 'rig'), None)
    est = next((c for c in children if c.name == 'estimator'), None)
    counts = sample_counts(est, rig)
    if 'stale' in counts:       # the estimator's own count: an input that fell silent
        during = counts['stale']
        since = 'during the duty'
    else:                       # its last diagnostics (up to a second old)
        during = state.stale_events
        since = 'at the last diagnostics'
    per = ', '.join(f'{k} {v}' for k, v in during.items() if v)
    out.append(f'  stale events    {sum(during.values())} ({since})' + (f': {per}' if per else '')
               + f'; inputs on fallback at the end: {state.fallback}')
    rig_figures = _summary_line(rig, 'rig summary:')
    if 'published' in counts and 'received' in counts:
        sent = counts['published']
        low = min(counts['received'].values())
        out.append(f'  samples         the rig published {sent} per input; the estimator '
                   f'received {low} of them on its worst input ({100.0 * low / max(sent, 1):.2f} '
                   f'%), rejected {sum(counts["rejected"].values())}')
    elif state.received:
        mean = sum(state.received.values()) / len(state.received)
        out.append(f'  samples         the estimator had received {mean:.0f} per input at its '
                   'last diagnostics')
    for c in children:
        out.append(f'  {c.name:<15} {c.describe()}')
    if rig_figures:
        out.append(f'  rig figures     {rig_figures}')
    if recording is not None:
        text = recording_text(recording) if recording.exists() else f'{recording}: not written'
        out.append(f'  recording       {text}')
        out.append(f'  recorder health {recorder_health_text(state)}')
        for fault in state.recorder_faults[-5:]:
            out.append(f'                  {fault}')
    if opts.foxglove is not None:
        said = state.ready.get(ESTIMATOR_NODE, {})
        if said.get('foxglove'):
            text = f'{said["foxglove"]}, served by the estimator'
        elif said.get('foxglove_error'):
            text = f'not started: {said["foxglove_error"]}'
        else:
            text = 'unknown: the estimator never said it was ready'
        out.append(f'  foxglove view   {text}')
    return out


def run(opts: LiveOptions, out: TextIO = sys.stdout, err: TextIO = sys.stderr,
        domain: Optional[int] = None) -> int:
    """
    Run the live twin for ``opts.duration_s`` (or until Ctrl-C); return the exit status.

    ``domain``: the ROS domain to use; None picks a free one (see :func:`open_domain`).
    Returns 2 at once when the recording's path exists (file or directory).
    """
    if opts.foxglove is not None:
        taken = address_taken(*opts.foxglove)
        if taken:
            print(f'Foxglove view: {address_text(*opts.foxglove)}: {taken}; the twin runs '
                  'without it (--foxglove HOST:PORT for another address)', file=err, flush=True)
            opts = replace(opts, foxglove=None)
    record_path = None
    if opts.record:
        record_path = Path(opts.record_path or default_output('live')).resolve()
        if record_path.exists():
            print(f'error: {record_path} exists: a recording is never overwritten', file=err)
            return 2
    # here, once: the rig and the estimator then load numba's cache in about a second each,
    # instead of both compiling at once (minutes on a busy machine) after an install
    print('loading the compiled model (after an install or a change of the model code it '
          'compiles once, in a minute or two) ...', file=out, flush=True)
    print(f'model ready in {compile_estimator(load_config(opts.config)):.1f} s', file=out,
          flush=True)
    log_dir = Path(tempfile.mkdtemp(prefix='wet-eha-live-'))
    stop = {'why': None}

    def on_signal(signum, frame) -> None:
        stop['why'] = 'interrupted' if signum == signal.SIGINT else 'terminated'

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    children: List[Child] = []
    context = node = executor = None
    state = TwinState()
    printer = StatusPrinter(out)
    early: Optional[Child] = None
    t0 = time.monotonic()
    try:
        os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'   # for this process's node
        context, domain = open_domain(domain)
        print(f'Live digital twin: {_what(opts)} on the simulated rig for {opts.duration_s:g} s '
              f'(Ctrl-C stops it earlier), ROS domain {domain}', file=out, flush=True)
        if opts.foxglove is not None:
            print('\n'.join(foxglove_lines(*opts.foxglove)), file=out, flush=True)
        env = dict(os.environ)
        env.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
                   PYTHONUNBUFFERED='1', RCUTILS_COLORIZED_OUTPUT='0')
        env.setdefault('OPENBLAS_NUM_THREADS', '1')
        commands = child_commands(opts, state.hardware_id, record_path)
        node = _monitor_node(context, state)
        waits = waited_nodes(record_path is not None)
        # all at once: the rig waits for the others to be ready before its duty starts
        children = [Child(name, commands[name], env, log_dir)
                    for name in ('rig', 'estimator', 'recorder') if name in commands]
        for c in children:
            if c.name == 'recorder':     # the recorder's own summary line says what it lost
                c.meanings[1] = 'the recording lost messages to write errors'
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        # the rig starts anyway after START_TIMEOUT_S; a little later the run gives up
        start_limit = t0 + START_TIMEOUT_S + 10.0
        while stop['why'] is None:
            now = time.monotonic()
            if state.rig_started is None:
                if now >= start_limit:
                    stop['why'] = 'start-up timed out'
                    break
                line = state.starting_line(now - t0, waits)
            else:
                elapsed = now - state.rig_started
                if elapsed >= opts.duration_s:
                    stop['why'] = 'duration reached'
                    break
                line = state.status_line(elapsed, opts.duration_s)
            executor.spin_once(timeout_sec=0.05)
            early = next((c for c in children if not c.running()), None)
            if early is not None:
                stop['why'] = f'the {early.name} exited early'
                break
            printer.update(now, line, state.estimates > 0)
        if state.rig_started is not None:
            printer.update(math.inf, state.status_line(time.monotonic() - state.rig_started,
                                                       opts.duration_s), state.estimates > 0)
    finally:
        printer.finish()
        end = time.monotonic()
        start_s = (state.rig_started if state.rig_started is not None else end) - t0
        run_s = end - t0 - start_s
        # the recorder last, so that it keeps what the others sent until they stopped
        stop_children([c for c in children if c.name != 'recorder'])
        stop_children([c for c in children if c.name == 'recorder'])
        for c in children:
            c.close()
        if node is not None:
            node.destroy_node()
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)
        if context is not None:
            rclpy.try_shutdown(context=context)
        for s, handler in old.items():
            signal.signal(s, handler)
    for line in summary(opts, state, children, run_s, domain, stop['why'] or 'stopped',
                        record_path, start_s):
        print(line, file=out)
    out.flush()
    ok = (early is None and state.rig_started is not None and state.estimates > 0
          and all(c.clean() for c in children))
    if state.rig_started is None and early is None:
        missing = [n for n in waited_nodes(record_path is not None) if n not in state.ready]
        print(f'error: the rig did not start its duty within {start_s:.0f} s of start-up'
              + (f': not ready: {", ".join(missing)}' if missing else ''), file=err)
    elif early is not None:
        print(f'error: the {early.name} {early.describe()} before the end of the run; its last '
              'lines:', file=err)
        for line in early.tail():
            print(f'  {line}', file=err)
    elif not state.estimates:
        print('error: no estimate received from the estimator', file=err)
    for c in children:
        if c is not early and not c.clean():
            print(f'error: the {c.name} {c.describe()}; its last lines:', file=err)
            for line in c.tail(8):
                print(f'  {line}', file=err)
    if ok:
        shutil.rmtree(log_dir, ignore_errors=True)
    else:
        print(f'(logs of the children kept in {log_dir})', file=err)
    err.flush()
    return 0 if ok else 1
