"""
Walk an MCAP file record by record, up to its end or to where it was cut or damaged.

MCAP framing: opcode u8, length u64, body; so a file cut anywhere is read up
to its last complete chunk and reported as truncated (:attr:`Scanner.problem`)
instead of failing, and a file that is not MCAP raises :class:`BagError`. The
summary at the end of a complete file is used for what it offers (topics,
counts, metadata) without reading the data. A chunk's Message Index records
(written after it) give the offset of every message record in the
uncompressed chunk; chunks without index, and the gaps between indexed
messages (schemas, channels), are walked record by record.

A message record is opcode (u8), length (u64), channel id (u16), sequence
(u32), log time (u64), publish time (u64), then the CDR data.
"""

import io
import os
from pathlib import Path
import struct
from typing import Dict, Iterator, List, NamedTuple, Optional, Tuple
import zlib

import lz4.frame
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, Header, Metadata, MetadataIndex, Schema, Statistics
import numpy as np
import zstandard

MAGIC = b'\x89MCAP0\r\n'

_RECORD_HEAD = struct.Struct('<BQ')
HEAD_BYTES = _RECORD_HEAD.size
# Offsets in a message record from its opcode byte.
LENGTH_AT = 1
_CHANNEL_AT = 9
LOG_TIME_AT = 15
DATA_AT = 31
MESSAGE_HEADER_BYTES = 22            # channel id, sequence, log time, publish time
_FOOTER_BYTES = HEAD_BYTES + 20 + len(MAGIC)
_LOOSE_UNIT_BYTES = 4 * 1024 * 1024   # top-level (unchunked) records are decoded in units this big
_BYTE_OFFSETS = {n: np.arange(n, dtype=np.int64) for n in (2, 4, 8)}


class BagError(ValueError):
    """A file is not a readable MCAP bag, or holds what this reader refuses to decode."""


class _Damage(Exception):
    """The file stops making sense here: reading ends, the bag is reported truncated."""


class Unit(NamedTuple):
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
    """Return the record of ``record_type`` whose body is ``body``."""
    return record_type.read(ReadDataStream(io.BytesIO(body)))


def take(buf: np.ndarray, pos: np.ndarray, dtype: str) -> np.ndarray:
    """Gather one little-endian value of ``dtype`` at each byte offset ``pos`` of ``buf``."""
    dt = np.dtype(dtype)
    return buf[pos[:, None] + _BYTE_OFFSETS[dt.itemsize]].view(dt).reshape(-1)


class Scanner:
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
        """Return the message type of ``channel`` ('' when its schema is unknown)."""
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
        summary_start = struct.unpack_from('<Q', tail, HEAD_BYTES)[0]
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
                body = summary[pos + HEAD_BYTES:pos + HEAD_BYTES + length]
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
                pos += HEAD_BYTES + length
            for index in metadata_indexes:
                self._f.seek(index.offset + HEAD_BYTES)
                record = _parse(Metadata, self._f.read(index.length - HEAD_BYTES))
                self.metadata[record.name] = record.metadata
            self._f.seek(len(MAGIC))
            opcode, length = _RECORD_HEAD.unpack(self._f.read(HEAD_BYTES))
            if opcode == Opcode.HEADER:
                self.header = _parse(Header, self._f.read(length))
        except (struct.error, ValueError, UnicodeDecodeError, McapError):  # a damaged summary
            self.schemas.clear()
            self.channels.clear()
            self.metadata.clear()
            return None
        return statistics

    # --- the data section, record by record --------------------------------------------

    def units(self) -> Iterator[Unit]:
        """Yield the file's message-bearing units in file order, up to the end or the damage."""
        self._f.seek(len(MAGIC))
        loose = bytearray()
        complete = False
        try:
            head = self._read_head()
            while head is not None:
                if head.opcode == Opcode.CHUNK:
                    if loose:
                        yield Unit(bytes(loose), None, head.start)
                        loose.clear()
                    data = self._decompress(_parse(Chunk, self._read_body(head)), head.start)
                    index, head = self._read_message_indexes()
                    yield Unit(data, index, self._f.tell())
                    continue
                if head.opcode in (Opcode.MESSAGE, Opcode.SCHEMA, Opcode.CHANNEL):
                    body = self._read_body(head)
                    loose += _RECORD_HEAD.pack(head.opcode, head.length) + body
                    if len(loose) >= _LOOSE_UNIT_BYTES:
                        yield Unit(bytes(loose), None, self._f.tell())
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
            yield Unit(bytes(loose), None, self._f.tell())
        if not complete and self.problem is None:
            self.problem = f'the file ends at byte {self.size} without the MCAP footer'

    def _read_head(self) -> Optional[_Head]:
        start = self._f.tell()
        raw = self._f.read(HEAD_BYTES)
        if len(raw) < HEAD_BYTES:
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

    def locate(self, unit: Unit) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
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
        return buf, pos, take(buf, pos + _CHANNEL_AT, '<u2')

    def _indexed_positions(self, data: bytes, buf: np.ndarray,
                           pos: np.ndarray) -> Optional[np.ndarray]:
        """Check index offsets against the records and walk the gaps; None if they disagree."""
        size = len(buf)
        if len(pos) and (pos[0] < 0 or pos[-1] > size - DATA_AT):
            return None
        if len(pos) and not (buf[pos] == Opcode.MESSAGE).all():
            return None
        ends = pos + HEAD_BYTES + take(buf, pos + LENGTH_AT, '<u8').astype(np.int64)
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
            if pos + HEAD_BYTES > stop:
                raise _Damage('a record header crosses the end of a chunk')
            opcode, length = unpack(data, pos)
            end = pos + HEAD_BYTES + length
            if end > stop:
                raise _Damage('a record crosses the end of a chunk')
            if opcode == Opcode.MESSAGE:
                if length < MESSAGE_HEADER_BYTES:
                    raise _Damage('a message record is shorter than its header')
                positions.append(pos)
            elif opcode == Opcode.SCHEMA:
                schema = _parse(Schema, data[pos + HEAD_BYTES:end])
                self.schemas[schema.id] = schema
            elif opcode == Opcode.CHANNEL:
                channel = _parse(Channel, data[pos + HEAD_BYTES:end])
                self.channels[channel.id] = channel
            pos = end
        return positions

    def located(self) -> Iterator[Tuple[Unit, np.ndarray, np.ndarray, np.ndarray]]:
        """Yield each unit with its byte array, message record offsets and channel ids."""
        for unit in self.units():
            try:
                buf, pos, channel_ids = self.locate(unit)
            except (_Damage, struct.error, UnicodeDecodeError, McapError) as exc:
                self.problem = f'damaged chunk before byte {unit.file_offset}: {exc}'
                return
            yield unit, buf, pos, channel_ids
