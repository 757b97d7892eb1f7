"""
Read rosbag2-style MCAP files fast, including files whose recorder was killed.

A bag is one MCAP file or a rosbag2 bag directory (``metadata.yaml`` and
the files it lists, as ``ros2 bag record -s mcap`` leaves them when it
splits), read as one run (:func:`bag_files`).

The file is walked record by record (MCAP framing: opcode u8, length u64,
body), so a file cut anywhere is read up to its last complete chunk and
reported as truncated instead of failing; a file that is not MCAP raises
:class:`BagError`. The summary at the end of a complete file is used for
what it offers (topics, counts, metadata) without reading the data.

Speed path (:func:`read_columns`, :func:`iter_column_blocks`): numeric topics
of a few fixed-layout types are decoded chunk by chunk with numpy instead of
message by message. A chunk's Message Index records (written after it) give
the offset of every message record in the uncompressed chunk; the fields are
then gathered at computed offsets for all messages of a chunk at once. A
message record is opcode (u8), length (u64), channel id (u16), sequence (u32),
log time (u64), publish time (u64), then the CDR data: a 4-byte encapsulation
header (00 01: little-endian plain CDR, what rclpy writes; anything else is
refused) and the fields, each aligned to its size counted from the end of that
header. Chunks without index, and the gaps between indexed messages (schemas,
channels), are walked record by record.
"""

from dataclasses import dataclass
import io
import multiprocessing
import os
from pathlib import Path
import pickle
import re
import struct
from typing import (Callable, Dict, Iterable, Iterator, List, Mapping, NamedTuple, Optional,
                    Sequence, Tuple)
import zlib

import lz4.frame
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, Header, Metadata, MetadataIndex, Schema, Statistics
import numpy as np
import yaml
import zstandard

from . import cdr

MAGIC = b'\x89MCAP0\r\n'
#: The file of a rosbag2 bag directory that lists its files, and its top-level key.
ROSBAG2_METADATA = 'metadata.yaml'
ROSBAG2_METADATA_ROOT = 'rosbag2_bagfile_information'
FLOAT64 = 'std_msgs/msg/Float64'
FLUID_PRESSURE = 'sensor_msgs/msg/FluidPressure'
TEMPERATURE = 'sensor_msgs/msg/Temperature'
# Fields decoded by the speed path, per type. The two header types share one layout:
# Header (stamp, frame_id), then two float64.
COLUMN_FIELDS = {
    FLOAT64: ('data',),
    FLUID_PRESSURE: ('fluid_pressure', 'variance'),
    TEMPERATURE: ('temperature', 'variance'),
}

_RECORD_HEAD = struct.Struct('<BQ')
_HEAD_BYTES = _RECORD_HEAD.size
# Offsets in a message record from its opcode byte.
_LENGTH_AT = 1
_CHANNEL_AT = 9
_LOG_TIME_AT = 15
_DATA_AT = 31
_MESSAGE_HEADER_BYTES = 22            # channel id, sequence, log time, publish time
_FOOTER_BYTES = _HEAD_BYTES + 20 + len(MAGIC)
_LOOSE_UNIT_BYTES = 4 * 1024 * 1024   # top-level (unchunked) records are decoded in units this big
_BYTE_OFFSETS = {n: np.arange(n, dtype=np.int64) for n in (2, 4, 8)}


class BagError(ValueError):
    """A file is not a readable MCAP bag, or holds what this reader refuses to decode."""


class _Damage(Exception):
    """The file stops making sense here: reading ends, the bag is reported truncated."""


class TopicInfo(NamedTuple):
    """A topic of a bag."""

    type_name: str
    message_count: int
    offered_qos_profiles: str   # YAML, as rosbag2 stores it in the channel metadata
    type_hash: str              # RIHS01_..., empty when the recorder did not store one


