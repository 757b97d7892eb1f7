"""
Numeric topics of a bag decoded chunk by chunk with numpy: the replay's speed path.

Topics of a few fixed-layout types (:data:`COLUMN_FIELDS`) are decoded for
all messages of a chunk at once instead of message by message: the
:class:`~.records.Scanner` gives the offset of every message record, and the
fields are gathered at computed offsets. The CDR data starts with a 4-byte
encapsulation header (00 01: little-endian plain CDR, what rclpy writes;
anything else is refused) and the fields follow, each aligned to its size
counted from the end of that header.
"""

from dataclasses import dataclass
import os
from pathlib import Path
import pickle
import struct
from typing import Callable, Dict, Iterator, List, Mapping, Optional, Protocol, Tuple, Union

import numpy as np

from . import cdr
from .files import join_problems, scans, total_bytes
from .records import (BagError, DATA_AT, LENGTH_AT, LOG_TIME_AT, MESSAGE_HEADER_BYTES, Scanner,
                      take, Unit)
from ..interface import FLOAT64, FLUID_PRESSURE, TEMPERATURE
from ..processes import child_context

# Fields decoded by the speed path, per type. The two header types share one layout:
# Header (stamp, frame_id), then two float64.
COLUMN_FIELDS = {
    FLOAT64: ('data',),
    FLUID_PRESSURE: ('fluid_pressure', 'variance'),
    TEMPERATURE: ('temperature', 'variance'),
}


@dataclass
class Columns:
    """
    The decoded messages of one topic, in file order.

    ``time_ns`` is the header stamp when it is non-zero, else the log time
    (for Float64, which has no header, it is the log time array itself).
    ``values`` maps field names to float64 arrays.
    """

    type_name: str
    log_time_ns: np.ndarray
    time_ns: np.ndarray
    values: Dict[str, np.ndarray]

    def __len__(self) -> int:
        return len(self.log_time_ns)


@dataclass
class ColumnData:
    """The result of :func:`read_columns`: columns per topic and how reading ended."""

    topics: Dict[str, Columns]
    message_count: int       # messages decoded, all topics
    truncated: bool
    problem: Optional[str]


def _require(ok: np.ndarray, where: str, what: str) -> None:
    if not ok.all():
        raise BagError(f'{where}: a message is too short for {what}')


def _decode(buf: np.ndarray, pos: np.ndarray, type_name: str, where: str) -> Columns:
    """Decode the messages (all of ``type_name``) whose records start at ``pos`` in ``buf``."""
    data = pos + DATA_AT
    size = take(buf, pos + LENGTH_AT, '<u8').astype(np.int64) - MESSAGE_HEADER_BYTES
    log_time_ns = take(buf, pos + LOG_TIME_AT, '<i8')
    head = cdr.ENCAPSULATION_BYTES
    _require(size >= head, where, 'a CDR encapsulation header')
    plain_le = (buf[data] == cdr.PLAIN_LE[0]) & (buf[data + 1] == cdr.PLAIN_LE[1])
    if not plain_le.all():
        k = data[np.argmin(plain_le)]
        raise BagError(f'{where}: CDR encapsulation {buf[k]:02x}{buf[k + 1]:02x}; only 0001 '
                       '(little-endian plain CDR, what rclpy writes) is decoded')
    body = data + head  # CDR alignment counts from the end of the encapsulation header
    if type_name == FLOAT64:
        _require(size >= head + 8, where, type_name)
        return Columns(type_name, log_time_ns, log_time_ns, {'data': take(buf, body, '<f8')})
    # a Header, then the two float64 (cdr.py has the layout)
    _require(size >= head + cdr.FRAME_ID_AT, where, 'a std_msgs/Header')
    sec = take(buf, body + cdr.STAMP_SEC_AT, '<i4').astype(np.int64)
    nanosec = take(buf, body + cdr.STAMP_NANOSEC_AT, '<u4')
    first = cdr.first_after_header(
        take(buf, body + cdr.FRAME_ID_LENGTH_AT, '<u4').astype(np.int64))
    _require(size >= head + first + 16, where, type_name)
    stamp_ns = sec * 1_000_000_000 + nanosec
    a, b = COLUMN_FIELDS[type_name]
    return Columns(type_name, log_time_ns, np.where(stamp_ns != 0, stamp_ns, log_time_ns),
                   {a: take(buf, body + first, '<f8'), b: take(buf, body + first + 8, '<f8')})


