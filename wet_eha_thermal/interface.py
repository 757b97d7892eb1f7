"""
The twin's interface, without ROS: topic names, message types, estimates, thermocouples.

Inputs (what the rig publishes; SI units, as the messages define them):

| input | default topic | type | unit |
| --- | --- | --- | --- |
| phase current | /eha/current | std_msgs/Float64 | A RMS |
| motor speed | /eha/speed | std_msgs/Float64 | rad/s (signed) |
| port A pressure | /eha/pressure_a | sensor_msgs/FluidPressure | Pa absolute |
| port B pressure | /eha/pressure_b | sensor_msgs/FluidPressure | Pa absolute |
| accumulator pressure | /eha/pressure_acc | sensor_msgs/FluidPressure | Pa absolute |
| or: differential pressure | /eha/pressure_diff | sensor_msgs/FluidPressure | Pa, p_A - p_B |
| actuator position (LVDT) | /eha/position | std_msgs/Float64 | m |
| ambient temperature | /eha/ambient | sensor_msgs/Temperature | degC |
| thermocouples | /eha/measured/<name> | sensor_msgs/Temperature | degC |

A Float64 carries no stamp: its sample time is the receiving node's clock (the
ROS clock, so /clock under use_sim_time). Messages with a header use its stamp,
or the clock when the stamp is zero. These are the defaults: a rig declares its
own topics, types (JointState, batched blocks) and units in the estimator's
``inputs_file`` (:mod:`wet_eha_thermal.inputs`).

Outputs of the estimator: /eha/estimate/<name> (sensor_msgs/Temperature, degC,
variance = uncertainty^2) for every name in ``ESTIMATES``; /eha/state
(std_msgs/Float64MultiArray: the model's state vector in K) with the name of
each element on /eha/state_names (std_msgs/String holding JSON, transient-local:
the names do not change within a run); /diagnostics
(diagnostic_msgs/DiagnosticArray, 1 Hz); /eha/alerts (std_msgs/String holding
JSON, transient-local so a late subscriber gets the last one) and the same as
numbers on /eha/drive/alerts (:class:`DriveAlerts`); acknowledgements
on /eha/alerts/ack (std_msgs/String: a quantity, or empty for all); the drive's
current limits on /eha/current_limits (sensor_msgs/JointState) and
/eha/current_limit (std_msgs/Float64), below. The recorder
reports its health on /eha/recorder/health (std_msgs/String holding JSON,
transient-local) and in /diagnostics.

At shutdown the simulated rig and the estimator print their counts as one
line of JSON, a :class:`NodeReport`, which ``live`` summarises.

The estimator, the offline tools and the ROS nodes take these names from
here; :mod:`.ros.topics` adds what needs rclpy (QoS profiles, publishing).
"""

from dataclasses import asdict, dataclass, field
import enum
import json
import math
from typing import Dict, Iterable, Optional, Sequence, TextIO, Tuple

