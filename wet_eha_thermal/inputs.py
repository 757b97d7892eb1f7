"""
The estimator's inputs by configuration: topic, message type, field and unit of each.

A rig connects by declaring, per input (``current_A``, ``speed_rad_s``,
``p_a_Pa``, ``p_b_Pa``, ``p_acc_Pa``, ``dp_Pa``, ``position_m``), where its
samples are and in what unit, in the manner of robot_localization's per-sensor
blocks: a YAML file with one ``inputs:`` mapping, loaded into :class:`Inputs`
and checked before the node subscribes (one :class:`~.config.ConfigError`
naming the key). An input left out keeps its default, today's topic of
:mod:`.interface`; with no file at all the estimator listens as it always did.
The same blocks declare the ``ambient`` temperature and, under
``thermocouples:``, each thermocouple of the live correction by its name in
:data:`.interface.THERMOCOUPLES` (a temperature in K, degC or degF; by
default a ``sensor_msgs/Temperature`` in degC on today's topic).

Per input (:class:`InputSignal`):

- ``topic`` and ``message_type``: ``std_msgs/msg/Float64`` (no stamp: the sample is
  stamped on arrival with the receiving node's ROS clock),
  ``sensor_msgs/msg/FluidPressure`` or ``sensor_msgs/msg/Temperature`` (the
  header's stamp; its first float64), ``sensor_msgs/msg/JointState`` (the
  header's stamp; ``field`` position, velocity or effort of the joint named
  ``joint``: what ros2_control's joint_state_broadcaster publishes), or the
  batched form ``std_msgs/msg/Float64MultiArray`` (below). Inputs may share a
  topic (one /joint_states carries speed, current and position): it is
  subscribed once and decoded once per message.
- ``unit`` (a name of :data:`.units.BY_NAME`: A, A_peak, mA, rad/s, r/min,
  deg/s, Pa, kPa, MPa, bar, psi, m, mm, K, degC, degF), ``scale``, ``offset``
  and ``sign``:
  the SI value the estimator takes is ``(sign * scale * raw + offset)``
  expressed in ``unit``, converted to SI. A gauge pressure sensor in bar takes
  ``offset: 1.01325`` (the estimator's pressures are absolute).

**Batched form** (a DAQ's block of samples in one message), a
``std_msgs/Float64MultiArray``::

    layout.data_offset = 2          (at least 2)
    data[0] = t0_s                  sample time of the first sample (s, ROS time)
    data[1] = dt_s                  sample period (s, > 0)
    data[data_offset + k * columns + c]    sample k of column c

so sample ``k`` is stamped ``t0_s + k * dt_s`` and a block of ``n`` samples
of ``columns`` signals holds ``data_offset + n * columns`` numbers
(``layout.dim`` is free: ``[samples n, columns]`` is the natural choice and
is what :func:`encode_batch` writes). Each input names its ``column`` and the
block's ``columns``. A float64 ``t0_s`` resolves about 0.24 us at today's
epoch seconds: fine for sample periods of microseconds and more.

The decoding reads the CDR bytes (:mod:`.bag.cdr`'s layouts, either byte
order) without building a message: one ``struct`` read per value of a
per-message type, one numpy view per batched block. No ROS import here: the
node subscribes raw and hands each message's bytes to a :class:`TopicDecoder`.
"""

from dataclasses import dataclass, fields
import math
import os
from pathlib import Path
import struct
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np
import yaml

from . import interface, units
from .bag import cdr
from .config_spec import ConfigError, from_dict, spec

FLOAT64, FLUID_PRESSURE, TEMPERATURE, JOINT_STATE, BATCH = (
    interface.FLOAT64, interface.FLUID_PRESSURE, interface.TEMPERATURE, interface.JOINT_STATE,
    interface.FLOAT64_ARRAY)
#: Message types an input may come in; BATCH carries many samples per message.
TYPES = (FLOAT64, FLUID_PRESSURE, TEMPERATURE, JOINT_STATE, BATCH)
#: The fields of a JointState an input may read.
JOINT_FIELDS = ('position', 'velocity', 'effort')
#: The SI unit of each input (what the estimator takes).
SI_UNIT = {'current_A': 'A', 'speed_rad_s': 'rad/s', 'p_a_Pa': 'Pa', 'p_b_Pa': 'Pa',
           'p_acc_Pa': 'Pa', 'dp_Pa': 'Pa', 'position_m': 'm', 'ambient': 'K'}
