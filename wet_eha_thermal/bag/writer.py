"""
Record ROS 2 messages to MCAP files that rosbag2 (Jazzy) reads as its own.

What this writes is what rosbag2's MCAP storage plugin writes (checked in
ros2/rosbag2: rosbag2_storage_mcap/src/mcap_storage.cpp, rosbag2_cpp's
local_message_definition_source.cpp and sequential_writer.cpp, and
rosbag2_storage's yaml.hpp and qos.cpp of metadata version 9, Jazzy):

- profile ``ros2``; one schema per type, named ``pkg/msg/Type``, encoding
  ``ros2msg``: the .msg file as installed (comments kept, as rosbag2 keeps
  them), then every type it uses, depth first in sorted order, each after a
  line of 80 ``=`` and ``MSG: pkg/Type`` (see :func:`message_definition`);
- one channel per topic, message encoding ``cdr``, with the metadata
  ``offered_qos_profiles`` (YAML list of the publishers' QoS) and
  ``topic_type_hash`` (``RIHS01_...``);
- a Metadata record ``rosbag2`` whose ``serialized_metadata`` is the YAML of
  the bag's BagMetadata, written when a file is opened and again when it is
  closed (readers keep the last one);
- as a bag directory (``directory=True``, what ``ros2 bag record -s mcap``
  makes): the files ``<dir name>_0.mcap``, ``_1``, ... inside it and
  ``metadata.yaml``, ``rosbag2_bagfile_information`` holding the same
  BagMetadata: what ``ros2 bag info`` and rosbag2_py open a bag by (the
  tests read it with rosbags, an independent rosbag2 reader).

Crash safety: messages are collected in an MCAP chunk, which is useless until
it is complete. This writer closes the chunk (mcap's public
``Writer.flush()``: finish the chunk, write it and flush the file) when it
holds ``chunk_bytes`` of records, spans ``flush_interval_s`` of log time, or
holds a message older than ``flush_interval_s`` of wall time; a background
thread checks the last condition when no message arrives. A SIGKILL therefore
loses at most about ``flush_interval_s`` of data (the OS keeps what was
written; a power cut is another matter, nothing is fsync'ed). Readers recover
every complete chunk of such a file (see :mod:`wet_eha_thermal.bag.reader`).
A bag directory's ``metadata.yaml`` is replaced whole (written beside, then
renamed over it) when the bag opens, at each split and at close: a killed
recorder leaves one that lists every file it had begun, the last one cut.

Write errors: mcap writes through a :class:`FileSink`, which keeps what it is
given in memory and writes it to the file at each flush, whole or not at all:
on an OSError the file is cut back to the end of the previous flush (a
complete chunk, or the header), the bytes are kept for another try, and
mcap's in-memory state (chunk indexes, statistics) stays that of a file that
will hold them. What follows an error depends on ``on_error``:

- ``'raise'`` (the default, for the offline tools): the OSError reaches the
  caller, and every later write and the close raise too; the file is left
  cut at its last complete chunk unless the close manages to finish it.
- ``'suspend'`` (a recorder that must survive a full disk): a hidden file of
  ``reserve_bytes`` (``.wet_eha_reserve`` inside a bag directory,
  ``.<file name>.wet_eha_reserve`` beside a lone file), allocated with
  ``posix_fallocate`` before a file opens and grown when a long file's summary
  would need more, is deleted at the first error: the space it frees finishes
  the file (the chunk that failed, the rosbag2 record, the summary and footer:
  a complete MCAP file that strict readers open) and ``metadata.yaml`` (every
  file with its real message count and times). The writer is then
  *suspended*: messages are dropped and counted, per topic and in total,
  without an exception (so is the one whose split met the error, having no
  file to go to); about once a second it measures the free space at
  the destination and, once that is ``reserve_bytes + resume_margin_bytes``,
  makes the reserve again and opens the next file of the bag
  (``<name>_<k>.mcap``; a lone ``run.mcap`` goes on in ``run_1.mcap``, ...),
  listed in ``metadata.yaml``. When even finishing fails (the freed space was
  taken by others), the file stays cut at its last complete chunk, which
  :mod:`wet_eha_thermal.bag.reader` recovers, and the error is reported.
  :meth:`BagWriter.health` tells the state, the counts, the files, the
  errors and the free space; ``on_state_change`` is called at every change.
  The reserve is deleted at close; a SIGKILL leaves it behind.
"""

import contextlib
from dataclasses import dataclass
import errno
from importlib.metadata import version
import json
import os
from pathlib import Path
import re
import shutil
import sys
import textwrap
import threading
import time
from typing import Callable, Dict, List, Optional, Tuple

from mcap.writer import CompressionType, LIBRARY_IDENTIFIER, Writer
import yaml

from .reader import ROSBAG2_METADATA, ROSBAG2_METADATA_ROOT

LIBRARY = f'wet_eha_thermal/{version("wet_eha_thermal")} ({LIBRARY_IDENTIFIER})'
ROSBAG2_METADATA_NAME = 'rosbag2'
ROSBAG2_METADATA_KEY = 'serialized_metadata'
ROSBAG2_METADATA_VERSION = 9      # rosbag2 Jazzy
DEFAULT_CHUNK_BYTES = 768 * 1024  # rosbag2's MCAP default (mcap C++ McapWriterOptions)
COMPRESSIONS = {'zstd': CompressionType.ZSTD, 'lz4': CompressionType.LZ4,
                'none': CompressionType.NONE}