PREFIX = '/eha'
#: Message types of the twin's topics, as bags store them (pkg/msg/Type)
FLOAT64 = 'std_msgs/msg/Float64'
FLUID_PRESSURE = 'sensor_msgs/msg/FluidPressure'
TEMPERATURE = 'sensor_msgs/msg/Temperature'
FLOAT64_ARRAY = 'std_msgs/msg/Float64MultiArray'
STRING = 'std_msgs/msg/String'
DIAGNOSTIC_ARRAY = 'diagnostic_msgs/msg/DiagnosticArray'
JOINT_STATE = 'sensor_msgs/msg/JointState'
#: Metadata records of a bag the twin writes (the recorder's, a replay's, the simulated
#: rig's): the estimator's configuration, as {CONFIG_METADATA_KEY: its YAML text, ...},
#: the estimator node's parameters file and the recorder's settings
CONFIG_METADATA = 'wet_eha_thermal.config'
CONFIG_METADATA_KEY = 'yaml'
PARAMS_METADATA = 'wet_eha_thermal.params'
#: ... and the estimator's inputs file (``inputs_file``), which a replay decodes by
INPUTS_METADATA = 'wet_eha_thermal.inputs'
RECORDER_METADATA = 'wet_eha_thermal.recorder'
#: The nodes' names (one place: ``live`` and the rig's ``wait_for`` name them too)
ESTIMATOR_NODE, RIG_NODE, RECORDER_NODE = 'eha_thermal_estimator', 'eha_sim_rig', 'eha_recorder'
#: The sensor inputs, in the order of the model's SampleBlock fields: SI units (A RMS,
#: rad/s, absolute Pa of chamber A, chamber B and the accumulator, m of the LVDT)
INPUTS = ('current_A', 'speed_rad_s', 'p_a_Pa', 'p_b_Pa', 'p_acc_Pa', 'position_m')
#: ... with one differential pressure sensor, p_a - p_b (estimator.pressure_inputs:
#: differential)
DIFFERENTIAL_INPUTS = ('current_A', 'speed_rad_s', 'dp_Pa', 'position_m')
INPUT_TOPICS = {
    'current_A': f'{PREFIX}/current',
    'speed_rad_s': f'{PREFIX}/speed',
    'p_a_Pa': f'{PREFIX}/pressure_a',
    'p_b_Pa': f'{PREFIX}/pressure_b',
    'p_acc_Pa': f'{PREFIX}/pressure_acc',
    'dp_Pa': f'{PREFIX}/pressure_diff',      # instead of the three above (pressure_inputs)
    'position_m': f'{PREFIX}/position',
}
# sensor_msgs/FluidPressure; the others are std_msgs/Float64
PRESSURE_INPUTS = ('p_a_Pa', 'p_b_Pa', 'p_acc_Pa', 'dp_Pa')
#: message type name of every input, as bags store it
INPUT_TYPES = {name: FLUID_PRESSURE if name in PRESSURE_INPUTS else FLOAT64
               for name in INPUT_TOPICS}