class MessageDecoder(Protocol):
    """
    Decodes a topic message by message, for a type the columns do not read (a JointState, ...).

    ``type_name`` is the type the bag must hold; ``fields`` the names of the
    values; ``decode`` takes the log times (ns) and the CDR bytes of a run of
    messages and returns the samples' times (ns) and each field's values:
    as many samples as messages, or more (a batched block).
    """

    type_name: str
    fields: Tuple[str, ...]

    def decode(self, log_time_ns: np.ndarray, messages: List[bytes]
               ) -> Tuple[np.ndarray, Dict[str, np.ndarray]]:
        """Return the samples' times (ns) and values of ``messages``."""


Spec = Union[str, MessageDecoder]


def _type_name(spec: Spec) -> str:
    return spec if isinstance(spec, str) else spec.type_name


def _fields(spec: Spec) -> Tuple[str, ...]:
    return COLUMN_FIELDS[spec] if isinstance(spec, str) else tuple(spec.fields)


def _check_specs(specs: Mapping[str, Spec]) -> Dict[str, Spec]:
    for topic, spec in specs.items():
        if isinstance(spec, str) and spec not in COLUMN_FIELDS:
            raise BagError(f'topic {topic}: type {spec} is not one read as columns '
                           f'({", ".join(COLUMN_FIELDS)})')
    return dict(specs)


def _decode_each(buf: np.ndarray, pos: np.ndarray, decoder: MessageDecoder,
                 where: str) -> Columns:
    """Decode the messages whose records start at ``pos`` one by one with ``decoder``."""
    size = take(buf, pos + LENGTH_AT, '<u8').astype(np.int64) - MESSAGE_HEADER_BYTES
    log_time_ns = take(buf, pos + LOG_TIME_AT, '<i8')
    starts = (pos + DATA_AT).tolist()
    messages = [buf[at:at + n].tobytes() for at, n in zip(starts, size.tolist())]
    try:
        time_ns, values = decoder.decode(log_time_ns, messages)
    except (ValueError, struct.error) as exc:
        raise BagError(f'{where}: {exc}') from exc
    return Columns(decoder.type_name, log_time_ns, time_ns, values)


class _Selection:
    """The channels carrying the requested topics, checked against the requested types."""

    def __init__(self, scan: Scanner, specs: Dict[str, Spec]):
        self._scan = scan
        self._specs = specs
        self._known = 0
        self.ids: Dict[str, List[int]] = {topic: [] for topic in specs}

    def update(self) -> None:
        channels = self._scan.channels
        if len(channels) == self._known:
            return
        self._known = len(channels)
        self.ids = {topic: [] for topic in self._specs}
        for channel in channels.values():
            spec = self._specs.get(channel.topic)
            if spec is None:
                continue
            expected = _type_name(spec)
            found = self._scan.type_name(channel)
            if found != expected or channel.message_encoding != 'cdr':
                raise BagError(f'{self._scan.path}: topic {channel.topic} is {found} '
                               f'({channel.message_encoding}), expected {expected} (cdr)')
            self.ids[channel.topic].append(channel.id)


def _decoded_units(scan: Scanner, specs: Dict[str, Spec]) -> Iterator[Tuple[Unit, dict]]:
    """Yield each unit with the columns of the requested topics found in it."""
    selection = _Selection(scan, specs)
    for unit, buf, pos, channel_ids in scan.located():
        selection.update()
        decoded = {}
        for topic, ids in selection.ids.items():
            if not ids:
                continue
            mine = channel_ids == ids[0] if len(ids) == 1 else np.isin(channel_ids, ids)
            if mine.any():
                spec, where = specs[topic], f'{scan.path}: {topic}'
                decoded[topic] = _decode(buf, pos[mine], spec, where) if isinstance(spec, str) \
                    else _decode_each(buf, pos[mine], spec, where)
        yield unit, decoded


def _empty(spec: Spec) -> Columns:
    log_time_ns = np.empty(0, np.int64)
    return Columns(_type_name(spec), log_time_ns,
                   log_time_ns if spec == FLOAT64 else np.empty(0, np.int64),
                   {name: np.empty(0) for name in _fields(spec)})


def _concatenate(spec: Spec, parts: List[Columns]) -> Columns:
    if not parts:
        return _empty(spec)
    log_time_ns = np.concatenate([p.log_time_ns for p in parts])
    return Columns(_type_name(spec), log_time_ns,
                   log_time_ns if spec == FLOAT64
                   else np.concatenate([p.time_ns for p in parts]),
                   {name: np.concatenate([p.values[name] for p in parts])
                    for name in _fields(spec)})


