"""
The recorder: every topic of the twin to a rosbag2 bag directory (MCAP files).

Node ``eha_recorder``. It subscribes at start to every topic the twin uses
(``topic_prefix`` replaces ``/eha``; see :mod:`wet_eha_thermal.interface`):
each estimator input of ``INPUT_TOPICS`` (all of them: three pressures and
the differential one), the ambient temperature, the thermocouples, the
estimates, the state, the state's names and the alerts (both transient
local, so what was published before the recorder started is recorded too),
the acknowledgements, the drive's current limits and /diagnostics (its own
status included); also ros2_control's ``/joint_states`` and every topic the
estimator's inputs file ``inputs_file`` names (:mod:`wet_eha_thermal.inputs`:
a rig's JointStates, batched blocks, ...), with that file stored in the bag
so that a replay decodes them as the estimator did. ``extra_topics``
names further topics, subscribed once they appear in the ROS graph, with
their type and a QoS adapted to their publishers as rosbag2 does (reliable
and transient local only when every publisher is).

QoS of the fixed subscriptions: the sensor topics (inputs, ambient,
thermocouples) take ``qos`` (sensor_data, best effort, hears every
publisher; or reliable, which hears only reliable publishers but loses
nothing they send); the outputs and acknowledgements are reliable; the
alerts and the state's names reliable and transient local. Depth ``qos_depth``.

Messages are taken raw (CDR bytes, never deserialised) and written with
:class:`~wet_eha_thermal.bag.writer.BagWriter`; a topic becomes a channel at
its first message, with the QoS of its publisher at that moment as
``offered_qos_profiles`` (the subscription's when no publisher is known), so
topics that never carry a message are left out of the bag. Log time is the
node's ROS clock at receipt, as ``ros2 bag record`` does: the system clock,
or /clock under ``use_sim_time``, where messages received before the first
/clock are dropped and counted (they would have log time 0). The publish time
is the log time too: the EventsExecutor of the Jazzy wheels fails on
callbacks that ask for the message info (source timestamp).

The bag is what ``ros2 bag record -s mcap -o NAME`` writes: the directory
``output`` with ``NAME_0.mcap`` (then ``NAME_1.mcap``, ... when splitting)
and ``metadata.yaml``, which ``ros2 bag info`` and Foxglove read. An
``output`` ending in ``.mcap`` is one MCAP file instead (``<stem>_0.mcap``,
... beside it when splitting), for tools that want a lone file.

So that a run can be reproduced from any file of it alone, each holds Metadata
records: ``wet_eha_thermal.config`` (``path``, ``yaml``: the text of the
estimator configuration ``config_file``), ``wet_eha_thermal.params`` (the
estimator's parameters file ``params_file``, when given) and
``wet_eha_thermal.recorder`` (package ``version``, ``node``,
``started_utc`` and the recorder's ``parameters`` as YAML).

The writer closes a chunk every ``flush_interval_s``, so a SIGKILL loses
about that much; metadata.yaml is rewritten at each split, before the new
file takes its first message, so it lists every file that holds one (a kill
inside a split can leave the next file begun, unlisted and empty). SIGINT or
SIGTERM stop it cleanly: the messages already received are written, the bag
is closed (summary, rosbag2 metadata, metadata.yaml) and a one-line summary
goes to stderr. An existing file or
directory, even an empty one (as ``ros2 bag record`` refuses it), is never
overwritten (exit status 2).

A full disk or a write error never stops the recorder: the writer
(``on_error='suspend'``) closes the file being written cleanly with the
space of a reserve (``reserve_bytes``), drops and counts the messages while
there is no room, and goes on in the next split file once ``reserve_bytes +
resume_margin_bytes`` are free again. Its health (the JSON of
``interface.RECORDER_HEALTH_TOPIC``: state, messages written and dropped,
bytes, write rate, free space and the time it leaves, errors, the file
being written) goes out on that latched topic and as the /diagnostics status
``eha_recorder: recorder`` (``left/eha_recorder: recorder`` under /left)
once a second, and at once (within ``WATCH_PERIOD_S``) when the writer's
state changes: ERROR while suspended, WARN when the free space holds less
than ``free_space_warn_s`` of recording at the present rate or after a
fault it recovered from. A run that lost messages to the disk ends with
exit status 1.

Run: ``wet-eha-thermal-record --ros-args -p output:=runs/test`` or
``python -m wet_eha_thermal.ros.recorder_node``.
"""