AMBIENT_TOPIC = f'{PREFIX}/ambient'
MEASURED_PREFIX = f'{PREFIX}/measured'
ESTIMATE_PREFIX = f'{PREFIX}/estimate'
STATE_TOPIC = f'{PREFIX}/state'
#: latched std_msgs/String JSON {"unit": "K", "names": [...]}: one name per element of
#: the state (the model's :attr:`~wet_eha_thermal.model.eha.EHAModel.quantities`)
STATE_NAMES_TOPIC = f'{PREFIX}/state_names'
ALERT_TOPIC = f'{PREFIX}/alerts'
ACK_TOPIC = f'{PREFIX}/alerts/ack'
#: latched std_msgs/String JSON of each node that is ready ({"node", "ready", ...}); the
#: simulated rig starts its duty once the nodes it waits for are, and says so here too
READY_TOPIC = f'{PREFIX}/ready'
#: latched std_msgs/String JSON of the recorder's health, at 1 Hz and at once on a change:
#: {"node", "hardware_id", "stamp_s", "level" (0 OK, 1 WARN, 2 ERROR), "level_name",
#: "message", "state" (recording, suspended, closed), "messages_written",
#: "messages_dropped", "bytes_written", "write_rate_B_s", "free_bytes", "time_left_s"
#: (free space over the write rate; null while nothing is written), "errors",
#: "last_error", "file" (being written; null while suspended), "files"}
RECORDER_HEALTH_TOPIC = f'{PREFIX}/recorder/health'
#: The thermal current limits for the drive (docs/live.md#current-limits-for-the-drive):
#: sensor_msgs/JointState stamped with the sample time they belong to, one entry per horizon
#: (effort: A RMS; position: the horizon, s; +inf for the continuous limit;
#: header.frame_id: "ok" or "fallback: <why>"), and the binding limit alone (the
#: shortest horizon's, or the fallback) as a std_msgs/Float64 for the simplest drive
CURRENT_LIMITS_TOPIC = f'{PREFIX}/current_limits'
CURRENT_LIMIT_TOPIC = f'{PREFIX}/current_limit'
#: The same limits as numbers only, for a drive or a PLC bridge that parses no text: a
#: std_msgs/Float64MultiArray of the layout :class:`DriveLimits` documents (reliable,
#: depth 100), one message per limit tick
DRIVE_LIMITS_TOPIC = f'{PREFIX}/drive/limits'
#: The alerts' state as numbers only: a std_msgs/Float64MultiArray of the layout
#: :class:`DriveAlerts` documents, latched (reliable, transient local) like ALERT_TOPIC and
#: sent with it: at start, at every change of a level or an acknowledgement
DRIVE_ALERTS_TOPIC = f'{PREFIX}/drive/alerts'
#: What-if from the live state (docs/live.md#what-if-from-the-live-state), std_msgs/String JSON
#: both ways, reliable and volatile. The request: {"id": text, one duty of "stage" (1..6),
#: "table" {"time_s", "flow_L_min", "load_MPa": [...]} or "samples" {"time_s", "current_A",
#: "speed_rad_s", "p_a_Pa", "p_b_Pa", "p_acc_Pa"[, "position_m"]: [...]} (each repeats with its
#: last time as the period), "duration_s" (<= 86400), optionally "ambient_C" (default: the
#: estimator's), "dt_s", "sample_rate_Hz", "record_every_s", "quantities" [names]}. The answer,
#: with the request's "id": {"id", "ok", "error" (null, or why it did not run), "source",
#: "start_stamp_s" (sample time of the state it starts from), "duty", "duration_s", "dt_s",
#: "ambient_C", "stopped" (null, or why it ended early), "wall_s", "time_s": [...] (from the
#: start; the first point is the start state), "temperatures_C": {name: [...]}, "peaks_C",
#: "peak_time_s", "limits_C", "time_to_limit_s": {limited quantity: s, or null: not within}}
WHATIF_REQUEST_TOPIC = f'{PREFIX}/whatif/request'
WHATIF_RESPONSE_TOPIC = f'{PREFIX}/whatif/response'
DIAGNOSTICS_TOPIC = '/diagnostics'
#: ros2_control's joint_state_broadcaster publishes here (sensor_msgs/JointState): the
#: recorder records it whatever the inputs file says
JOINT_STATES_TOPIC = '/joint_states'
#: A node's ``hardware_id`` at the root namespace; in a namespace the namespace follows it
#: (:func:`hardware_id`)
HARDWARE_ID = 'wet-eha-rig'


def namespace_prefix(namespace: str = '/') -> str:
    """
    Return the topics' prefix of a node in ``namespace`` with ``topic_prefix`` '' (root: /eha).

    >>> namespace_prefix('/left/')
    '/left'
    >>> namespace_prefix('/')
    '/eha'
    """
    return PREFIX if namespace.strip('/') == '' else '/' + namespace.strip('/')


def hardware_id(namespace: str = '/') -> str:
    """
    Return the default ``hardware_id`` of a node in ``namespace``: one per actuator.

    Two actuators started as ``-r __ns:=/left`` and ``-r __ns:=/right`` report
    ``wet-eha-rig/left`` and ``wet-eha-rig/right`` without a parameter; a node
    at the root keeps ``wet-eha-rig``. An explicit ``hardware_id`` parameter wins.

    >>> hardware_id('/left')
    'wet-eha-rig/left'
    >>> hardware_id('/')
    'wet-eha-rig'
    """
    return HARDWARE_ID + namespace.rstrip('/')