@dataclass
class BagInfo:
    """What a bag holds; for a cut file, what could be recovered of it."""

    path: Path
    profile: str
    library: str
    topics: Dict[str, TopicInfo]
    metadata: Dict[str, Dict[str, str]]   # Metadata records by name (the last of a name wins)
    message_count: int
    start_time_ns: int                    # log time span of the messages (0, 0 when none)
    end_time_ns: int
    truncated: bool                       # reading stopped before the footer (cut, damage)
    problem: Optional[str]                # where and why reading stopped, when truncated
    files: Tuple[Path, ...] = ()          # the MCAP files read, in order (one for a file)


class RawMessage(NamedTuple):
    """One message as stored: topic, type, log (receive) time and CDR bytes."""

    topic: str
    type_name: str
    log_time_ns: int
    data: bytes


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


class _Unit(NamedTuple):
    """A run of records: a chunk's uncompressed content, or consecutive top-level records."""

    data: bytes
    index: Optional[np.ndarray]   # message record offsets from the chunk's message indexes
    file_offset: int              # how far into the file reading got with this unit


class _Head(NamedTuple):
    """The framing of a record: opcode, body length, file offset of the opcode."""

    opcode: int
    length: int
    start: int


def _parse(record_type, body):
    return record_type.read(ReadDataStream(io.BytesIO(body)))


def _take(buf: np.ndarray, pos: np.ndarray, dtype: str) -> np.ndarray:
    """Gather one little-endian value of ``dtype`` at each byte offset ``pos`` of ``buf``."""
    dt = np.dtype(dtype)
    return buf[pos[:, None] + _BYTE_OFFSETS[dt.itemsize]].view(dt).reshape(-1)