from datetime import datetime, timezone
import functools
from importlib.metadata import version
import json
from pathlib import Path
import signal
import sys
import time
from typing import Dict, List, Optional, Tuple

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import NameValidationException, ParameterException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
from wet_eha_thermal import inputs, interface
from wet_eha_thermal.bag.writer import (BagHealth, BagWriter, COMPRESSIONS,
                                        DEFAULT_RESERVE_BYTES, DEFAULT_RESUME_MARGIN_BYTES,
                                        qos_profiles, RECORDING, SUSPENDED)
from wet_eha_thermal.config import ConfigError, default_config_path, load_config
from wet_eha_thermal.ros import topics
from wet_eha_thermal.ros.runtime import (declare_parameters, descriptor, FastClock, Readiness,
                                         run_node, shared_parameters)
import yaml

NODE_NAME = interface.RECORDER_NODE
DIAGNOSTICS_PERIOD_S = 1.0
#: The writer's state is looked at this often (steady clock, s): a change (a fault, a file
#: closed, writing resumed) is reported at once, not at the next second.
WATCH_PERIOD_S = 0.2
#: The write rate is the bytes written over this much time (s).
RATE_WINDOW_S = 10.0
#: How often the graph is searched for extra topics not subscribed yet (steady clock, s).
DISCOVERY_PERIOD_S = 0.5
#: After a stop signal, messages are written until none came for DRAIN_IDLE_S (s), at most
#: DRAIN_MAX_S.
DRAIN_IDLE_S, DRAIN_MAX_S = 0.2, 3.0
_OK, _WARN, _ERROR = 0, 1, 2


# Not the rig's helpers: importing the rig loads the model and SciPy (0.2 s), and in
# `wet-eha-thermal live` the rig waits for the recorder to start.


# name -> (default, descriptor); every parameter is read once, at start
PARAMETERS = {
    'output': ('', descriptor(
        "bag directory to make (<name>_0.mcap, ... and metadata.yaml); '' = "
        'runs/eha_<UTC time>; a name ending .mcap is one MCAP file instead (<stem>_0.mcap, '
        '... with splitting); never overwritten')),
    'split_bytes': (0, descriptor('start a new file after this many bytes (0 = never)',
                                  0, 2 ** 62)),
    'split_duration_s': (0.0, descriptor(
        'start a new file after this much log time, s (0 = never)', 0.0, 1.0e7)),
    'flush_interval_s': (1.0, descriptor(
        'close a chunk after this much time: the most a SIGKILL loses, s', 0.05, 60.0)),
    'free_space_warn_s': (600.0, descriptor(
        'warn when the free space at the destination holds less than this much recording at '
        'the present write rate, s', 0.0, 1.0e6)),
    'reserve_bytes': (DEFAULT_RESERVE_BYTES, descriptor(
        'space held in reserve beside the bag, freed to close a file cleanly when the disk is '
        'full, bytes', 0, 2 ** 40)),
    'resume_margin_bytes': (DEFAULT_RESUME_MARGIN_BYTES, descriptor(
        'after a full disk, writing resumes (in a new file) once this much more than the '
        'reserve is free again, bytes', 0, 2 ** 40)),
    'compression': ('zstd', descriptor('chunk compression: ' + ', '.join(COMPRESSIONS))),
    **shared_parameters('qos', 'qos_depth', 'topic_prefix', 'hardware_id', 'executor'),
    # declared by type: rclpy takes an empty list for a byte array; unset, it reads None
    'extra_topics': (Parameter.Type.STRING_ARRAY, descriptor(
        'further topics to record (names; type and QoS from their publishers)')),
    'config_file': ('', descriptor(
        "estimator configuration stored in the bag; '' = the shipped "
        'config/reference_eha.yaml')),
    'params_file': ('', descriptor(
        "estimator parameters file stored in the bag ('' = none)")),
    'inputs_file': ('', descriptor(
        "the estimator's inputs file (wet_eha_thermal/inputs.py): its topics are recorded "
        "and the file stored in the bag, for replay; '' = the /eha topics")),
    'wait_for_estimator': (False, descriptor(
        "say ready only once the estimator's volatile outputs (estimates, state, limits) are "
        'matched too (live sets it: a rig that waits for the recorder then starts its duty '
        'with every tick of them recorded from the first)')),
}