def status_name(what: str, node: str, namespace: str = '/') -> str:
    """
    Return the diagnostic status name ``<namespace>/<node>: what``, without the leading /.

    Every node publishes on the one /diagnostics, so a status names the node
    that reports it by its full name (diagnostic_updater's ``node: task`` with
    the namespace in front): two actuators' estimators started in namespaces
    /left and /right report ``left/eha_thermal_estimator: estimate`` and
    ``right/eha_thermal_estimator: estimate``, apart in an aggregator; at the
    root it is ``eha_thermal_estimator: estimate``.

    >>> status_name('estimate', 'eha_thermal_estimator', '/left')
    'left/eha_thermal_estimator: estimate'
    >>> status_name('rig', 'eha_sim_rig')
    'eha_sim_rig: rig'
    """
    return f'{namespace.strip("/")}/{node}: {what}'.lstrip('/')


#: Splits of ``live``'s recording (``--max-bag-duration``, ``--max-bag-size``): a new file
#: every 10 minutes or 1 GiB, whichever comes first. A file is strictly readable (the mcap
#: library, rosbags, ros2 bag) once closed with its summary: a crash or a full disk leaves at
#: most the one being written without it (our reader still recovers it to its last second),
#: and the writer's indexes, which grow with a file, are dropped at each split. At the twin's
#: 850 MiB an hour a file is about 140 MiB.
LIVE_SPLIT_DURATION_S = 600.0
LIVE_SPLIT_BYTES = 2 ** 30
ESTIMATES = ('winding_mean', 'winding_hotspot', 'end_winding_hotspot', 'frame', 'magnet',
             'airgap_oil_outlet', 'motor_oil_outlet', 'pump_case', 'pump_outlet', 'chamber_a',
             'chamber_b', 'accumulator', 'oil')
#: the topic of each estimate, in the order of ESTIMATES
ESTIMATE_TOPICS = tuple(f'{ESTIMATE_PREFIX}/{name}' for name in ESTIMATES)
#: The estimator's outputs, the topics of its publishers (besides the state's names, the
#: ready message and /diagnostics); :func:`volatile_outputs` are those a late subscriber misses
ESTIMATOR_OUTPUTS = ESTIMATE_TOPICS + (
    STATE_TOPIC, ALERT_TOPIC, CURRENT_LIMITS_TOPIC, CURRENT_LIMIT_TOPIC, DRIVE_LIMITS_TOPIC,
    DRIVE_ALERTS_TOPIC)
#: thermocouples of the reference rig (docs/model.md) and the estimate each one measures
#: (an output of :mod:`wet_eha_thermal.model.quantities`)
THERMOCOUPLES = {'winding': 'winding_mean', 'frame': 'frame', 'pump_inlet': 'pump_outlet',
                 'pump_case': 'pump_case', 'chamber_a': 'chamber_a', 'chamber_b': 'chamber_b',
                 'motor_oil_outlet': 'motor_oil_outlet'}


#: QoS kinds of the topics (:func:`topic_table`): ``sensor`` the nodes' ``qos`` parameter
#: (sensor_data, best effort, or reliable), ``output`` reliable and volatile, ``latched``
#: reliable and transient local, the last message kept. ``ros.topics.qos_profile`` makes
#: the rclpy profile of a kind, ``bag.rosbag2.offered_profiles`` what a bag stores of it.
SENSOR, OUTPUT, LATCHED = 'sensor', 'output', 'latched'