class _Scanner:
    """Walk an MCAP file record by record; note where and why it ends early."""

    def __init__(self, path: os.PathLike):
        self.path = Path(path)
        try:
            self._f = open(self.path, 'rb')
        except OSError as exc:
            raise BagError(f'cannot open bag {self.path}: {exc.strerror}') from exc
        self.size = os.fstat(self._f.fileno()).st_size
        magic = self._f.read(len(MAGIC))
        if magic != MAGIC:
            self._f.close()
            if self.size == 0:
                raise BagError(f'{self.path}: empty file (0 bytes), not an MCAP bag')
            raise BagError(f'{self.path}: not an MCAP file (it does not start with the '
                           'MCAP magic bytes)')
        self.header = Header(profile='', library='')
        self.schemas: Dict[int, Schema] = {}
        self.channels: Dict[int, Channel] = {}
        self.metadata: Dict[str, Dict[str, str]] = {}
        self.problem: Optional[str] = None   # set when reading the data stops before the footer
        self._zstd = zstandard.ZstdDecompressor()

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self._f.close()

    def type_name(self, channel: Channel) -> str:
        schema = self.schemas.get(channel.schema_id)
        return schema.name if schema is not None else ''

    # --- the summary of a complete file -------------------------------------------------

    def read_summary(self) -> Optional[Statistics]:
        """
        Read schemas, channels and metadata from the summary; return its statistics.

        None when the file has no usable footer or summary (cut, or written
        without one); the data section must then be scanned.
        """
        if self.size < len(MAGIC) + _FOOTER_BYTES:
            return None
        self._f.seek(self.size - _FOOTER_BYTES)
        tail = self._f.read(_FOOTER_BYTES)
        opcode, length = _RECORD_HEAD.unpack_from(tail)
        if opcode != Opcode.FOOTER or length != 20 or tail[-len(MAGIC):] != MAGIC:
            return None
        summary_start = struct.unpack_from('<Q', tail, _HEAD_BYTES)[0]
        summary_end = self.size - _FOOTER_BYTES
        if not len(MAGIC) < summary_start <= summary_end:
            return None
        self._f.seek(summary_start)
        summary = self._f.read(summary_end - summary_start)
        statistics = None
        metadata_indexes = []
        pos = 0
        try:
            while pos < len(summary):
                opcode, length = _RECORD_HEAD.unpack_from(summary, pos)
                body = summary[pos + _HEAD_BYTES:pos + _HEAD_BYTES + length]
                if opcode == Opcode.SCHEMA:
                    schema = _parse(Schema, body)
                    self.schemas[schema.id] = schema
                elif opcode == Opcode.CHANNEL:
                    channel = _parse(Channel, body)
                    self.channels[channel.id] = channel
                elif opcode == Opcode.STATISTICS:
                    statistics = _parse(Statistics, body)
                elif opcode == Opcode.METADATA_INDEX:
                    metadata_indexes.append(_parse(MetadataIndex, body))
                pos += _HEAD_BYTES + length
            for index in metadata_indexes:
                self._f.seek(index.offset + _HEAD_BYTES)
                record = _parse(Metadata, self._f.read(index.length - _HEAD_BYTES))
                self.metadata[record.name] = record.metadata
            self._f.seek(len(MAGIC))
            opcode, length = _RECORD_HEAD.unpack(self._f.read(_HEAD_BYTES))
            if opcode == Opcode.HEADER:
                self.header = _parse(Header, self._f.read(length))
        except (struct.error, ValueError, UnicodeDecodeError, McapError):  # a damaged summary
            self.schemas.clear()
            self.channels.clear()
            self.metadata.clear()
            return None
        return statistics

    # --- the data section, record by record --------------------------------------------

    def units(self) -> Iterator[_Unit]:
        """Yield the file's message-bearing units in file order, up to the end or the damage."""
        self._f.seek(len(MAGIC))
        loose = bytearray()
        complete = False
        try:
            head = self._read_head()
            while head is not None:
                if head.opcode == Opcode.CHUNK:
                    if loose:
                        yield _Unit(bytes(loose), None, head.start)
                        loose.clear()
                    data = self._decompress(_parse(Chunk, self._read_body(head)), head.start)
                    index, head = self._read_message_indexes()
                    yield _Unit(data, index, self._f.tell())
                    continue
                if head.opcode in (Opcode.MESSAGE, Opcode.SCHEMA, Opcode.CHANNEL):
                    body = self._read_body(head)
                    loose += _RECORD_HEAD.pack(head.opcode, head.length) + body
                    if len(loose) >= _LOOSE_UNIT_BYTES:
                        yield _Unit(bytes(loose), None, self._f.tell())
                        loose.clear()
                elif head.opcode == Opcode.HEADER:
                    self.header = _parse(Header, self._read_body(head))
                elif head.opcode == Opcode.METADATA:
                    record = _parse(Metadata, self._read_body(head))
                    self.metadata[record.name] = record.metadata
                elif head.opcode == Opcode.FOOTER:
                    self._read_body(head)
                    if self._f.read(len(MAGIC)) != MAGIC:
                        raise _Damage(f'no MCAP magic after the footer at byte {head.start}')
                    complete = True
                    break
                else:  # indexes, statistics, attachments...: not needed here
                    self._check_length(head)
                    self._f.seek(head.length, os.SEEK_CUR)
                head = self._read_head()
        except _Damage as exc:
            self.problem = str(exc)
        except (struct.error, UnicodeDecodeError, McapError, ValueError) as exc:
            self.problem = f'unreadable record before byte {self._f.tell()}: {exc}'
        if loose:
            yield _Unit(bytes(loose), None, self._f.tell())
        if not complete and self.problem is None:
            self.problem = f'the file ends at byte {self.size} without the MCAP footer'

    def _read_head(self) -> Optional[_Head]:
        start = self._f.tell()
        raw = self._f.read(_HEAD_BYTES)
        if len(raw) < _HEAD_BYTES:
            if raw:
                raise _Damage(f'the file ends inside a record header at byte {start}')
            return None
        return _Head(*_RECORD_HEAD.unpack(raw), start)

    def _check_length(self, head: _Head) -> None:
        present = self.size - self._f.tell()
        if head.length > present:
            try:
                kind = Opcode(head.opcode).name
            except ValueError:
                kind = f'opcode 0x{head.opcode:02x}'
            raise _Damage(f'the file ends inside a {kind} record at byte {head.start}: '
                          f'{present} of its {head.length} bytes are there')

    def _read_body(self, head: _Head) -> bytes:
        self._check_length(head)
        return self._f.read(head.length)

    def _decompress(self, chunk: Chunk, start: int) -> bytes:
        try:
            if chunk.compression == 'zstd':
                data = self._zstd.decompress(chunk.data, max_output_size=chunk.uncompressed_size)
            elif chunk.compression == 'lz4':
                data = lz4.frame.decompress(chunk.data)
            elif chunk.compression == '':
                data = chunk.data
            else:
                raise _Damage(f'chunk at byte {start}: unknown compression '
                              f'{chunk.compression!r}')
        except (zstandard.ZstdError, RuntimeError) as exc:
            raise _Damage(f'chunk at byte {start} does not decompress: {exc}') from exc
        if len(data) != chunk.uncompressed_size or (
                chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc):
            raise _Damage(f'chunk at byte {start}: content does not match its size or CRC')
        return data

    def _read_message_indexes(self):
        """Read the Message Index records after a chunk; return (offsets or None, next head)."""
        offsets = []
        head = self._read_head()
        while head is not None and head.opcode == Opcode.MESSAGE_INDEX:
            body = self._read_body(head)
            entries_bytes = struct.unpack_from('<I', body, 2)[0]
            # entries are (log time u64, offset u64); keep the offsets
            offsets.append(np.frombuffer(body, '<u8', entries_bytes // 8, 6)[1::2])
            head = self._read_head()
        index = np.concatenate(offsets).astype(np.int64) if offsets else None
        return index, head

    def locate(self, unit: _Unit) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """
        Return the unit as a byte array, its message record offsets in file order, their channels.

        Registers the schemas and channels met on the way.
        """
        buf = np.frombuffer(unit.data, np.uint8)
        pos = None
        if unit.index is not None:
            pos = self._indexed_positions(unit.data, buf, np.sort(unit.index))
        if pos is None:
            pos = np.array(self._walk(unit.data, 0, len(unit.data)), dtype=np.int64)
        return buf, pos, _take(buf, pos + _CHANNEL_AT, '<u2')

    def _indexed_positions(self, data: bytes, buf: np.ndarray,
                           pos: np.ndarray) -> Optional[np.ndarray]:
        """Check index offsets against the records and walk the gaps; None if they disagree."""
        size = len(buf)
        if len(pos) and (pos[0] < 0 or pos[-1] > size - _DATA_AT):
            return None
        if len(pos) and not (buf[pos] == Opcode.MESSAGE).all():
            return None
        ends = pos + _HEAD_BYTES + _take(buf, pos + _LENGTH_AT, '<u8').astype(np.int64)
        if len(pos) and (ends[-1] > size or (ends[:-1] > pos[1:]).any()):
            return None
        gap_starts = np.concatenate(([0], ends))
        gap_ends = np.concatenate((pos, [size]))
        try:
            for a, b in zip(gap_starts[gap_starts < gap_ends].tolist(),
                            gap_ends[gap_starts < gap_ends].tolist()):
                if self._walk(data, a, b):
                    return None  # messages the index does not list
        except _Damage:
            return None  # the index is wrong: the walk of the whole chunk decides
        return pos

    def _walk(self, data: bytes, start: int, stop: int) -> List[int]:
        """Return the offsets of the message records in data[start:stop]; register the rest."""
        positions = []
        unpack = _RECORD_HEAD.unpack_from
        pos = start
        while pos < stop:
            if pos + _HEAD_BYTES > stop:
                raise _Damage('a record header crosses the end of a chunk')
            opcode, length = unpack(data, pos)
            end = pos + _HEAD_BYTES + length
            if end > stop:
                raise _Damage('a record crosses the end of a chunk')
            if opcode == Opcode.MESSAGE:
                if length < _MESSAGE_HEADER_BYTES:
                    raise _Damage('a message record is shorter than its header')
                positions.append(pos)
            elif opcode == Opcode.SCHEMA:
                schema = _parse(Schema, data[pos + _HEAD_BYTES:end])
                self.schemas[schema.id] = schema
            elif opcode == Opcode.CHANNEL:
                channel = _parse(Channel, data[pos + _HEAD_BYTES:end])
                self.channels[channel.id] = channel
            pos = end
        return positions

    def located(self) -> Iterator[Tuple[_Unit, np.ndarray, np.ndarray, np.ndarray]]:
        """Yield each unit with its byte array, message record offsets and channel ids."""
        for unit in self.units():
            try:
                buf, pos, channel_ids = self.locate(unit)
            except (_Damage, struct.error, UnicodeDecodeError, McapError) as exc:
                self.problem = f'damaged chunk before byte {unit.file_offset}: {exc}'
                return
            yield unit, buf, pos, channel_ids


def _natural_key(path: Path) -> tuple:
    """Sort key of a file name with its numbers compared as numbers (``_2`` before ``_10``)."""
    return tuple(int(part) if part.isdigit() else part
                 for part in re.split(r'(\d+)', path.name))


_SPLIT_MEMBER = re.compile(r'(.+)_\d+\.mcap$')


def one_split_series(files: Sequence[Path]) -> bool:
    """Return whether ``.mcap`` files are one bag: a single file, or ``<stem>_<N>.mcap`` all."""
    stems = {m.group(1) if m else None for m in (_SPLIT_MEMBER.match(f.name) for f in files)}
    return len(files) == 1 or (len(stems) == 1 and None not in stems)


def is_bag(path: os.PathLike) -> bool:
    """
    Return whether ``path`` names one bag rather than a folder of separate logs.

    A file (or a missing path, which reading reports) is a bag; so is a folder
    with ``metadata.yaml``, or whose ``.mcap`` files are one split series.
    """
    path = Path(path)
    if not path.is_dir() or (path / ROSBAG2_METADATA).is_file():
        return True
    files = list(path.glob('*.mcap'))
    return bool(files) and one_split_series(files)


def bag_files(path: os.PathLike) -> Tuple[Path, ...]:
    """
    Return the MCAP files of a bag in reading order: a file alone, or a bag directory's.

    A rosbag2 bag directory (``ros2 bag record -s mcap``) lists its files in
    ``metadata.yaml`` (``relative_file_paths``); without that file (a folder
    of our writer's ``<stem>_0.mcap``, ``<stem>_1.mcap``, ...), its
    ``*.mcap`` files are taken by name, numbers compared as numbers, if they
    are one such series (or one file): else they are separate logs, and
    that is an error here. A listed file that is missing stays in the list:
    reading it reports it by name.
    """
    path = Path(path)
    if not path.is_dir():
        return (path,)
    meta = path / ROSBAG2_METADATA
    if meta.is_file():
        try:
            info = yaml.safe_load(meta.read_text())[ROSBAG2_METADATA_ROOT]
            names = info.get('relative_file_paths') or [f['path'] for f in info['files']]
        except (OSError, yaml.YAMLError, KeyError, TypeError, AttributeError) as exc:
            raise BagError(f'{meta}: not a rosbag2 metadata file ({type(exc).__name__}: '
                           f'{exc})') from None
        files = tuple(path / str(name) for name in names)
    else:
        files = tuple(sorted(path.glob('*.mcap'), key=_natural_key))
        if files and not one_split_series(files):
            raise BagError(f'{path}: {len(files)} separate logs ({files[0].name}, '
                           f'{files[1].name}, ...), not the files of one split bag: '
                           '`replay` them as a campaign')
    if not files:
        raise BagError(f'{path}: a folder with neither {ROSBAG2_METADATA} nor .mcap files, '
                       'not a bag')
    return files


def _scans(path: os.PathLike, problems: List[str]) -> Iterator[_Scanner]:
    """
    Open the files of the bag ``path`` one after another, each closed before the next.

    A lone file that cannot be opened raises :class:`BagError`; in a bag
    directory, such a file is noted in ``problems`` and skipped, and so is
    the rest of a file that was cut (its first part is read).
    """
    files = bag_files(path)
    lone = not Path(path).is_dir()
    for name in files:
        try:
            scan = _Scanner(name)
        except BagError as exc:
            if lone:
                raise
            problems.append(str(exc))
            continue
        with scan:
            yield scan
        if scan.problem is not None:
            problems.append(scan.problem if lone else f'{name.name}: {scan.problem}')


def _problem(problems: List[str]) -> Optional[str]:
    return '; '.join(problems) if problems else None


def _require(ok: np.ndarray, where: str, what: str) -> None:
    if not ok.all():
        raise BagError(f'{where}: a message is too short for {what}')


def _decode(buf: np.ndarray, pos: np.ndarray, type_name: str, where: str) -> Columns:
    """Decode the messages (all of ``type_name``) whose records start at ``pos`` in ``buf``."""
    data = pos + _DATA_AT
    size = _take(buf, pos + _LENGTH_AT, '<u8').astype(np.int64) - _MESSAGE_HEADER_BYTES
    log_time_ns = _take(buf, pos + _LOG_TIME_AT, '<i8')
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
        return Columns(type_name, log_time_ns, log_time_ns, {'data': _take(buf, body, '<f8')})
    # a Header, then the two float64 (cdr.py has the layout)
    _require(size >= head + cdr.FRAME_ID_AT, where, 'a std_msgs/Header')
    sec = _take(buf, body + cdr.STAMP_SEC_AT, '<i4').astype(np.int64)
    nanosec = _take(buf, body + cdr.STAMP_NANOSEC_AT, '<u4')
    first = cdr.first_after_header(
        _take(buf, body + cdr.FRAME_ID_LENGTH_AT, '<u4').astype(np.int64))
    _require(size >= head + first + 16, where, type_name)
    stamp_ns = sec * 1_000_000_000 + nanosec
    a, b = COLUMN_FIELDS[type_name]
    return Columns(type_name, log_time_ns, np.where(stamp_ns != 0, stamp_ns, log_time_ns),
                   {a: _take(buf, body + first, '<f8'), b: _take(buf, body + first + 8, '<f8')})


def _check_specs(specs: Mapping[str, str]) -> Dict[str, str]:
    for topic, type_name in specs.items():
        if type_name not in COLUMN_FIELDS:
            raise BagError(f'topic {topic}: type {type_name} is not one read as columns '
                           f'({", ".join(COLUMN_FIELDS)})')
    return dict(specs)


class _Selection:
    """The channels carrying the requested topics, checked against the requested types."""

    def __init__(self, scan: _Scanner, specs: Dict[str, str]):
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
            expected = self._specs.get(channel.topic)
            if expected is None:
                continue
            found = self._scan.type_name(channel)
            if found != expected or channel.message_encoding != 'cdr':
                raise BagError(f'{self._scan.path}: topic {channel.topic} is {found} '
                               f'({channel.message_encoding}), expected {expected} (cdr)')
            self.ids[channel.topic].append(channel.id)


def _decoded_units(scan: _Scanner, specs: Dict[str, str]) -> Iterator[Tuple[_Unit, dict]]:
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
                decoded[topic] = _decode(buf, pos[mine], specs[topic], f'{scan.path}: {topic}')
        yield unit, decoded


def _empty(type_name: str) -> Columns:
    log_time_ns = np.empty(0, np.int64)
    return Columns(type_name, log_time_ns,
                   log_time_ns if type_name == FLOAT64 else np.empty(0, np.int64),
                   {name: np.empty(0) for name in COLUMN_FIELDS[type_name]})


def _concatenate(type_name: str, parts: List[Columns]) -> Columns:
    if not parts:
        return _empty(type_name)
    log_time_ns = np.concatenate([p.log_time_ns for p in parts])
    return Columns(type_name, log_time_ns,
                   log_time_ns if type_name == FLOAT64
                   else np.concatenate([p.time_ns for p in parts]),
                   {name: np.concatenate([p.values[name] for p in parts])
                    for name in COLUMN_FIELDS[type_name]})


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

    With ``prefetch`` (where processes can fork) a child process reads and
    decodes the next block while the caller works on this one: a replay's
    model step and the reading then run on two cores. The pipe between them
    holds about one block, so memory stays flat; the blocks, the attributes
    and the errors are the same as without it, and ``on_progress`` is then
    called once per block.
    """

    def __init__(self, path: os.PathLike, specs: Mapping[str, str], *,
                 max_block_s: float = 10.0,
                 on_progress: Optional[Callable[[int, int], None]] = None,
                 prefetch: bool = False):
        self.path = Path(path)
        self.specs = _check_specs(specs)
        self.max_block_s = max_block_s
        self.on_progress = on_progress
        self.prefetch = prefetch and 'fork' in multiprocessing.get_all_start_methods()
        self.message_count = 0
        self.truncated = False
        self.problem: Optional[str] = None

    def __iter__(self) -> Iterator[Dict[str, Columns]]:
        return self._prefetched() if self.prefetch else self._blocks()

    def _prefetched(self) -> Iterator[Dict[str, Columns]]:
        ctx = multiprocessing.get_context('fork')
        receive, send = ctx.Pipe(duplex=False)
        child = ctx.Process(target=self._produce, args=(send,), daemon=True,
                            name=f'read {self.path.name}')
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

    def _produce(self, send) -> None:
        """Child process: send every block, then the end (or the error), each with the state."""
        progress = [0, 0]
        self.on_progress = lambda done, size: progress.__setitem__(slice(None), (done, size))

        def state():
            return self.message_count, self.truncated, self.problem, *progress

        try:
            for block in self._blocks():
                send.send(('block', block, state()))
            send.send(('end', None, state()))
        except (BrokenPipeError, KeyboardInterrupt):
            pass                      # the caller stopped listening
        except Exception as exc:      # noqa: BLE001 - handed to the caller, who raises it
            try:
                try:
                    send.send(('error', exc, state()))
                except (TypeError, AttributeError, pickle.PicklingError):
                    send.send(('error', BagError(f'{self.path}: {exc!r}'), state()))
            except BrokenPipeError:
                pass
        finally:
            send.close()

    def _blocks(self) -> Iterator[Dict[str, Columns]]:
        max_block_ns = self.max_block_s * 1e9
        self.message_count = 0
        self.truncated = False
        self.problem = None
        problems: List[str] = []
        total, done = _total_bytes(self.path), 0
        parts = {topic: [] for topic in self.specs}
        first_ns = last_ns = None
        for scan in _scans(self.path, problems):
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
        self.problem = _problem(problems)
        if first_ns is not None:
            yield self._block(parts)

    def _block(self, parts: Dict[str, List[Columns]]) -> Dict[str, Columns]:
        return {topic: _concatenate(self.specs[topic], p) for topic, p in parts.items()}


def iter_column_blocks(path: os.PathLike, specs: Mapping[str, str], *,
                       max_block_s: float = 10.0,
                       on_progress: Optional[Callable[[int, int], None]] = None,
                       prefetch: bool = False) -> ColumnBlocks:
    """
    Return the blocks of columns of the topics ``specs`` (topic -> type name) of a bag.

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
    may be a bag directory (:func:`bag_files`).
    """
    specs = _check_specs(specs)
    problems: List[str] = []
    total, done = _total_bytes(path), 0
    builders = {topic: _ColumnBuilder(type_name, 0) for topic, type_name in specs.items()}
    message_count = 0
    for scan in _scans(path, problems):
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
                      message_count, bool(problems), _problem(problems))


def iter_raw(path: os.PathLike, topics: Optional[Iterable[str]] = None) -> Iterator[RawMessage]:
    """Yield the messages of a bag (of ``topics`` only, when given) in file order."""
    # a bag directory's files one after another; what cannot be read is open_bag's to report
    wanted = None if topics is None else set(topics)
    for scan in _scans(path, []):
        for unit, buf, pos, channel_ids in scan.located():
            ends = pos + _HEAD_BYTES + _take(buf, pos + _LENGTH_AT, '<u8').astype(np.int64)
            times = _take(buf, pos + _LOG_TIME_AT, '<i8')
            for p, end, c, t in zip(pos.tolist(), ends.tolist(), channel_ids.tolist(),
                                    times.tolist()):
                channel = scan.channels.get(c)
                if channel is None:
                    raise BagError(f'{scan.path}: a message on channel {c} comes before '
                                   'the record of that channel')
                if wanted is None or channel.topic in wanted:
                    yield RawMessage(channel.topic, scan.type_name(channel), t,
                                     unit.data[p + _DATA_AT:end])


def open_bag(path: os.PathLike) -> BagInfo:
    """
    Describe a bag: topics, types, message counts, metadata records, whether it was cut.

    ``path``: an MCAP file or a bag directory (:func:`bag_files`). A complete
    file is described from its summary; a cut one (or one without summary
    statistics) is scanned, and the counts are what it holds. A directory is
    described as one run over its files: a file that is missing, not MCAP or
    cut is named in ``problem`` (``truncated`` set) and the others are used;
    when none can be read, :class:`BagError` names each.
    """
    problems: List[str] = []
    parts = [_describe(scan) for scan in _scans(path, problems)]
    if not Path(path).is_dir():
        return parts[0]
    if not parts:
        raise BagError(f'{path}: no file of the bag can be read: {_problem(problems)}')
    topics: Dict[str, TopicInfo] = {}
    metadata: Dict[str, Dict[str, str]] = {}
    for part in parts:
        metadata.update(part.metadata)
        for topic, t in part.topics.items():
            before = topics.get(topic)
            topics[topic] = t._replace(message_count=t.message_count + (
                before.message_count if before else 0))
    spans = [(p.start_time_ns, p.end_time_ns) for p in parts if p.message_count]
    return BagInfo(Path(path), parts[0].profile, parts[0].library, topics, metadata,
                   sum(p.message_count for p in parts),
                   min((a for a, _ in spans), default=0), max((b for _, b in spans), default=0),
                   bool(problems), _problem(problems), tuple(p.path for p in parts))


def _total_bytes(path: os.PathLike) -> int:
    """Return the size of the bag's files that exist (bytes), for progress."""
    return sum(f.stat().st_size for f in bag_files(path) if f.is_file())


def _describe(scan: _Scanner) -> BagInfo:
    """Describe one open MCAP file (see :func:`open_bag`)."""
    statistics = scan.read_summary()
    if statistics is not None:
        counts = dict(statistics.channel_message_counts)
        start_ns, end_ns = statistics.message_start_time, statistics.message_end_time
    else:
        counts = {}
        start_ns = end_ns = None
        for _, buf, pos, channel_ids in scan.located():
            if not len(pos):
                continue
            for c, n in enumerate(np.bincount(channel_ids).tolist()):
                if n:
                    counts[c] = counts.get(c, 0) + n
            times = _take(buf, pos + _LOG_TIME_AT, '<i8')
            lo, hi = int(times.min()), int(times.max())
            start_ns = lo if start_ns is None else min(start_ns, lo)
            end_ns = hi if end_ns is None else max(end_ns, hi)
    topics: Dict[str, TopicInfo] = {}
    for channel in sorted(scan.channels.values(), key=lambda c: c.id):
        before = topics.get(channel.topic)
        topics[channel.topic] = TopicInfo(
            scan.type_name(channel),
            counts.get(channel.id, 0) + (before.message_count if before else 0),
            channel.metadata.get('offered_qos_profiles', ''),
            channel.metadata.get('topic_type_hash', ''))
    return BagInfo(scan.path, scan.header.profile, scan.header.library, topics,
                   scan.metadata, sum(counts.values()), start_ns or 0, end_ns or 0,
                   scan.problem is not None, scan.problem, (scan.path,))