def recorded_topics(prefix: str = interface.PREFIX) -> Dict[str, Tuple[str, str]]:
    """Return the fixed topics of the recorder under ``prefix``: the twin's topic table."""
    return interface.topic_table(prefix)


def default_output(stem: str = 'eha') -> Path:
    """Return the bag directory ``runs/<stem>_<UTC time>`` (relative to the working folder)."""
    return Path('runs') / f'{stem}_{datetime.now(timezone.utc):%Y%m%dT%H%M%SZ}'


def is_single_file(output: Path) -> bool:
    """Return whether the recorder's ``output`` names one MCAP file, not a bag directory."""
    return output.suffix == '.mcap'


def _text_record(path: Path) -> Dict[str, str]:
    try:
        return {'path': str(path.resolve()), interface.CONFIG_METADATA_KEY: path.read_text()}
    except OSError as exc:
        raise ConfigError(f'cannot read {path}: {exc.strerror}') from exc


def _mib(n_bytes: int) -> str:
    return f'{n_bytes / 2 ** 20:.2f} MiB'


def _fmt(value: Optional[float]) -> str:
    return 'unknown' if value is None else f'{value:.0f}'


class RecorderNode(Node):
    """Record the twin's topics raw to a rosbag2 bag (see the module docstring)."""

    def __init__(self, **kwargs) -> None:
        super().__init__(NODE_NAME, **kwargs)
        p = self._read_parameters()
        # before the bag is made: a bad qos or inputs file leaves no empty recording behind
        input_spec = inputs.load_inputs(p['inputs_file'])
        qos_of = {kind: topics.qos_profile(kind, p['qos'], p['qos_depth'])
                  for kind in (interface.SENSOR, interface.OUTPUT, interface.LATCHED)}
        self.hardware_id = p['hardware_id']
        self.depth = p['qos_depth']
        self.started_utc = datetime.now(timezone.utc).isoformat(timespec='seconds')
        self.output = Path(p['output']) if p['output'] else default_output()
        self.writer = self._open_bag(p)

        self.types: Dict[str, str] = {}             # subscribed topic -> type
        self.qos: Dict[str, QoSProfile] = {}        # ... and its subscription's QoS
        self.counts: Dict[str, int] = {}            # topics written so far -> messages
        self.total = 0
        self.before_clock = 0                       # dropped: no /clock yet under use_sim_time
        self.errors = 0                             # of this node (the writer counts its own)
        self.last_error = ''
        self.write_failed = False                   # the bag lost messages (disk full, ...)
        self.free_space_warn_s = p['free_space_warn_s']
        self._rates: List[Tuple[float, int]] = []   # (time, bytes written) over RATE_WINDOW_S
        self._reported: Optional[tuple] = None      # what the last report said, to see news
        self.started_s = time.monotonic()
        self.clock = FastClock(self)
        input_subs, output_subs = self._subscribe_fixed(p['topic_prefix'], qos_of)
        input_subs += self._subscribe_inputs(p['topic_prefix'], input_spec,
                                             qos_of[interface.SENSOR])
        extra = ['/' + t.lstrip('/') for t in p['extra_topics']]    # as rosbag2 names them
        self.extra_wanted = [t for t in extra if t not in self.types]
        self._start_reporting(p['topic_prefix'], input_subs,
                              output_subs if p['wait_for_estimator'] else [])
        self.get_logger().info(
            f'recording {len(self.types)} topics under {p["topic_prefix"]} ({p["qos"]} QoS for '
            f'the sensors, depth {self.depth}) to {self.output}'
            + (f'; waiting for {", ".join(self.extra_wanted)}' if self.extra_wanted else ''))

    def _read_parameters(self) -> dict:
        """Declare the parameters and return their values, checked (ValueError)."""
        p = declare_parameters(self, PARAMETERS)
        p['extra_topics'] = list(p['extra_topics'] or [])
        p['use_sim_time'] = self.get_parameter('use_sim_time').value
        return p

    def _open_bag(self, p: dict) -> BagWriter:
        """Return the writer of a new bag at ``self.output``, its metadata from ``p``."""
        # check the configuration as the estimator will, and keep its text
        config_path = Path(p['config_file']) if p['config_file'] else default_config_path()
        load_config(config_path)
        metadata = {interface.CONFIG_METADATA: _text_record(config_path)}
        if p['params_file']:
            metadata[interface.PARAMS_METADATA] = _text_record(Path(p['params_file']))
        if p['inputs_file']:
            metadata[interface.INPUTS_METADATA] = _text_record(inputs.inputs_path(
                p['inputs_file']))
        metadata[interface.RECORDER_METADATA] = {
            'version': version('wet_eha_thermal'), 'node': self.get_fully_qualified_name(),
            'started_utc': self.started_utc,
            'parameters': yaml.safe_dump(p, sort_keys=False)}
        self.output.parent.mkdir(parents=True, exist_ok=True)
        try:
            # a full disk or a write error suspends the bag (files closed cleanly, messages
            # counted as dropped) until there is room again: the run is never stopped by it
            return BagWriter(
                self.output, metadata=metadata, flush_interval_s=p['flush_interval_s'],
                split_bytes=p['split_bytes'] or None,
                split_duration_s=p['split_duration_s'] or None, compression=p['compression'],
                directory=not is_single_file(self.output), on_error='suspend',
                reserve_bytes=p['reserve_bytes'], resume_margin_bytes=p['resume_margin_bytes'])
        except FileExistsError as exc:   # the directory, or the first file
            raise FileExistsError(f'{exc.filename} exists: a recording is never '
                                  'overwritten') from None

    def _start_reporting(self, prefix: str, input_subs: list, also: list) -> None:
        """
        Start the health and diagnostics, the ready handshake and the extra topics' search.

        ``also``: subscriptions the ready handshake waits for in any case (the
        estimator's volatile outputs, with ``wait_for_estimator``: the messages
        of one sent before the recorder had found it would be lost, and that
        topic's count would fall short of the others').
        """
        self.diag_pub = self.create_publisher(DiagnosticArray, interface.DIAGNOSTICS_TOPIC,
                                              QoSProfile(depth=10))
        self.health_pub = self.create_publisher(
            String, interface.prefixed(interface.RECORDER_HEALTH_TOPIC, prefix),
            topics.latched_qos())
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(DIAGNOSTICS_PERIOD_S, self._report, clock=steady)
        self.create_timer(WATCH_PERIOD_S, self._watch, clock=steady)
        # ready once every input topic that has a publisher is matched (a rig publishes
        # either the three pressures or the differential one)
        self.readiness = Readiness(
            self, interface.prefixed(interface.READY_TOPIC, prefix), input_subs,
            self.hardware_id, require_all=False, also=also)
        if self.extra_wanted:
            # steady clock: under use_sim_time an extra topic may be /clock itself
            self._discovery = self.create_timer(DISCOVERY_PERIOD_S, self._discover,
                                                clock=steady)
            self._discover()

    # ------------------------------------------------------------ subscriptions
    def _subscribe_fixed(self, prefix: str, qos_of: Dict[str, QoSProfile]
                         ) -> Tuple[list, list]:
        """Subscribe to every fixed topic under ``prefix``; return the inputs' and outputs'."""
        inputs = {interface.prefixed(t, prefix) for t in interface.INPUT_TOPICS.values()}
        outputs = set(interface.volatile_outputs(prefix))
        input_subs, output_subs = [], []
        for topic, (type_name, kind) in recorded_topics(prefix).items():
            sub = self._subscribe(topic, type_name, qos_of[kind])
            if topic in inputs:
                input_subs.append(sub)
            elif topic in outputs:
                output_subs.append(sub)
        return input_subs, output_subs

    def _subscribe_inputs(self, prefix: str, spec: inputs.Inputs, qos: QoSProfile) -> list:
        """Subscribe to /joint_states and each topic of the inputs file not subscribed yet."""
        wanted = {interface.JOINT_STATES_TOPIC: interface.JOINT_STATE}
        wanted.update({interface.prefixed(topic, prefix): type_name
                       for topic, type_name in inputs.topic_types(spec).items()})
        return [self._subscribe(topic, type_name, qos) for topic, type_name in wanted.items()
                if topic not in self.types]

    def _subscribe(self, topic: str, type_name: str, qos: QoSProfile):
        sub = self.create_subscription(topics.message_class(type_name), topic,
                                       functools.partial(self._on_message, topic), qos,
                                       raw=True)
        self.types[topic] = type_name
        self.qos[topic] = qos
        return sub

    def _discover(self) -> None:
        """Subscribe to the extra topics that have appeared, with their publishers' QoS."""
        for topic in list(self.extra_wanted):
            try:
                infos = self.get_publishers_info_by_topic(topic)
                if not infos:
                    continue
                reliable = all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE
                               for i in infos)
                latched = all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
                              for i in infos)
                qos = QoSProfile(
                    history=HistoryPolicy.KEEP_LAST, depth=self.depth,
                    reliability=(ReliabilityPolicy.RELIABLE if reliable
                                 else ReliabilityPolicy.BEST_EFFORT),
                    durability=(DurabilityPolicy.TRANSIENT_LOCAL if latched
                                else DurabilityPolicy.VOLATILE))
                self._subscribe(topic, infos[0].topic_type, qos)
                self.get_logger().info(f'recording {topic} ({infos[0].topic_type})')
            except Exception as exc:  # noqa: B902 - a bad name or type: report, record the rest
                self._failed(topic, exc)
            self.extra_wanted.remove(topic)
        if not self.extra_wanted:
            self._discovery.cancel()

    def _offered_qos(self, topic: str) -> QoSProfile:
        """Return the QoS of the topic's publisher (the subscription's when none is known)."""
        type_name = self.types[topic]
        for info in self.get_publishers_info_by_topic(topic):
            if info.topic_type == type_name:
                return info.qos_profile
        return self.qos[topic]

    def _on_message(self, topic: str, data: bytes) -> None:
        try:
            log_time_ns = self.clock.now_ns()
            if log_time_ns == 0:
                self.before_clock += 1
                return
            if topic not in self.counts:
                self.writer.add_topic(topic, self.types[topic],
                                      qos_profiles(self._offered_qos(topic)))
                self.counts[topic] = 0
            self.writer.write(topic, data, log_time_ns)     # dropped (counted) if suspended
            self.counts[topic] += 1
            self.total += 1
        except Exception as exc:  # noqa: B902 - never raise into the executor
            self._failed(topic, exc)

    def _failed(self, where: str, exc: BaseException) -> None:
        self.errors += 1
        self.last_error = f'{where}: {type(exc).__name__}: {exc}'
        self.get_logger().error(self.last_error, throttle_duration_sec=5.0)

    # ------------------------------------------------------------ reporting
    def bytes_written(self) -> int:
        """Return the size of the files written so far."""
        return self.writer.health().bytes_written

    def _watch(self) -> None:
        """Report at once when the writer's state or the level changed (a fault, a resume)."""
        try:
            h = self.writer.health()
            if self._news(h) != self._reported:
                self._report(h)
        except Exception as exc:  # noqa: B902
            self._failed('health', exc)

    def _news(self, h: BagHealth) -> tuple:
        """Return what, changed, is worth a report at once: state, faults, file, level."""
        return (h.state, h.changes, h.current_file, self.errors, self._level(h)[0])

    def _rate(self, h: BagHealth) -> Optional[float]:
        """Return the bytes written per second over the last RATE_WINDOW_S (None: too soon)."""
        self._rates.append((h.time_s, h.bytes_written))
        while len(self._rates) > 2 and h.time_s - self._rates[1][0] >= RATE_WINDOW_S:
            self._rates.pop(0)
        t0, b0 = self._rates[0]
        return (h.bytes_written - b0) / (h.time_s - t0) if h.time_s - t0 >= 1.0 else None

    def _time_left(self, h: BagHealth, rate: Optional[float]) -> Optional[float]:
        """Return how long the free space lasts at ``rate`` (s; None: unknown or no writing)."""
        if h.free_bytes is None or rate is None or rate <= 0.0:
            return None
        return h.free_bytes / rate

    def _level(self, h: BagHealth, rate: Optional[float] = None) -> Tuple[int, str]:
        """Return the level (OK, WARN, ERROR) and the message of the recorder's health."""
        if h.state == SUSPENDED:
            since = time.strftime('%H:%M:%S', time.localtime(h.last_error_time_s or time.time()))
            return _ERROR, (f'writing suspended since {since} ({h.last_error}); '
                            f'{h.messages_dropped} messages dropped; resumes in a new file when '
                            'there is room')
        if h.state != RECORDING:
            return _ERROR, f'the bag is {h.state}'
        left = self._time_left(h, rate)
        if left is not None and left < self.free_space_warn_s:
            return _WARN, (f'{left / 60.0:.1f} min of recording left at {rate / 1e3:.0f} kB/s '
                           f'({_mib(h.free_bytes)} free)')
        if h.errors:
            return _WARN, (f'writing again after {h.errors} write error(s), last: '
                           f'{h.last_error}; {h.messages_dropped} messages dropped')
        if self.errors:
            return _WARN, f'{self.errors} errors, last: {self.last_error}'
        if self.before_clock:
            return _WARN, f'{self.before_clock} messages before the first /clock'
        return _OK, f'recording to {h.current_file}'

    def health(self, h: Optional[BagHealth] = None) -> dict:
        """Return the recorder's health as it publishes it (interface.RECORDER_HEALTH_TOPIC)."""
        h = self.writer.health() if h is None else h
        rate = self._rate(h)
        level, message = self._level(h, rate)
        left = self._time_left(h, rate)
        return {'node': NODE_NAME, 'hardware_id': self.hardware_id, 'stamp_s': time.time(),
                'level': level, 'level_name': ('OK', 'WARN', 'ERROR')[level],
                'message': message, 'state': h.state,
                'messages_written': h.messages_written, 'messages_dropped': h.messages_dropped,
                'bytes_written': h.bytes_written, 'write_rate_B_s': rate,
                'free_bytes': h.free_bytes, 'time_left_s': left,
                'errors': h.errors + self.errors,
                'last_error': h.last_error or self.last_error,
                'file': None if h.current_file is None else str(h.current_file),
                'files': len(h.files)}

    def _report(self, h: Optional[BagHealth] = None) -> None:
        """Publish the health (topic) and the status (/diagnostics), now."""
        try:
            h = self.writer.health() if h is None else h
            health = self.health(h)
            self._reported = self._news(h)
            self.health_pub.publish(String(data=json.dumps(health)))
            values = [('state', h.state), ('messages written', h.messages_written),
                      ('messages dropped', h.messages_dropped),
                      ('bytes written', h.bytes_written),
                      ('write rate [B/s]', _fmt(health['write_rate_B_s'])),
                      ('free [B]', h.free_bytes), ('time left [s]', _fmt(health['time_left_s'])),
                      ('errors', health['errors']), ('last error', health['last_error']),
                      ('file', health['file'] or 'none'),
                      ('files', ', '.join(str(f) for f in h.files)),
                      ('topics written', len(self.counts)), ('topics subscribed', len(self.types)),
                      ('dropped before /clock', self.before_clock),
                      ('waiting for', ', '.join(self.extra_wanted) or 'none')]
            arr = DiagnosticArray()
            arr.header.stamp = self.get_clock().now().to_msg()
            arr.status = [DiagnosticStatus(
                level=bytes([health['level']]), message=health['message'],
                name=interface.status_name('recorder', self.get_name(), self.get_namespace()),
                hardware_id=self.hardware_id,
                values=[KeyValue(key=k, value=str(v)) for k, v in values])]
            self.diag_pub.publish(arr)
        except Exception as exc:  # noqa: B902
            self._failed('diagnostics', exc)

    def drain(self, executor) -> None:
        """Spin until no message came for ``DRAIN_IDLE_S`` (at most ``DRAIN_MAX_S``)."""
        start = idle_since = time.monotonic()
        total = self.total
        while True:
            executor.spin_once(timeout_sec=DRAIN_IDLE_S / 4)
            now = time.monotonic()
            if self.total != total:
                total, idle_since = self.total, now
            if now - idle_since >= DRAIN_IDLE_S or now - start >= DRAIN_MAX_S:
                return

    def close(self) -> str:
        """Close the bag (summary, rosbag2 metadata) and return the one-line summary."""
        h = self.writer.close()
        # a run that lost messages to the disk ends with status 1, however it recovered
        self.write_failed = h.errors > 0
        run_s = time.monotonic() - self.started_s
        per_topic = ', '.join(f'{t} {n}' for t, n in sorted(self.counts.items()))
        paths = h.files
        where = (', '.join(str(p) for p in paths) if is_single_file(self.output)
                 else f'{self.output} ({len(paths)} file{"s" if len(paths) > 1 else ""})')
        lost = (f'; write errors {h.errors} (last: {h.last_error}), {h.messages_dropped} '
                'messages dropped' if h.errors or h.messages_dropped else '')
        return (f'recorder summary: {h.messages_written} messages on {len(self.counts)} topics '
                f'in {run_s:.1f} s to {where} ({_mib(h.bytes_written)}){lost}; dropped before '
                f'/clock {self.before_clock}, errors {self.errors}; per topic: '
                f'{per_topic or "none"}')


_DESCRIPTION = ('Record the topics of the wet-EHA twin to a rosbag2 bag directory of MCAP '
                'files (ROS 2 node eha_recorder). ROS arguments follow --ros-args, e.g. '
                '--ros-args -p output:=runs/test -p qos:=reliable')


def main(args: Optional[List[str]] = None) -> int:
    """Record until Ctrl-C or SIGTERM; return the exit status (2: bad parameter or file)."""
    ignored = {}

    def drain(node: RecorderNode, executor) -> None:
        # a second signal must not cut the last chunk or the summary being written
        ignored.update({s: signal.signal(s, signal.SIG_IGN)
                        for s in (signal.SIGINT, signal.SIGTERM)})
        node.drain(executor)

    def close(node: RecorderNode) -> int:
        try:
            print(node.close(), file=sys.stderr, flush=True)
        finally:
            for s, handler in ignored.items():
                signal.signal(s, handler)
        return 1 if node.write_failed else 0

    return run_node(args, 'wet-eha-thermal-record', _DESCRIPTION, RecorderNode,
                    (ConfigError, FileExistsError, NameValidationException, ParameterException,
                     ValueError), after_spin=drain, close=close)


if __name__ == '__main__':
    sys.exit(main())