def topic_table(prefix: str = PREFIX) -> Dict[str, Tuple[str, str]]:
    """Return the twin's topics under ``prefix``: topic -> (message type, QoS kind)."""
    found = {INPUT_TOPICS[name]: (INPUT_TYPES[name], SENSOR) for name in INPUT_TOPICS}
    found[AMBIENT_TOPIC] = (TEMPERATURE, SENSOR)
    for tc in THERMOCOUPLES:
        found[f'{MEASURED_PREFIX}/{tc}'] = (TEMPERATURE, SENSOR)
    for topic in ESTIMATE_TOPICS:
        found[topic] = (TEMPERATURE, OUTPUT)
    found[STATE_TOPIC] = (FLOAT64_ARRAY, OUTPUT)
    found[STATE_NAMES_TOPIC] = (STRING, LATCHED)
    found[ALERT_TOPIC] = (STRING, LATCHED)
    found[CURRENT_LIMITS_TOPIC] = (JOINT_STATE, OUTPUT)
    found[CURRENT_LIMIT_TOPIC] = (FLOAT64, OUTPUT)
    found[DRIVE_LIMITS_TOPIC] = (FLOAT64_ARRAY, OUTPUT)
    found[DRIVE_ALERTS_TOPIC] = (FLOAT64_ARRAY, LATCHED)
    found[READY_TOPIC] = (STRING, LATCHED)
    found[RECORDER_HEALTH_TOPIC] = (STRING, LATCHED)
    found[ACK_TOPIC] = (STRING, OUTPUT)
    found[DIAGNOSTICS_TOPIC] = (DIAGNOSTIC_ARRAY, OUTPUT)
    return {prefixed(topic, prefix): spec for topic, spec in found.items()}


def volatile_outputs(prefix: str = PREFIX) -> Tuple[str, ...]:
    """
    Return the estimator's volatile outputs under ``prefix`` (reliable, nothing kept).

    A subscriber gets their messages only from the moment it has matched the
    estimator's publisher: a recorder that must hold every tick of them
    waits until it has matched them all.

    >>> volatile_outputs('/left')[-1]
    '/left/drive/limits'
    """
    table = topic_table(prefix)
    return tuple(t for t in (prefixed(t, prefix) for t in ESTIMATOR_OUTPUTS)
                 if table[t][1] == OUTPUT)


def prefixed(topic: str, prefix: str) -> str:
    """
    Return ``topic`` moved under ``prefix`` when it is under ``/eha``; any other as it is.

    >>> prefixed('/eha/current', '/left'), prefixed('/eha_rig/current', '/left')
    ('/left/current', '/eha_rig/current')
    """
    if topic != PREFIX and not topic.startswith(PREFIX + '/'):
        return topic
    return prefix.rstrip('/') + topic[len(PREFIX):]


class LimitStatus(enum.IntEnum):
    """
    The status of the drive's limits as a number (:class:`DriveLimits`): 0 is trusted.

    Any other code is a fallback: every limit is at most the conservative
    ``estimator.limits.fallback_current_A``. A code this version does not
    know (a newer estimator's) is a fallback as well.
    """

    OK = 0              #: computed from a trusted estimate
    STALE_INPUTS = 1    #: an input is stale: the model runs on its fallback value
    UNCERTAIN = 2       #: a limited temperature is more uncertain than limits.max_sigma_K
    BEHIND = 3          #: the estimator is behind its inputs, or had no time to compute them
    FAILED = 4          #: the computation failed
    OTHER = 5           #: another fallback (the text of CURRENT_LIMITS_TOPIC says which)
    STOPPED = 6         #: the estimator stopped publishing limits (deactivated): none follow


#: the words that name each fallback's cause in the limits' text (OTHER's detail says it all)
_FALLBACK_CAUSES = {LimitStatus.STALE_INPUTS: 'stale inputs', LimitStatus.UNCERTAIN: 'uncertain',
                    LimitStatus.BEHIND: 'behind', LimitStatus.FAILED: 'failed',
                    LimitStatus.STOPPED: 'stopped'}


def limits_cause(code: LimitStatus) -> str:
    """Return the words of a status's cause: ``stale inputs``, ``behind``...; ``ok``, ``other``."""
    return 'ok' if code == LimitStatus.OK else _FALLBACK_CAUSES.get(code, 'other')