# What rosbag2 takes for the field types of a .msg file, and the primitives it skips
# (rosbag2_cpp local_message_definition_source.cpp).
_MSG_FIELD_TYPE = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+', re.ASCII)
_PRIMITIVE_TYPES = frozenset({
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
    'int32', 'uint32', 'int64', 'uint64', 'string'})
_DEFINITION_DELIMITER = '=' * 80 + '\n'
# A record costs its data plus 9 bytes of opcode and length and 22 of message header.
_MESSAGE_RECORD_OVERHEAD_BYTES = 31
# libyaml's emitter when PyYAML has it: the bag metadata is dumped at every file change
_YAML_DUMPER = getattr(yaml, 'CSafeDumper', yaml.SafeDumper)
# The background check for messages waiting too long runs this often (fraction of the interval).
_IDLE_CHECK_FRACTION = 0.1

ON_ERROR = ('raise', 'suspend')
#: The states of :class:`BagHealth`.
RECORDING, SUSPENDED, CLOSED = 'recording', 'suspended', 'closed'
#: Space held back to finish a file when the disk is full, and free space asked for on top of it
#: before writing again (suspend mode).
DEFAULT_RESERVE_BYTES = 4 * 2 ** 20
DEFAULT_RESUME_MARGIN_BYTES = 16 * 2 ** 20
RESERVE_NAME = '.wet_eha_reserve'
#: While suspended, the free space is measured this often (s).
RESUME_CHECK_S = 1.0
# What closing a file may write besides its last chunk, to size the reserve: a Chunk Index
# record of the summary is 85 bytes and 10 a channel (mcap records.py); the header-sized rest
# (statistics, metadata indexes, footer) and a large last message fit in the slack.
_CHUNK_INDEX_BYTES, _CHUNK_INDEX_CHANNEL_BYTES = 100, 10
_CLOSE_SLACK_BYTES = 64 * 1024


def _share_dir(package: str) -> Path:
    """Return the share folder of a ROS package (ament index, else the running prefix)."""
    try:
        from ament_index_python.packages import get_package_share_directory
        return Path(get_package_share_directory(package))
    except Exception:  # noqa: B902 - no ament environment (pip venv) or package not indexed
        return Path(sys.prefix) / 'share' / package


def _split_type_name(type_name: str):
    """Return (package, Type) of 'pkg/msg/Type' or 'pkg/Type'."""
    parts = type_name.split('/')
    if len(parts) == 3 and parts[1] == 'msg':
        return parts[0], parts[2]
    if len(parts) == 2:
        return parts[0], parts[1]
    raise ValueError(f'message type {type_name!r}: expected pkg/msg/Type')


def _interface_file(type_name: str, suffix: str) -> Path:
    package, name = _split_type_name(type_name)
    path = _share_dir(package) / 'msg' / f'{name}{suffix}'
    if not path.is_file():
        raise ValueError(f'message type {type_name!r}: no {path}')
    return path


def message_definition(type_name: str) -> str:
    """
    Return the complete ``ros2msg`` definition of a message type, as rosbag2 stores it.

    That is rosbag2's own algorithm: the .msg text unchanged, then for each
    field type not seen before (sorted by name, depth first) a newline, the
    80 ``=`` delimiter line, ``MSG: <type as written in the .msg>`` and its
    text, recursively.
    """
    seen = set()

    def with_dependencies(name: str) -> str:
        text = _interface_file(name, '.msg').read_text()
        package = _split_type_name(name)[0]
        dependencies = sorted({
            t if '/' in t else f'{package}/{t}'
            for t in _MSG_FIELD_TYPE.findall(text) if t not in _PRIMITIVE_TYPES})
        for dependency in dependencies:
            if dependency not in seen:
                seen.add(dependency)
                text += ('\n' + _DEFINITION_DELIMITER + f'MSG: {dependency}\n'
                         + with_dependencies(dependency))
        return text

    return with_dependencies(type_name)


def type_hash(type_name: str) -> str:
    """Return the RIHS01 type hash of a message type, from its generated .json description."""
    description = json.loads(_interface_file(type_name, '.json').read_text())
    package, name = _split_type_name(type_name)
    full_name = f'{package}/msg/{name}'
    for entry in description['type_hashes']:
        if entry['type_name'] == full_name:
            return entry['hash_string']
    raise ValueError(f'message type {type_name!r}: no type hash in its .json description')


def _rosbag2_profile(history: str, depth: int, reliability: str, durability: str,
                     deadline_ns: int, lifespan_ns: int, liveliness: str, lease_ns: int,
                     avoid_ros_namespace_conventions: bool) -> dict:
    """Return one offered QoS profile as rosbag2 (metadata version 9) stores it."""
    def rmw_time(ns: int) -> Dict[str, int]:  # a new dict each: a shared one dumps as an alias
        sec, nsec = divmod(ns, 1_000_000_000)
        return {'sec': sec, 'nsec': nsec}

    return {'history': history, 'depth': depth, 'reliability': reliability,
            'durability': durability, 'deadline': rmw_time(deadline_ns),
            'lifespan': rmw_time(lifespan_ns), 'liveliness': liveliness,
            'liveliness_lease_duration': rmw_time(lease_ns),
            'avoid_ros_namespace_conventions': avoid_ros_namespace_conventions}