#: The channel of the ambient temperature (taken in degC by the session).
AMBIENT = 'ambient'


def thermocouple_channel(tc: str) -> str:
    """Return the channel of thermocouple ``tc``: its topic's name under /eha (``measured/tc``)."""
    return f'{interface.MEASURED_PREFIX}/{tc}'


#: The fewest leading numbers of a batched block: t0_s and dt_s.
BATCH_HEAD = 2


@dataclass(frozen=True, kw_only=True)
class InputSignal:
    """Where one input's samples are, and how they convert to the estimator's SI value."""

    topic: str = spec(doc=(
        "topic name; one under /eha moves with the node's topic_prefix"))
    message_type: str = spec(choices=TYPES, doc='pkg/msg/Type')
    joint: str = spec(default='', doc='JointState: the name of the joint to read')
    field: str = spec(default='', doc='JointState: position, velocity or effort')
    column: int = spec(0, 1000, default=0, doc="Float64MultiArray: this signal's column")
    columns: int = spec(1, 1000, default=1, doc='Float64MultiArray: signals per sample')
    unit: str = spec(choices=tuple(units.BY_NAME), doc=(
        "unit of sign * scale * raw + offset; converted to the input's SI unit"))
    scale: float = spec(default=1.0, doc='multiplies the raw value (before the unit)')
    offset: float = spec(default=0.0, doc=(
        'added after scale and sign, in unit (a gauge pressure in bar: 1.01325)'))
    sign: int = spec(-1, 1, default=1, doc='1 or -1: flips the direction (speed, position)')

    def check(self, key: str) -> None:
        """Check the type's own keys: joint and field of a JointState, column of a block."""
        if not self.topic:
            raise ConfigError(f'{key}.topic: empty; give the topic name')
        if self.sign not in (-1, 1):
            raise ConfigError(f'{key}.sign = {self.sign!r}: expected 1 or -1')
        if self.scale == 0.0:
            raise ConfigError(f'{key}.scale = 0.0: would read every sample as the offset')
        if self.message_type == JOINT_STATE:
            if not self.joint:
                raise ConfigError(f'{key}.joint: missing; a {JOINT_STATE} input names its joint')
            if self.field not in JOINT_FIELDS:
                raise ConfigError(f'{key}.field = {self.field!r}: a {JOINT_STATE} input reads '
                                  f'one of {", ".join(JOINT_FIELDS)}')
        elif self.joint or self.field:
            raise ConfigError(f'{key}: joint and field are for {JOINT_STATE} only, not '
                              f'{self.message_type}')
        if self.message_type == BATCH:
            if self.column >= self.columns:
                raise ConfigError(f'{key}.column = {self.column}: must be below {key}.columns = '
                                  f'{self.columns}')
        elif self.column or self.columns != 1:
            raise ConfigError(f'{key}: column and columns are for {BATCH} only, not '
                              f'{self.message_type}')

    def to_si(self) -> Tuple[float, float]:
        """Return (gain, bias): the estimator's value is ``gain * raw + bias`` (SI)."""
        factor = units.BY_NAME[self.unit][1]
        return self.sign * self.scale * factor, \
            (self.offset + units.ZERO.get(self.unit, 0.0)) * factor


def _default(name: str) -> InputSignal:
    """Return today's input ``name``: its interface topic, Float64 or FluidPressure, SI."""
    return InputSignal(topic=interface.INPUT_TOPICS[name],
                       message_type=interface.INPUT_TYPES[name], unit=SI_UNIT[name])


def _temperature(topic: str) -> InputSignal:
    """Return today's temperature on ``topic``: a sensor_msgs/Temperature in degC."""
    return InputSignal(topic=topic, message_type=TEMPERATURE, unit='degC')


def _default_field(name: str, doc: str):
    return spec(default_factory=lambda: _default(name), doc=doc)