def limits_reason(code: LimitStatus, detail: str) -> str:
    """
    Return why limits of status ``code`` fell back, in words: the cause, then ``detail``.

    The text is made from the code, never the other way round; '' for OK.

    >>> limits_reason(LimitStatus.STALE_INPUTS, 'speed_rad_s')
    'stale inputs: speed_rad_s'
    """
    if code == LimitStatus.OK:
        return ''
    return f'{_FALLBACK_CAUSES[code]}: {detail}' if code in _FALLBACK_CAUSES else detail


def limits_frame_id(code: LimitStatus, detail: str) -> str:
    """Return the header.frame_id of the limits on CURRENT_LIMITS_TOPIC: ok, fallback: <why>."""
    return 'ok' if code == LimitStatus.OK else f'fallback: {limits_reason(code, detail)}'


def _check_head(data: Sequence[float], what: str, version: int, head: int) -> None:
    """Raise ValueError unless ``data`` has ``head`` numbers or more, the first ``version``."""
    if len(data) < head or data[0] != version:
        raise ValueError(f'not {what} v{version}: {len(data)} numbers, version '
                         f'{data[0] if len(data) else None}')


def _stamp_ns(data: Sequence[float]) -> int:
    """Return the stamp (ns) of a drive message's ``data`` (its numbers 1 and 2: sec, nanosec)."""
    return int(data[1]) * 1_000_000_000 + int(data[2])


@dataclass(frozen=True)
class DriveLimits:
    """
    The limits of one tick on DRIVE_LIMITS_TOPIC: numbers at fixed places, no text.

    The Float64MultiArray's ``data`` (every number a float64; the counts and
    codes are whole numbers, exact up to 2^53)::

        [0] layout version (1)      [4] status (:class:`LimitStatus`, 0 = OK)
        [1] stamp sec               [5] binding limit (A RMS): what a drive with
        [2] stamp nanosec               one number applies
        [3] sequence                [6] its horizon (s)
                                    [7] n: the number of limits that follow
        [8 + 2 i] horizon i (s; +inf: the continuous limit)
        [9 + 2 i] limit i (A RMS, >= 0; +inf: none within that horizon)

    The stamp is the sample time the limits belong to (as the header of
    CURRENT_LIMITS_TOPIC); the sequence counts the estimator's limit
    messages from 1: a gap is a lost message, a smaller one a restarted
    estimator. A drive needs the first 7 numbers only; it falls back on its
    own when the stamp is too old. ``layout.dim[0].label`` names the fields.
    """

    stamp_ns: int
    sequence: int
    status: LimitStatus
    binding_A: float
    binding_horizon_s: float
    horizons_s: Sequence[float]
    limits_A: Sequence[float]

    VERSION = 1
    HEAD = 8
    LABEL = ('wet_eha_thermal drive limits v1: version, stamp_sec, stamp_nanosec, sequence, '
             'status, binding_A, binding_horizon_s, n, then n x (horizon_s, limit_A)')

    def to_data(self) -> list:
        """Return the message's ``data``."""
        sec, nanosec = divmod(int(self.stamp_ns), 1_000_000_000)
        out = [float(self.VERSION), float(sec), float(nanosec), float(self.sequence),
               float(int(self.status)), float(self.binding_A), float(self.binding_horizon_s),
               float(len(self.limits_A))]
        for h, a in zip(self.horizons_s, self.limits_A):
            out += [float(h), float(a)]
        return out

    @classmethod
    def from_data(cls, data: Sequence[float]) -> 'DriveLimits':
        """Return the limits of a message's ``data``; ValueError if they are malformed."""
        _check_head(data, 'drive limits', cls.VERSION, cls.HEAD)
        n = int(data[7])
        if n != data[7] or len(data) != cls.HEAD + 2 * n:
            raise ValueError(f'drive limits: n = {data[7]} for {len(data)} numbers')
        limits = tuple(data[cls.HEAD + 1::2])
        if not all(a >= 0.0 for a in limits + (data[5],)):     # NaN fails too
            raise ValueError('drive limits: a limit is negative or NaN')
        try:
            status = LimitStatus(int(data[4]))
        except ValueError:
            status = LimitStatus.OTHER
        return cls(stamp_ns=_stamp_ns(data), sequence=int(data[3]), status=status,
                   binding_A=float(data[5]), binding_horizon_s=float(data[6]),
                   horizons_s=tuple(data[cls.HEAD::2]), limits_A=limits)