class ColumnBlocks:
    """
    The requested topics of a bag as consecutive blocks of columns (one pass, constant memory).

    Iterating yields dictionaries topic -> :class:`Columns` (every requested
    topic, empty when it has no message in the block), each block covering
    consecutive chunks until their messages span ``max_block_s`` of log time
    (a bag directory's files follow one another). After the iteration
    (already before the last block), ``truncated`` and ``problem`` tell
    whether and why reading ended early (a cut file; in a directory, each
    file missing, not MCAP or cut, by name), ``message_count`` how many
    messages were decoded.

    With ``prefetch`` a child process reads and decodes the next block while
    the caller works on this one: a replay's model step and the reading then
    run on two cores. The pipe between them holds about one block, so memory
    stays flat; the blocks, the attributes and the errors are the same as
    without it, and ``on_progress`` is then called once per block. The child
    is forked, or comes from the fork server when the caller runs threads
    (:mod:`~wet_eha_thermal.processes`): then ``specs`` must pickle.
    """

    def __init__(self, path: os.PathLike, specs: Mapping[str, Spec], *,
                 max_block_s: float = 10.0,
                 on_progress: Optional[Callable[[int, int], None]] = None,
                 prefetch: bool = False):
        self.path = Path(path)
        self.specs = _check_specs(specs)
        self.max_block_s = max_block_s
        self.on_progress = on_progress
        self.prefetch = prefetch
        self.message_count = 0
        self.truncated = False
        self.problem: Optional[str] = None

    def __iter__(self) -> Iterator[Dict[str, Columns]]:
        return self._prefetched() if self.prefetch else self._blocks()

    def _prefetched(self) -> Iterator[Dict[str, Columns]]:
        ctx = child_context(preload=[__name__])
        receive, send = ctx.Pipe(duplex=False)
        child = ctx.Process(target=_produce, args=(self.path, self.specs, self.max_block_s, send),
                            daemon=True, name=f'read {self.path.name}')
        child.start()
        send.close()
        try:
            while True:
                try:
                    kind, payload, state = receive.recv()
                except EOFError:
                    raise BagError(f'{self.path}: the reading process ended without a word '
                                   f'(exit code {child.exitcode})') from None
                self.message_count, self.truncated, self.problem, offset, size = state
                if self.on_progress is not None:
                    self.on_progress(offset, size)
                if kind == 'error':
                    raise payload
                if kind == 'end':
                    return
                yield payload
        finally:
            # the caller may stop early (an error in its model step, ^C): the reader goes too
            receive.close()
            child.join(timeout=5.0)
            if child.is_alive():
                child.kill()
                child.join()

    def _blocks(self) -> Iterator[Dict[str, Columns]]:
        max_block_ns = self.max_block_s * 1e9
        self.message_count = 0
        self.truncated = False
        self.problem = None
        problems: List[str] = []
        total, done = total_bytes(self.path), 0
        parts = {topic: [] for topic in self.specs}
        first_ns = last_ns = None
        for scan in scans(self.path, problems):
            for unit, decoded in _decoded_units(scan, self.specs):
                for topic, columns in decoded.items():
                    parts[topic].append(columns)
                    self.message_count += len(columns)
                    lo, hi = int(columns.log_time_ns.min()), int(columns.log_time_ns.max())
                    first_ns = lo if first_ns is None else min(first_ns, lo)
                    last_ns = hi if last_ns is None else max(last_ns, hi)
                if self.on_progress is not None:
                    self.on_progress(done + unit.file_offset, total)
                if first_ns is not None and last_ns - first_ns >= max_block_ns:
                    yield self._block(parts)
                    parts = {topic: [] for topic in self.specs}
                    first_ns = last_ns = None
            done += scan.size
        self.truncated = bool(problems)
        self.problem = join_problems(problems)
        if first_ns is not None:
            yield self._block(parts)

    def _block(self, parts: Dict[str, List[Columns]]) -> Dict[str, Columns]:
        return {topic: _concatenate(self.specs[topic], p) for topic, p in parts.items()}


def iter_column_blocks(path: os.PathLike, specs: Mapping[str, Spec], *,
                       max_block_s: float = 10.0,
                       on_progress: Optional[Callable[[int, int], None]] = None,
                       prefetch: bool = False) -> ColumnBlocks:
    """
    Return the blocks of columns of the topics ``specs`` of a bag.

    ``specs`` maps topic -> type name (of :data:`COLUMN_FIELDS`, decoded a
    chunk at once) or a :class:`MessageDecoder` (message by message).

    See :class:`ColumnBlocks`; ``on_progress(bytes_read, bag_bytes)`` is
    called after each chunk (after each block with ``prefetch``).
    """
    return ColumnBlocks(path, specs, max_block_s=max_block_s, on_progress=on_progress,
                        prefetch=prefetch)