@dataclass(frozen=True, kw_only=True)
class Inputs:
    """
    Every input of the estimator, declared per signal; each defaults to today's topic.

    Those the configuration does not use (the three absolute pressures with a
    differential sensor, or ``dp_Pa`` without) are checked but not subscribed.
    """

    current_A: InputSignal = _default_field('current_A', 'motor phase current (A RMS)')
    speed_rad_s: InputSignal = _default_field('speed_rad_s', 'motor shaft speed (rad/s)')
    p_a_Pa: InputSignal = _default_field('p_a_Pa', 'port A pressure, absolute (Pa)')
    p_b_Pa: InputSignal = _default_field('p_b_Pa', 'port B pressure, absolute (Pa)')
    p_acc_Pa: InputSignal = _default_field('p_acc_Pa', 'accumulator pressure, absolute (Pa)')
    dp_Pa: InputSignal = _default_field('dp_Pa', 'port A minus port B (Pa)')
    position_m: InputSignal = _default_field('position_m', 'rod position (m)')
    ambient: InputSignal = spec(
        default_factory=lambda: _temperature(interface.AMBIENT_TOPIC),
        doc="the air around the actuator: the housings' heat loss (default: the model's)")
    thermocouples: Dict[str, InputSignal] = spec(default_factory=dict, doc=(
        "the live correction's thermocouples by name (" + ', '.join(interface.THERMOCOUPLES)
        + '); one left out is a sensor_msgs/Temperature in degC on /eha/measured/<name>'))

    def signal(self, channel: str) -> InputSignal:
        """Return the signal of ``channel``: an input, ``ambient`` or a thermocouple's."""
        prefix = thermocouple_channel('')
        if channel.startswith(prefix):
            tc = channel[len(prefix):]
            return self.thermocouples.get(tc) or _temperature(channel)
        return getattr(self, channel)

    def check(self, key: str) -> None:
        """Check each unit is of its input's quantity, and each thermocouple's name."""
        unknown = sorted(set(self.thermocouples) - set(interface.THERMOCOUPLES))
        if unknown:
            raise ConfigError(f'{key}.thermocouples: unknown {", ".join(unknown)}; allowed: '
                              f'{", ".join(interface.THERMOCOUPLES)}')
        named = [(f.name, getattr(self, f.name), SI_UNIT[f.name])
                 for f in fields(self) if f.name != 'thermocouples']
        named += [(f'thermocouples.{tc}', sig, 'K') for tc, sig in self.thermocouples.items()]
        for name, sig, si_unit in named:
            if units.BY_NAME[sig.unit][0] != si_unit:
                allowed = [u for u, (s, _) in units.BY_NAME.items() if s == si_unit]
                raise ConfigError(f'{key}.{name}.unit = {sig.unit!r}: not a unit of '
                                  f'{si_unit}; allowed: {", ".join(allowed)}')


def inputs_from_yaml(text: str, origin: str = 'inputs') -> Inputs:
    """Return the :class:`Inputs` of YAML ``text`` holding one ``inputs:`` mapping."""
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f'{origin}: not valid YAML: {exc}') from exc
    if not isinstance(data, dict) or set(data) != {'inputs'}:
        raise ConfigError(f'{origin}: expected one top-level key, inputs:')
    try:
        return from_dict(Inputs, data['inputs'] or {}, 'inputs')
    except ConfigError as exc:
        raise ConfigError(f'{origin}: {exc}') from None


def inputs_path(name: str) -> Path:
    """Return the inputs file ``name``: as given, or else in the shipped config folder."""
    from .config import config_dir        # the config folder's search, in one place
    path = Path(os.path.expanduser(name))
    if path.is_absolute() or path.is_file():
        return path
    shipped = config_dir() / path
    return shipped if shipped.is_file() else path


def load_inputs(name: Optional[str]) -> Inputs:
    """Return the inputs of file ``name`` (see :func:`inputs_path`); today's for None or ''."""
    if not name:
        return Inputs()
    path = inputs_path(name)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(f'inputs_file {name!r}: cannot read {path}: {exc.strerror}') from None
    return inputs_from_yaml(text, str(path))


# ------------------------------------------------------------------ decoding
_ORDER = {b'\x00\x00': '>', b'\x00\x01': '<'}     # plain CDR, big- and little-endian


def _reader(data) -> '_Reader':
    """Return the reader of the byte order of ``data`` (little-endian first: the usual)."""
    if data[1] == 1 and data[0] == 0:
        return _LITTLE
    try:
        return _READERS[_ORDER[bytes(data[:2])]]
    except KeyError:
        raise ValueError(f'CDR encapsulation {bytes(data[:2]).hex()}: only plain CDR '
                         '(0000, 0001) is read') from None


class _Reader:
    """The struct formats of one byte order."""

    def __init__(self, order: str) -> None:
        self.u32 = struct.Struct(order + 'I')
        self.f64 = struct.Struct(order + 'd')
        self.stamp = struct.Struct(order + 'iI')
        self.dtype = np.dtype(order + 'f8')


_READERS = {order: _Reader(order) for order in _ORDER.values()}
_LITTLE = _READERS['<']
_HEAD = cdr.ENCAPSULATION_BYTES