@dataclass(frozen=True)
class QuantityAlert:
    """
    One monitored quantity's alert in :class:`DriveAlerts`.

    ``quantity``: its name (on the wire its index in :data:`ESTIMATES`);
    ``reported``: the level a drive acts on, 0 OK, 1 WARN, 2 CRITICAL (the
    alarm), the latch included; ``active``: the level the estimate holds
    now; ``acknowledged``: an operator acknowledged it (the level stays
    reported while its condition holds); ``value_C``: the estimate the
    alerts last judged (NaN before any); ``warn_C``, ``critical_C``: its
    thresholds; ``since_s``: sample time of the last change of ``reported``
    (NaN before any estimate).
    """

    quantity: str
    reported: int
    active: int
    acknowledged: bool
    value_C: float
    warn_C: float
    critical_C: float
    since_s: float


@dataclass(frozen=True)
class DriveAlerts:
    """
    The alerts' state on DRIVE_ALERTS_TOPIC: numbers at fixed places, no text.

    The Float64MultiArray's ``data`` (every number a float64; codes and
    counts are whole numbers)::

        [0] layout version (1)      [4] worst reported level (0 OK, 1 WARN, 2 CRITICAL)
        [1] stamp sec               [5] n: the number of quantities that follow
        [2] stamp nanosec           [6] m: the numbers per quantity (8)
        [3] sequence
        [7 + m i + 0] quantity: its index in ESTIMATES (1 winding_hotspot, 4 magnet, 12 oil)
        [7 + m i + 1] reported level    [7 + m i + 5] warn threshold (degC)
        [7 + m i + 2] active level      [7 + m i + 6] critical threshold (degC)
        [7 + m i + 3] acknowledged 0/1  [7 + m i + 7] since: sample time of the last
        [7 + m i + 4] value (degC)                     change of the reported level (s)

    The stamp is the sample time of the estimate the alerts last judged (0
    before any); the sequence counts the estimator's alert messages from 1
    (the first is sent at start). A reader finds quantity i at 7 + m i,
    taking m from the message, so a later version may append numbers to a
    quantity without moving the ones above. ``layout.dim[0].label`` names
    the fields.
    """

    stamp_ns: int
    sequence: int
    level: int
    quantities: Sequence[QuantityAlert]

    VERSION = 1
    HEAD = 7
    STRIDE = 8
    LABEL = ('wet_eha_thermal drive alerts v1: version, stamp_sec, stamp_nanosec, sequence, '
             'level, n, m, then n x (quantity index in ESTIMATES, reported, active, '
             'acknowledged, value_C, warn_C, critical_C, since_s)')

    def to_data(self) -> list:
        """Return the message's ``data``."""
        sec, nanosec = divmod(int(self.stamp_ns), 1_000_000_000)
        out = [float(self.VERSION), float(sec), float(nanosec), float(self.sequence),
               float(self.level), float(len(self.quantities)), float(self.STRIDE)]
        for q in self.quantities:
            out += [float(ESTIMATES.index(q.quantity)), float(q.reported), float(q.active),
                    float(bool(q.acknowledged)), float(q.value_C), float(q.warn_C),
                    float(q.critical_C), float(q.since_s)]
        return out

    @classmethod
    def from_data(cls, data: Sequence[float]) -> 'DriveAlerts':
        """Return the alerts of a message's ``data``; ValueError if they are malformed."""
        _check_head(data, 'drive alerts', cls.VERSION, cls.HEAD)
        n, m = int(data[5]), int(data[6])
        if n != data[5] or m != data[6] or m < cls.STRIDE or len(data) != cls.HEAD + n * m:
            raise ValueError(f'drive alerts: n = {data[5]}, m = {data[6]} for {len(data)} '
                             'numbers')
        quantities = []
        for i in range(n):
            q = data[cls.HEAD + m * i:cls.HEAD + m * i + cls.STRIDE]
            index = int(q[0])
            if index != q[0] or not 0 <= index < len(ESTIMATES):
                raise ValueError(f'drive alerts: quantity index {q[0]} not in ESTIMATES')
            quantities.append(QuantityAlert(ESTIMATES[index], int(q[1]), int(q[2]), q[3] != 0.0,
                                            *(float(v) for v in q[4:8])))
        return cls(stamp_ns=_stamp_ns(data), sequence=int(data[3]), level=int(data[4]),
                   quantities=tuple(quantities))