def qos_profiles(qos) -> List[dict]:
    """
    Return an rclpy QoSProfile as rosbag2 (metadata version 9) lists a topic's offered QoS.

    Read by attribute, so this module imports nothing of ROS: the recorder
    passes what its publishers offer.
    """
    return [_rosbag2_profile(
        qos.history.short_key, qos.depth, qos.reliability.short_key,
        qos.durability.short_key, qos.deadline.nanoseconds, qos.lifespan.nanoseconds,
        qos.liveliness.short_key, qos.liveliness_lease_duration.nanoseconds,
        qos.avoid_ros_namespace_conventions)]


def offered_qos(reliability: str = 'reliable', durability: str = 'volatile',
                depth: int = 10) -> List[dict]:
    """
    Return the offered QoS of a keep-last publisher, as :func:`qos_profiles` lists it.

    For bags written without ROS (replay's estimates, the simulated rig's
    logs): rclpy's defaults for the rest (no deadline, lifespan or lease,
    system-default liveliness).
    """
    return [_rosbag2_profile('keep_last', depth, reliability, durability, 0, 0,
                             'system_default', 0, False)]


def _yaml(data) -> str:
    return yaml.dump(data, Dumper=_YAML_DUMPER, sort_keys=False,
                     default_flow_style=False).rstrip('\n')


class _Topic:
    """What the bag keeps of a topic: type, definition, hash, QoS and message counts."""

    def __init__(self, name: str, type_name: str, qos: Optional[List[dict]]):
        package, short = _split_type_name(type_name)
        self.name = name
        self.type_name = f'{package}/msg/{short}'
        self.definition = message_definition(self.type_name)
        self.type_hash = type_hash(self.type_name)
        self.qos = list(qos or [])  # [] is what rosbag2 stores when it does not know them
        # the channel metadata of every file: dumped once, not at each split (~0.1 ms a topic)
        self.qos_yaml = _yaml(self.qos)
        self.message_count = 0      # in complete chunks of the bag's files
        self.pending = 0            # in the chunk being built
        self.dropped = 0            # in no file (suspended, or a chunk that could not be written)

    def record_bytes(self) -> int:
        """Return about what its schema and channel records take in a file."""
        return (2 * len(self.type_name) + len(self.definition) + len(self.name)
                + len(self.qos_yaml) + len(self.type_hash) + 200)


class _Span:
    """Message count and log time span of some messages."""

    def __init__(self):
        self.message_count = 0
        self.start_ns = 0
        self.end_ns = 0

    def add(self, log_time_ns: int) -> None:
        if self.message_count == 0 or log_time_ns < self.start_ns:
            self.start_ns = log_time_ns
        self.end_ns = max(self.end_ns, log_time_ns)
        self.message_count += 1

    def merge(self, other: '_Span') -> None:
        if other.message_count == 0:
            return
        if self.message_count == 0 or other.start_ns < self.start_ns:
            self.start_ns = other.start_ns
        self.end_ns = max(self.end_ns, other.end_ns)
        self.message_count += other.message_count


class _FileStats(_Span):
    """What one file of the bag holds: messages of complete chunks, and bytes."""

    def __init__(self, path: Path):
        super().__init__()
        self.path = path
        self.bytes = 0

    def as_rosbag2(self) -> dict:
        return {'path': self.path.name,
                'starting_time': {'nanoseconds_since_epoch': self.start_ns},
                'duration': {'nanoseconds': self.end_ns - self.start_ns},
                'message_count': self.message_count}


class FileSink:
    """
    A file of the bag as mcap writes it: kept in memory until a flush, then all of it or nothing.

    :meth:`write` keeps the bytes (it never fails); :meth:`flush` writes them
    at the end of the file, and when that fails cuts the file back to what
    the previous flush left (:attr:`size`), keeps the bytes for the next
    flush (or :meth:`discard`) and raises the OSError. :meth:`tell` counts
    the kept bytes too: it is the offset mcap gives its records. The file is
    made here, never over an existing one (FileExistsError).

    :meth:`write_at` is the one call that writes to the file: a test makes a
    full disk by overriding it. Not a ``RawIOBase``, which mcap would buffer.
    """

    def __init__(self, path: os.PathLike):
        self.path = Path(path)
        self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o666)
        #: Bytes in the file: those of the flushes that succeeded.
        self.size = 0
        self._kept: List[bytes] = []
        self._kept_bytes = 0

    @property
    def closed(self) -> bool:
        """Return whether the file is closed."""
        return self._fd < 0

    def write(self, data: bytes) -> int:
        """Keep ``data`` for the next flush; return its length."""
        self._kept.append(bytes(data))  # mcap passes bytes: no copy
        self._kept_bytes += len(data)
        return len(data)

    def tell(self) -> int:
        """Return the offset the next byte given will have in the file."""
        return self.size + self._kept_bytes

    def flush(self) -> None:
        """Write the kept bytes (OSError: none of them stays in the file, all are kept)."""
        offset = self.size
        try:
            for data in self._kept:
                view = memoryview(data)
                while view:
                    done = self.write_at(view, offset)
                    if done <= 0:
                        raise OSError(errno.EIO, f'{self.path}: no byte written')
                    view = view[done:]
                    offset += done
        except OSError:
            with contextlib.suppress(OSError):  # a reader stops at the cut anyway
                os.ftruncate(self._fd, self.size)
            raise
        self.size = offset
        self.discard()

    def write_at(self, data: memoryview, offset: int) -> int:
        """Write some of ``data`` at ``offset`` of the file; return how many bytes."""
        return os.pwrite(self._fd, data, offset)

    def discard(self) -> None:
        """Forget the bytes not written."""
        self._kept = []
        self._kept_bytes = 0

    def close(self) -> None:
        """Close the file (what was not flushed is not in it)."""
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1