def _align(pos: int, size: int) -> int:
    """Return ``pos`` (from the start of the bytes) aligned to ``size`` past the header."""
    return pos + (-(pos - _HEAD) % size)


class TopicDecoder:
    """
    Decode one topic's messages into the samples of the inputs it carries.

    ``channels``: the inputs read from this topic, in order. A per-message
    type gives :meth:`decode`: (header stamp in ns, 0 for a Float64, which
    the node stamps on arrival; one SI value per channel). The batched type
    gives :meth:`decode_batch`: (stamps in s, one row of SI values per
    sample, a column per channel).
    """

    def __init__(self, topic: str, signals: Sequence[Tuple[str, InputSignal]]) -> None:
        self.topic = topic
        types = {s.message_type for _, s in signals}
        if len(types) != 1:
            names = ', '.join(f'{n} ({s.message_type})' for n, s in signals)
            raise ConfigError(f'inputs: topic {topic} is declared with different types: {names}')
        self.message_type = types.pop()
        self.batched = self.message_type == BATCH
        self.channels = tuple(n for n, _ in signals)
        gain_bias = [s.to_si() for _, s in signals]
        self.gain = np.array([g for g, _ in gain_bias])
        self.bias = np.array([b for _, b in gain_bias])
        self._affine = tuple(gain_bias)
        if self.batched:
            widths = {s.columns for _, s in signals}
            if len(widths) != 1:
                raise ConfigError(f'inputs: topic {topic}: its inputs give different columns')
            self.columns = widths.pop()
            self.column = [s.column for _, s in signals]
        self.joints = [(s.joint, JOINT_FIELDS.index(s.field)) for _, s in signals] \
            if self.message_type == JOINT_STATE else []
        self._names_cache: Optional[tuple] = None
        self.decode = {FLOAT64: self._float64, FLUID_PRESSURE: self._header_first,
                       TEMPERATURE: self._header_first, JOINT_STATE: self._joint_state,
                       BATCH: self._not_per_message}[self.message_type]

    def _convert(self, raw: Sequence[float]) -> List[float]:
        return [g * r + b for (g, b), r in zip(self._affine, raw)]

    def _float64(self, data) -> Tuple[int, List[float]]:
        value = _reader(data).f64.unpack_from(data, _HEAD)[0]
        return 0, [g * value + b for g, b in self._affine]

    def _header_first(self, data) -> Tuple[int, List[float]]:
        r = _reader(data)
        sec, nanosec = r.stamp.unpack_from(data, _HEAD + cdr.STAMP_SEC_AT)
        length = r.u32.unpack_from(data, _HEAD + cdr.FRAME_ID_LENGTH_AT)[0]
        value = r.f64.unpack_from(data, _HEAD + cdr.first_after_header(length))[0]
        return sec * 1_000_000_000 + nanosec, [g * value + b for g, b in self._affine]

    def _joint_state(self, data) -> Tuple[int, List[float]]:
        r = _reader(data)
        sec, nanosec = r.stamp.unpack_from(data, _HEAD + cdr.STAMP_SEC_AT)
        length = r.u32.unpack_from(data, _HEAD + cdr.FRAME_ID_LENGTH_AT)[0]
        start = _align(_HEAD + cdr.FRAME_ID_AT + length, 4)
        # the names rarely change: compare their bytes with the last message's
        cache = self._names_cache
        if cache is not None and cache[0] == start and data[start:cache[1]] == cache[2]:
            end, index = cache[1], cache[3]
        else:
            end, index = self._joint_names(data, r, start)
        pos = end
        arrays = []
        for _ in JOINT_FIELDS:           # position, velocity, effort: count, then float64s
            pos = _align(pos, 4)
            n = r.u32.unpack_from(data, pos)[0]
            pos += 4
            if n:
                pos = _align(pos, 8)
            arrays.append((pos, n))
            pos += 8 * n
        raw = []
        for j, f in index:
            at, n = arrays[f]
            if j >= n:
                raise ValueError(f'{self.topic}: joint {self.joints[len(raw)][0]!r} has no '
                                 f'{JOINT_FIELDS[f]} (the message gives {n} values)')
            raw.append(r.f64.unpack_from(data, at + 8 * j)[0])
        return sec * 1_000_000_000 + nanosec, self._convert(raw)

    def _joint_names(self, data, r: _Reader, start: int) -> Tuple[int, list]:
        """Read the names from ``start``; return where they end and each channel's index."""
        count = r.u32.unpack_from(data, start)[0]
        pos = start + 4
        names = []
        for _ in range(count):
            pos = _align(pos, 4)
            n = r.u32.unpack_from(data, pos)[0]
            names.append(bytes(data[pos + 4:pos + 3 + n]).decode())
            pos += 4 + n
        index = []
        for joint, f in self.joints:
            if joint not in names:
                raise ValueError(f'{self.topic}: no joint {joint!r} in the message (it has '
                                 f'{", ".join(names) or "none"})')
            index.append((names.index(joint), f))
        self._names_cache = (start, pos, bytes(data[start:pos]), index)
        return pos, index

    def _not_per_message(self, data):
        raise TypeError(f'{self.topic}: a batched topic is read with decode_batch')

    def decode_batch(self, data) -> Tuple[np.ndarray, np.ndarray]:
        """Return the stamps (s) and the SI values (one row per sample) of a batched block."""
        r = _reader(data)
        pos = _HEAD
        dims = r.u32.unpack_from(data, pos)[0]
        pos += 4
        for _ in range(dims):            # label (string), size, stride
            pos = _align(pos, 4)
            pos += 4 + r.u32.unpack_from(data, pos)[0]
            pos = _align(pos, 4) + 8
        pos = _align(pos, 4)
        data_offset, count = r.u32.unpack_from(data, pos)[0], r.u32.unpack_from(data, pos + 4)[0]
        pos += 8
        if data_offset < BATCH_HEAD or (count - data_offset) % self.columns or count < data_offset:
            raise ValueError(f'{self.topic}: not a block of {self.columns} column(s): '
                             f'data_offset {data_offset}, {count} numbers')
        if count:
            pos = _align(pos, 8)
        values = np.frombuffer(data, dtype=r.dtype, count=count, offset=pos)
        t0, dt = float(values[0]), float(values[1])
        if not (math.isfinite(t0) and math.isfinite(dt) and dt > 0.0):
            raise ValueError(f'{self.topic}: block t0_s = {t0!r}, dt_s = {dt!r}: need finite, '
                             'dt_s > 0')
        block = values[data_offset:].reshape(-1, self.columns)[:, self.column]
        stamps = t0 + dt * np.arange(block.shape[0])
        return stamps, block * self.gain + self.bias