class _ColumnBuilder:
    """The growing columns of one topic (preallocated when the summary gives the count)."""

    def __init__(self, type_name: str, capacity: int):
        self.type_name = type_name
        names = ['log_time_ns'] + ([] if type_name == FLOAT64 else ['time_ns'])
        self._arrays = {name: np.empty(capacity, np.int64) for name in names}
        self._arrays.update({name: np.empty(capacity) for name in COLUMN_FIELDS[type_name]})
        self._count = 0

    def reserve(self, more: int) -> None:
        """Make room for ``more`` values past those held."""
        need = self._count + more
        for name, array in self._arrays.items():
            if need > len(array):
                # by half at least, so that the rare regrowth (no summary) stays cheap
                grown = np.empty(max(need, len(array) * 3 // 2), array.dtype)
                grown[:self._count] = array[:self._count]
                self._arrays[name] = grown

    def append(self, columns: Columns) -> None:
        start, stop = self._count, self._count + len(columns)
        self.reserve(len(columns))
        for name, array in self._arrays.items():
            if name == 'log_time_ns':
                array[start:stop] = columns.log_time_ns
            elif name == 'time_ns':
                array[start:stop] = columns.time_ns
            else:
                array[start:stop] = columns.values[name]
        self._count = stop

    def columns(self) -> Columns:
        for array in self._arrays.values():
            array.resize(self._count, refcheck=False)  # in place: no second copy of the data
        log_time_ns = self._arrays['log_time_ns']
        return Columns(self.type_name, log_time_ns, self._arrays.get('time_ns', log_time_ns),
                       {name: self._arrays[name] for name in COLUMN_FIELDS[self.type_name]})


def read_columns(path: os.PathLike, specs: Mapping[str, str],
                 on_progress: Optional[Callable[[int, int], None]] = None) -> ColumnData:
    """
    Read and decode whole numeric topics of a bag: ``specs`` maps topic -> type name.

    Types: std_msgs/msg/Float64 (field ``data``), sensor_msgs/msg/FluidPressure
    (``fluid_pressure``, ``variance``), sensor_msgs/msg/Temperature
    (``temperature``, ``variance``). A topic absent from the bag comes back
    empty. ``on_progress(bytes_read, bag_bytes)`` is called after each chunk.
    A cut file is read up to the cut (``truncated``, ``problem``); ``path``
    may be a bag directory (:func:`~.files.bag_files`).
    """
    specs = _check_specs(specs)
    if not all(isinstance(spec, str) for spec in specs.values()):
        raise BagError('read_columns takes type names only (iter_column_blocks takes decoders)')
    problems: List[str] = []
    total, done = total_bytes(path), 0
    builders = {topic: _ColumnBuilder(type_name, 0) for topic, type_name in specs.items()}
    message_count = 0
    for scan in scans(path, problems):
        statistics = scan.read_summary()
        counts = statistics.channel_message_counts if statistics is not None else {}
        for topic, b in builders.items():     # preallocated from the summary's counts
            b.reserve(sum(counts.get(c.id, 0) for c in scan.channels.values()
                          if c.topic == topic))
        for unit, decoded in _decoded_units(scan, specs):
            for topic, columns in decoded.items():
                builders[topic].append(columns)
                message_count += len(columns)
            if on_progress is not None:
                on_progress(done + unit.file_offset, total)
        done += scan.size
    return ColumnData({topic: b.columns() for topic, b in builders.items()},
                      message_count, bool(problems), join_problems(problems))


def _produce(path: Path, specs: Mapping[str, Spec], max_block_s: float, send) -> None:
    """Child process: send every block, then the end (or the error), each with the state."""
    progress = [0, 0]
    blocks = ColumnBlocks(path, specs, max_block_s=max_block_s,
                          on_progress=lambda done, size: progress.__setitem__(slice(None),
                                                                              (done, size)))

    def state():
        return blocks.message_count, blocks.truncated, blocks.problem, *progress

    try:
        for block in blocks._blocks():
            send.send(('block', block, state()))
        send.send(('end', None, state()))
    except (BrokenPipeError, KeyboardInterrupt):
        pass                      # the caller stopped listening
    except Exception as exc:      # noqa: BLE001 - handed to the caller, who raises it
        try:
            try:
                send.send(('error', exc, state()))
            except (TypeError, AttributeError, pickle.PicklingError):
                send.send(('error', BagError(f'{path}: {exc!r}'), state()))
        except BrokenPipeError:
            pass
    finally:
        send.close()