def _free_bytes(path: Path) -> int:
    return shutil.disk_usage(path).free


@dataclass(frozen=True)
class BagHealth:
    """What a :class:`BagWriter` has done so far (:meth:`BagWriter.health`)."""

    state: str                   # RECORDING, SUSPENDED or CLOSED
    messages_written: int        # in complete chunks of the bag's files
    messages_pending: int        # in the chunk being built, written when it closes
    messages_dropped: int        # given to write() but in no file (suspended, or a lost chunk)
    dropped_by_topic: Dict[str, int]
    bytes_written: int           # in the bag's files, all of them
    current_file: Optional[Path]  # None while suspended and once closed
    files: Tuple[Path, ...]      # every file of the bag, in order
    errors: int                  # OSErrors met: writing, closing, reopening, metadata.yaml
    last_error: str              # '' before the first
    last_error_time_s: Optional[float]   # when it happened (time.time(), s)
    free_bytes: Optional[int]    # free at the destination now (None: not measurable)
    reserve_bytes: int           # the reserve held now (0: freed, or none in raise mode)
    changes: int                 # state changes and errors so far: a new value is news
    time_s: float                # time.monotonic() of the snapshot, for rates of bytes_written


class BagWriter:
    """
    Write messages to a rosbag2-compatible MCAP file, a series of them, or a bag directory.

    ``metadata`` maps record names to string dictionaries, stored as MCAP
    Metadata records at the start of every file (so that a run can be
    reproduced from a file alone, even a cut one). Without splitting the bag
    is the one file ``path``; with ``split_bytes`` or ``split_duration_s`` it
    is ``<stem>_0.mcap``, ``<stem>_1.mcap``, ... next to ``path`` (rosbag2's
    naming), each a complete MCAP file, the next begun before a message once
    the current file holds ``split_bytes`` or that message is
    ``split_duration_s`` of log time after the file's first.

    With ``directory`` the bag is the rosbag2 bag directory ``path``, made
    here (its parent must exist): the files ``<name>_0.mcap``, ... inside it,
    split or not, and ``metadata.yaml`` (see the module docstring).

    Write errors (see the module docstring): ``on_error='raise'`` raises
    them; ``'suspend'`` finishes the file with the space of a reserve of
    ``reserve_bytes``, drops messages until the destination has
    ``reserve_bytes + resume_margin_bytes`` free again, then goes on in the
    next file; :meth:`health` tells what happened and ``on_state_change``
    (called with the new :class:`BagHealth`, from the writing thread or the
    writer's own, never holding the writer's lock) is called at every change
    of state and at every error. ``sink`` opens a file of the bag
    (:class:`FileSink` or a subclass of it) and ``free_space`` measures the
    free bytes of a folder: both are there for tests.

    Existing files and directories are never overwritten (FileExistsError).
    Safe to use from several threads.
    """

    def __init__(self, path: os.PathLike, *,
                 metadata: Optional[Dict[str, Dict[str, str]]] = None,
                 chunk_bytes: int = DEFAULT_CHUNK_BYTES, flush_interval_s: float = 1.0,
                 split_bytes: Optional[int] = None, split_duration_s: Optional[float] = None,
                 compression: str = 'zstd', directory: bool = False,
                 on_error: str = 'raise', reserve_bytes: int = DEFAULT_RESERVE_BYTES,
                 resume_margin_bytes: int = DEFAULT_RESUME_MARGIN_BYTES,
                 on_state_change: Optional[Callable[[BagHealth], None]] = None,
                 sink: Callable[[Path], FileSink] = FileSink,
                 free_space: Callable[[Path], int] = _free_bytes):
        if compression not in COMPRESSIONS:
            raise ValueError(f'compression {compression!r}: expected one of '
                             + ', '.join(COMPRESSIONS))
        if not flush_interval_s > 0 or chunk_bytes <= 0:
            raise ValueError('flush_interval_s and chunk_bytes must be positive')
        if (split_bytes is not None and split_bytes <= 0) or (
                split_duration_s is not None and not split_duration_s > 0):
            raise ValueError('split_bytes and split_duration_s must be positive')
        if on_error not in ON_ERROR:
            raise ValueError(f'on_error {on_error!r}: expected one of ' + ', '.join(ON_ERROR))
        if reserve_bytes < 0 or resume_margin_bytes < 0:
            raise ValueError('reserve_bytes and resume_margin_bytes must not be negative')
        self._metadata = {name: dict(values) for name, values in (metadata or {}).items()}
        if ROSBAG2_METADATA_NAME in self._metadata:
            raise ValueError(f'metadata name {ROSBAG2_METADATA_NAME!r} is reserved for rosbag2')
        for name, values in self._metadata.items():
            if not all(isinstance(x, str) for kv in values.items() for x in kv):
                raise ValueError(f'metadata {name!r}: keys and values must be strings')
        self._path = Path(path)
        self._directory = directory
        self._destination = self._path if directory else self._path.parent
        self._splitting = split_bytes is not None or split_duration_s is not None
        self._split_bytes = split_bytes
        self._split_duration_ns = (None if split_duration_s is None
                                   else round(split_duration_s * 1e9))
        self._chunk_bytes = chunk_bytes
        self._flush_interval_s = flush_interval_s
        self._flush_interval_ns = round(flush_interval_s * 1e9)
        self._compression = COMPRESSIONS[compression]
        self._suspending = on_error == 'suspend'
        self._reserve_path = None
        if self._suspending and reserve_bytes:
            self._reserve_path = (self._path / RESERVE_NAME if directory else
                                  self._path.with_name(f'.{self._path.name}{RESERVE_NAME}'))
        self._reserve_bytes = reserve_bytes
        # on a small file system (a few MiB) the reserve and the room to resume in scale with
        # it: at most half of it each, or nothing would ever be recorded there
        try:
            half = shutil.disk_usage(self._path.parent).total // 2   # the bag is not made yet
        except OSError:
            half = reserve_bytes + resume_margin_bytes
        self._resume_free_bytes = min(reserve_bytes + resume_margin_bytes, half)
        self._on_state_change = on_state_change
        self._make_sink = sink
        self._free_space = free_space
        self._topics: Dict[str, _Topic] = {}
        self._files: List[_FileStats] = []
        self._lock = threading.Lock()
        self._closed = False
        self._error: Optional[BaseException] = None     # raise mode: what every call raises
        self._state = RECORDING
        self._sink: Optional[FileSink] = None
        self._mcap: Optional[Writer] = None
        self._chunk = _Span()           # the messages of the chunk being built
        self._pending_bytes = 0
        self._tail_built = False        # the current file's summary is in its sink
        self._chunks_in_file = 0
        self._definition_bytes = 0      # schema and channel records of a file, about
        self._bag_yaml_bytes = 0
        self._reserve_held = 0
        self._written = self._dropped = self._bytes_written = 0
        self._errors = self._changes = 0
        self._last_error = ''
        self._last_error_time_s: Optional[float] = None
        self._notice = False            # on_state_change is due
        self._next_check_s = 0.0
        if directory:
            # one call that fails on anything already there, as ros2 bag record refuses an
            # existing output folder, even an empty one
            self._path.mkdir()
        try:
            self._open_file()
        except OSError as exc:
            # a full disk at the start is one more fault to wait out; a taken name is not
            if not self._suspending or exc.errno not in (errno.ENOSPC, errno.EDQUOT):
                self._release_reserve()
                raise
            self._note_error(exc, f'opening {self._path}')
            self._suspend()
        self._stop = threading.Event()
        self._flusher = threading.Thread(target=self._flush_idle, name='bag-flush', daemon=True)
        self._flusher.start()
        self._deliver(self._take_notice())

    @property
    def paths(self) -> List[Path]:
        """Return the files of the bag so far, in order."""
        with self._lock:
            return [f.path for f in self._files]

    @property
    def topics(self) -> Dict[str, str]:
        """Return the topics added so far and their types."""
        with self._lock:
            return {name: t.type_name for name, t in self._topics.items()}

    def health(self) -> BagHealth:
        """Return what the writer has done so far and its state (cheap: a lock and a statvfs)."""
        free = self._measure_free()  # a system call: outside the lock
        with self._lock:
            return BagHealth(
                state=self._state, messages_written=self._written,
                messages_pending=self._chunk.message_count, messages_dropped=self._dropped,
                dropped_by_topic={t.name: t.dropped for t in self._topics.values()
                                  if t.dropped},
                bytes_written=self._bytes_written,
                current_file=None if self._sink is None else self._sink.path,
                files=tuple(f.path for f in self._files), errors=self._errors,
                last_error=self._last_error, last_error_time_s=self._last_error_time_s,
                free_bytes=free, reserve_bytes=self._reserve_held, changes=self._changes,
                time_s=time.monotonic())

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self.close()

    def add_topic(self, topic: str, msg_type_name: str,
                  qos: Optional[List[dict]] = None) -> None:
        """
        Declare a topic of type ``msg_type_name`` ('pkg/msg/Type').

        ``qos``: its publishers' offered QoS, as :func:`qos_profiles` or
        :func:`offered_qos` return them.
        """
        entry = _Topic(topic, msg_type_name, qos)  # reads the definition outside the lock
        with self._lock:
            self._check_usable()
            if topic in self._topics:
                raise ValueError(f'topic {topic!r} was already added')
            self._topics[topic] = entry
            self._definition_bytes += entry.record_bytes()
            if self._mcap is not None:  # else the next file registers it
                self._register(entry)

    def write(self, topic: str, data: bytes, log_time_ns: int,
              publish_time_ns: Optional[int] = None) -> None:
        """
        Write one message, serialised (CDR; rclpy's ``serialize_message`` or :mod:`.cdr`).

        ``log_time_ns`` is the receive time (rosbag2's recv_timestamp),
        ``publish_time_ns`` the send time (the log time when not given).
        While suspended the message is dropped (counted).
        """
        with self._lock:
            self._check_usable()
            entry = self._topics.get(topic)
            if entry is None:
                raise ValueError(f'topic {topic!r} was not added')
            if self._state == SUSPENDED:
                self._maybe_resume()
            elif self._splitting and self._split_due(log_time_ns):
                self._split()
            if self._sink is None:
                entry.dropped += 1
                self._dropped += 1
            else:
                self._add(entry, data, log_time_ns, publish_time_ns)
            notice = self._take_notice()
        self._deliver(notice)

    def close(self) -> BagHealth:
        """
        Write the last chunk, the rosbag2 metadata and the summary, close the file; return health.

        Raise mode: an OSError met now or before is raised. Suspend mode: it
        is in the health returned.
        """
        with self._lock:
            closed, self._closed = self._closed, True
        if closed:
            return self.health()
        self._stop.set()
        self._flusher.join()
        with self._lock:
            try:
                if self._sink is not None:
                    try:
                        self._end_file()
                    except OSError as exc:  # raise mode
                        self._note_error(exc, f'closing {self._files[-1].path}')
                        self._error = self._error or exc
                        raise
                self._rewrite_metadata_yaml()
            finally:
                self._release_reserve()
                self._set_state(CLOSED)
                notice = self._take_notice()
        self._deliver(notice)
        if self._error is not None:
            raise OSError(f'writing {self._files[-1].path} failed') from self._error
        return self.health()

    # ------------------------------------------------------------ writing
    def _check_usable(self) -> None:
        if self._closed:
            raise ValueError('the bag writer is closed')
        if self._error is not None:
            raise OSError(f'writing {self._files[-1].path} failed') from self._error

    def _add(self, entry: _Topic, data: bytes, log_time_ns: int,
             publish_time_ns: Optional[int]) -> None:
        self._mcap.add_message(
            self._channel_ids[entry.name], log_time_ns, data,
            log_time_ns if publish_time_ns is None else publish_time_ns)
        entry.pending += 1
        self._chunk.add(log_time_ns)
        if self._pending_bytes == 0:
            self._pending_first_log_ns = log_time_ns
            self._pending_since_s = time.monotonic()
        self._pending_bytes += len(data) + _MESSAGE_RECORD_OVERHEAD_BYTES
        if (self._pending_bytes >= self._chunk_bytes
                or log_time_ns - self._pending_first_log_ns >= self._flush_interval_ns
                or time.monotonic() - self._pending_since_s >= self._flush_interval_s):
            self._close_chunk_or_fault()

    def _close_chunk_or_fault(self) -> None:
        try:
            self._close_chunk()
        except OSError as exc:
            self._fault(exc, f'writing {self._sink.path}')

    def _close_chunk(self) -> None:
        self._mcap.flush()  # the chunk goes to the sink, whose flush writes it or raises
        self._commit()

    def _commit(self) -> None:
        """Count what the sink's last flush put in the file."""
        current = self._files[-1]
        self._bytes_written += self._sink.size - current.bytes
        current.bytes = self._sink.size
        self._pending_bytes = 0
        if self._chunk.message_count == 0:
            return
        current.merge(self._chunk)
        self._written += self._chunk.message_count
        self._chunk = _Span()
        for entry in self._topics.values():
            entry.message_count += entry.pending
            entry.pending = 0
        self._chunks_in_file += 1
        if self._reserve_held and self._close_cost() > self._reserve_held:
            with contextlib.suppress(OSError):  # the disk is nearly full: the next write says so
                self._ensure_reserve()

    def _split_due(self, log_time_ns: int) -> bool:
        current = self._files[-1]
        if current.message_count == 0 and self._chunk.message_count == 0:
            return False  # never leave a file without messages behind
        start_ns = current.start_ns if current.message_count else self._chunk.start_ns
        return ((self._split_bytes is not None and current.bytes >= self._split_bytes)
                or (self._split_duration_ns is not None
                    and log_time_ns - start_ns >= self._split_duration_ns))

    def _split(self) -> None:
        try:
            clean = self._end_file()
        except OSError as exc:  # raise mode
            self._fault(exc, f'closing {self._files[-1].path}')
        if not clean:
            self._suspend()
            return
        try:
            self._open_file()
        except OSError as exc:
            self._fault(exc, 'opening the next file')

    def _next_path(self) -> Path:
        k = len(self._files)
        if self._directory:
            return self._path / f'{self._path.name}_{k}.mcap'
        if self._splitting or k:
            stem = self._path.name[:-5] if self._path.name.endswith('.mcap') else self._path.name
            return self._path.with_name(f'{stem}_{k}.mcap')
        return self._path

    def _open_file(self) -> None:
        """Begin the next file of the bag, listed in metadata.yaml; on OSError none is left."""
        path = self._next_path()
        self._chunks_in_file = 0
        self._ensure_reserve()
        sink = self._make_sink(path)
        self._files.append(_FileStats(path))
        self._sink = sink
        try:
            # Chunks are closed by this class (size, log time, wall time): the mcap writer's own
            # size limit is put out of reach so that there is one place deciding it.
            self._mcap = Writer(sink, chunk_size=2 ** 62, compression=self._compression)
            self._mcap.start(profile='ros2', library=LIBRARY)
            self._tail_built = False
            self._schema_ids: Dict[str, int] = {}
            self._channel_ids: Dict[str, int] = {}
            for entry in self._topics.values():
                self._register(entry)
            for name, values in self._metadata.items():
                self._mcap.add_metadata(name, values)
            bag_yaml = self._write_rosbag2_metadata()
            self._close_chunk()  # header and metadata reach the disk now, before any message
            if self._directory:  # the new file is listed before it holds a message
                self._write_metadata_yaml(bag_yaml)
        except BaseException:
            sink.close()
            self._files.pop()
            self._sink = self._mcap = None
            with contextlib.suppress(OSError):
                path.unlink()
            raise

    def _register(self, entry: _Topic) -> None:
        schema_id = self._schema_ids.get(entry.type_name)
        if schema_id is None:
            schema_id = self._mcap.register_schema(
                entry.type_name, 'ros2msg', entry.definition.encode())
            self._schema_ids[entry.type_name] = schema_id
        self._channel_ids[entry.name] = self._mcap.register_channel(
            entry.name, 'cdr', schema_id,
            {'offered_qos_profiles': entry.qos_yaml, 'topic_type_hash': entry.type_hash})

    def _finish_file(self) -> None:
        """Write the file's last chunk, rosbag2 record and summary (again after an OSError)."""
        if not self._tail_built:
            self._close_chunk()
            self._write_rosbag2_metadata()
            self._mcap.finish()  # into the sink: written by its flush
            self._tail_built = True
        self._sink.flush()
        self._commit()

    def _end_file(self) -> bool:
        """
        Finish and close the current file; return whether that went without an error.

        Raise mode: the OSError is raised. Suspend mode: the reserve is freed and
        the file finished with its space; when there is no reserve to free or it
        was not enough, the file stays cut at its last complete chunk and the
        messages of the chunk that could not be written are counted as dropped.
        """
        clean = True
        try:
            while True:
                try:
                    self._finish_file()
                    return clean
                except OSError as exc:
                    if not self._suspending:
                        raise
                    self._note_error(exc, f'closing {self._sink.path}')
                    clean = False
                    if not self._release_reserve():
                        self._lose_chunk()
                        return False
        finally:
            self._sink.close()
            self._sink = self._mcap = None

    def _lose_chunk(self) -> None:
        self._sink.discard()
        for entry in self._topics.values():
            entry.dropped += entry.pending
            entry.pending = 0
        self._dropped += self._chunk.message_count
        self._chunk = _Span()
        self._pending_bytes = 0

    # ------------------------------------------------------------ faults
    def _note_error(self, exc: OSError, doing: str) -> None:
        self._errors += 1
        self._last_error = f'{doing}: {exc.strerror or exc}'
        self._last_error_time_s = time.time()
        self._changes += 1
        self._notice = True

    def _set_state(self, state: str) -> None:
        if state != self._state:
            self._state = state
            self._changes += 1
            self._notice = True

    def _fault(self, exc: OSError, doing: str) -> None:
        """Deal with an OSError met while recording: raise it (raise mode), or suspend."""
        self._note_error(exc, doing)
        if not self._suspending:
            self._error = exc
            raise exc
        self._suspend()

    def _suspend(self) -> None:
        """Finish the file with the reserve's space, update metadata.yaml, drop messages."""
        self._release_reserve()
        if self._sink is not None:
            self._end_file()
        self._rewrite_metadata_yaml()
        self._set_state(SUSPENDED)
        self._next_check_s = time.monotonic() + RESUME_CHECK_S

    def _maybe_resume(self) -> None:
        """Open the next file once there is room again (measured at most once a second)."""
        now = time.monotonic()
        if now < self._next_check_s:
            return
        self._next_check_s = now + RESUME_CHECK_S
        free = self._measure_free()
        if free is None or free < max(self._resume_free_bytes, 2 * self._close_cost()):
            return
        try:
            self._open_file()
        except OSError as exc:
            self._note_error(exc, 'resuming')
            self._release_reserve()
            return
        self._set_state(RECORDING)

    def _measure_free(self) -> Optional[int]:
        try:
            return self._free_space(self._destination)
        except OSError:
            return None

    def _close_cost(self) -> int:
        """Return about what closing the current file may write: its last chunk, the summary."""
        per_chunk = _CHUNK_INDEX_BYTES + _CHUNK_INDEX_CHANNEL_BYTES * len(self._topics)
        return (self._chunk_bytes + 2 * self._definition_bytes + self._chunks_in_file * per_chunk
                + 3 * self._bag_yaml_bytes + _CLOSE_SLACK_BYTES)

    def _ensure_reserve(self) -> None:
        """
        Hold the reserve: ``reserve_bytes``, or twice the close of a file that needs more.

        Never more than half of what is free (the reserve held counted as free), but never
        less than the close: a small file system still records, and closes cleanly.
        """
        if self._reserve_path is None:
            return
        need = self._close_cost()
        free = self._measure_free()
        target = self._reserve_bytes if free is None else \
            min(self._reserve_bytes, (free + self._reserve_held) // 2)
        if self._reserve_held >= max(target, need):
            return
        if need <= target:
            size = target
        else:   # twice the close when there is room for it: a long file grows it seldom
            room = 2 * need if free is None else min(2 * need, free + self._reserve_held)
            size = max(need, room)
        fd = os.open(self._reserve_path, os.O_WRONLY | os.O_CREAT | os.O_CLOEXEC, 0o600)
        try:
            os.posix_fallocate(fd, 0, size)
        except OSError:
            with contextlib.suppress(OSError):  # no half reserve: what was held, or nothing
                if self._reserve_held:
                    os.ftruncate(fd, self._reserve_held)
                else:
                    self._reserve_path.unlink()
            raise
        finally:
            os.close(fd)
        self._reserve_held = size

    def _release_reserve(self) -> bool:
        """Delete the reserve; return whether there was one to free."""
        if not self._reserve_held:
            return False
        self._reserve_held = 0
        try:
            self._reserve_path.unlink()
        except FileNotFoundError:
            pass                        # someone deleted it: its space is free all the same
        except OSError as exc:
            self._note_error(exc, f'deleting {self._reserve_path}')
            return False
        return True

    def _take_notice(self) -> bool:
        notice, self._notice = self._notice, False
        return notice

    def _deliver(self, notice: bool) -> None:
        """Call on_state_change (never holding the lock: it may ask for the health)."""
        if not notice or self._on_state_change is None:
            return
        try:
            self._on_state_change(self.health())
        except Exception as exc:  # noqa: B902 - the caller's bug must not stop the writing
            with self._lock:
                self._errors += 1
                self._last_error = f'on_state_change: {type(exc).__name__}: {exc}'

    # ------------------------------------------------------------ rosbag2 metadata
    def _bag_metadata(self) -> dict:
        """Return the bag's rosbag2 BagMetadata so far (rosbag2_storage yaml.hpp, version 9)."""
        files = [f for f in self._files if f.message_count]
        start_ns = min((f.start_ns for f in files), default=0)
        end_ns = max((f.end_ns for f in files), default=0)
        return {
            'version': ROSBAG2_METADATA_VERSION,
            'storage_identifier': 'mcap',
            'duration': {'nanoseconds': end_ns - start_ns},
            'starting_time': {'nanoseconds_since_epoch': start_ns},
            'message_count': sum(f.message_count for f in self._files),
            'topics_with_message_count': [
                {'topic_metadata': {'name': t.name, 'type': t.type_name,
                                    'serialization_format': 'cdr',
                                    'offered_qos_profiles': t.qos,
                                    'type_description_hash': t.type_hash},
                 'message_count': t.message_count}
                for t in self._topics.values()],
            # chunk compression is the storage's business, not rosbag2's compression
            'compression_format': '',
            'compression_mode': '',
            'relative_file_paths': [f.path.name for f in self._files],
            'files': [f.as_rosbag2() for f in self._files],
            'custom_data': {},
            # the ROS wheels of requirements.txt are Jazzy's; a sourced ROS sets this
            'ros_distro': os.environ.get('ROS_DISTRO', 'jazzy'),
        }

    def _write_rosbag2_metadata(self) -> str:
        """Add the bag's metadata to the current file (rosbag2's record); return its YAML."""
        bag_yaml = _yaml(self._bag_metadata())
        self._bag_yaml_bytes = len(bag_yaml)
        self._mcap.add_metadata(ROSBAG2_METADATA_NAME, {ROSBAG2_METADATA_KEY: bag_yaml})
        return bag_yaml

    def _rewrite_metadata_yaml(self) -> None:
        """Bring a bag directory's metadata.yaml up to date (suspend mode: an error is noted)."""
        if not self._directory or not self._files:
            return
        try:
            self._write_metadata_yaml(_yaml(self._bag_metadata()))
        except OSError as exc:
            if not self._suspending:
                raise
            self._note_error(exc, f'writing {ROSBAG2_METADATA}')

    def _write_metadata_yaml(self, bag_yaml: str) -> None:
        """Replace the directory's metadata.yaml whole (a reader never sees half of one)."""
        # the record's YAML, indented under the root key (a block mapping nests so): PyYAML's
        # representer is the dear part of a split, about 10 ms for the recorder's 32 topics
        text = f'{ROSBAG2_METADATA_ROOT}:\n' + textwrap.indent(bag_yaml, '  ') + '\n'
        target = self._path / ROSBAG2_METADATA
        temporary = target.with_name(f'.{ROSBAG2_METADATA}.partial')
        try:
            temporary.write_text(text)
            os.replace(temporary, target)
        except OSError:
            with contextlib.suppress(OSError):
                temporary.unlink()
            raise

    def _flush_idle(self) -> None:
        """
        Close the chunk when its oldest message waited ``flush_interval_s`` (no new message).

        While suspended, look for room to resume in.
        """
        period_s = min(self._flush_interval_s * _IDLE_CHECK_FRACTION, RESUME_CHECK_S)
        while not self._stop.wait(period_s):
            with self._lock:
                if self._closed or self._error is not None:
                    continue
                if self._state == SUSPENDED:
                    self._maybe_resume()
                elif (self._pending_bytes
                      and time.monotonic() - self._pending_since_s >= self._flush_interval_s):
                    with contextlib.suppress(OSError):  # raise mode: the next write or close
                        self._close_chunk_or_fault()
                notice = self._take_notice()
            self._deliver(notice)