def all_channels() -> List[str]:
    """Return every channel an inputs file declares: the inputs, the ambient, each thermocouple."""
    return [*interface.INPUT_TOPICS, AMBIENT,
            *(thermocouple_channel(tc) for tc in interface.THERMOCOUPLES)]


def topic_types(spec: Inputs) -> Dict[str, str]:
    """Return topic -> message type of every topic ``spec`` reads (what a recorder records)."""
    return {spec.signal(c).topic: spec.signal(c).message_type for c in all_channels()}


def decoders(spec: Inputs, channels: Sequence[str]) -> List[TopicDecoder]:
    """Return one decoder per topic carrying any of ``channels``, in the order first named."""
    by_topic: Dict[str, list] = {}
    for name in channels:
        sig = spec.signal(name)
        by_topic.setdefault(sig.topic, []).append((name, sig))
    return [TopicDecoder(topic, signals) for topic, signals in by_topic.items()]


def encode_batch(t0_s: float, dt_s: float, values: np.ndarray) -> bytes:
    """
    Return a batched block, serialised: a std_msgs/Float64MultiArray of the layout above.

    ``values``: one row per sample, one column per signal (1-D: one signal).
    What a DAQ node, the simulated rig or a benchmark publishes.
    """
    values = np.asarray(values, dtype='<f8')
    if values.ndim == 1:
        values = values[:, None]
    n, m = values.shape
    out = bytearray(cdr.PLAIN_LE + b'\x00\x00')
    out += struct.pack('<I', 2)
    for label, size, stride in (('samples', n, n * m), ('columns', m, m)):
        out += bytes(-(len(out) - _HEAD) % 4)
        name = label.encode()
        out += struct.pack('<I', len(name) + 1) + name + b'\x00'
        out += bytes(-(len(out) - _HEAD) % 4)
        out += struct.pack('<II', size, stride)
    out += bytes(-(len(out) - _HEAD) % 4)
    out += struct.pack('<II', BATCH_HEAD, BATCH_HEAD + n * m)
    out += bytes(-(len(out) - _HEAD) % 8)
    out += struct.pack('<dd', t0_s, dt_s) + values.tobytes()
    return bytes(out)