#: The line of a node's :class:`NodeReport` starts with this, then its JSON.
REPORT_PREFIX = 'wet_eha_thermal node report: '
#: Version of the report's fields: a reader refuses any other.
REPORT_SCHEMA = 'wet_eha_thermal.node_report/1'


@dataclass(frozen=True)
class InputCounts:
    """One input's samples over a run of the estimator (its diagnostics' counters)."""

    received: int
    accepted: int
    rejected: int
    stale_events: int


@dataclass(frozen=True)
class NodeReport:
    """
    A node's counts at the end of its run, as data: what ``live`` summarises.

    The node writes it as its last line on stdout (:meth:`write`): ``live``
    sends its children SIGINT and reads their output after they exited, and
    a line flushed to the log file outlives the process, where a message on
    a topic during the shutdown of both ends may never arrive.

    ``samples_published``: the simulated rig's samples per input topic;
    ``inputs``: the estimator's counts per input; ``figures``: the rest, each
    name ending in its unit (``_s``, ``_ms``, ``_percent``) or naming a count
    (NaN where there is no figure, written as null).
    """

    node: str
    samples_published: Optional[int] = None
    inputs: Dict[str, InputCounts] = field(default_factory=dict)
    figures: Dict[str, float] = field(default_factory=dict)
    schema: str = REPORT_SCHEMA

    def to_json(self) -> str:
        """Return the report as one line of strict JSON."""
        data = asdict(self)
        data['figures'] = {k: v if math.isfinite(v) else None for k, v in self.figures.items()}
        return json.dumps(data, allow_nan=False)

    @classmethod
    def from_json(cls, text: str) -> 'NodeReport':
        """Return the report in ``text``; ValueError if it is not one of this schema."""
        try:
            data = json.loads(text)
            if data.get('schema') != REPORT_SCHEMA:
                raise ValueError(f'schema {data.get("schema")!r}, expected {REPORT_SCHEMA!r}')
            published = data['samples_published']
            return cls(node=str(data['node']),
                       samples_published=None if published is None else int(published),
                       inputs={str(k): InputCounts(**{f: int(n) for f, n in v.items()})
                               for k, v in data['inputs'].items()},
                       figures={str(k): math.nan if v is None else float(v)
                                for k, v in data['figures'].items()})
        except (AttributeError, KeyError, TypeError) as exc:
            raise ValueError(f'not a node report: {exc!r}') from None

    def write(self, stream: TextIO) -> None:
        """Put the report's line on ``stream`` as one piece (logs may share it), and flush."""
        stream.write(REPORT_PREFIX + self.to_json() + '\n')
        stream.flush()

    @classmethod
    def find(cls, lines: Iterable[str]) -> Optional['NodeReport']:
        """Return the last report among ``lines`` (None when there is none or it is bad)."""
        found = [ln[len(REPORT_PREFIX):] for ln in lines if ln.startswith(REPORT_PREFIX)]
        try:
            return cls.from_json(found[-1]) if found else None
        except ValueError:
            return None
