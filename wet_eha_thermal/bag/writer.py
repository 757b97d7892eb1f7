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
"""

from importlib.metadata import version
import json
import os
from pathlib import Path
import re
import sys
import textwrap
import threading
import time
from typing import Dict, List, Optional

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
    """What the bag keeps of a topic: type, definition, hash, QoS and message count."""

    def __init__(self, name: str, type_name: str, qos: Optional[List[dict]]):
        package, short = _split_type_name(type_name)
        self.name = name
        self.type_name = f'{package}/msg/{short}'
        self.definition = message_definition(self.type_name)
        self.type_hash = type_hash(self.type_name)
        self.qos = list(qos or [])  # [] is what rosbag2 stores when it does not know them
        # the channel metadata of every file: dumped once, not at each split (~0.1 ms a topic)
        self.qos_yaml = _yaml(self.qos)
        self.message_count = 0


class _FileStats:
    """Message count and log time span of one file of the bag."""

    def __init__(self, path: Path):
        self.path = path
        self.message_count = 0
        self.start_ns = 0
        self.end_ns = 0

    def add(self, log_time_ns: int) -> None:
        if self.message_count == 0 or log_time_ns < self.start_ns:
            self.start_ns = log_time_ns
        self.end_ns = max(self.end_ns, log_time_ns)
        self.message_count += 1

    def as_rosbag2(self) -> dict:
        return {'path': self.path.name,
                'starting_time': {'nanoseconds_since_epoch': self.start_ns},
                'duration': {'nanoseconds': self.end_ns - self.start_ns},
                'message_count': self.message_count}


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

    Existing files and directories are never overwritten (FileExistsError).
    Safe to use from several threads.
    """

    def __init__(self, path: os.PathLike, *,
                 metadata: Optional[Dict[str, Dict[str, str]]] = None,
                 chunk_bytes: int = DEFAULT_CHUNK_BYTES, flush_interval_s: float = 1.0,
                 split_bytes: Optional[int] = None, split_duration_s: Optional[float] = None,
                 compression: str = 'zstd', directory: bool = False):
        if compression not in COMPRESSIONS:
            raise ValueError(f'compression {compression!r}: expected one of '
                             + ', '.join(COMPRESSIONS))
        if not flush_interval_s > 0 or chunk_bytes <= 0:
            raise ValueError('flush_interval_s and chunk_bytes must be positive')
        if (split_bytes is not None and split_bytes <= 0) or (
                split_duration_s is not None and not split_duration_s > 0):
            raise ValueError('split_bytes and split_duration_s must be positive')
        self._metadata = {name: dict(values) for name, values in (metadata or {}).items()}
        if ROSBAG2_METADATA_NAME in self._metadata:
            raise ValueError(f'metadata name {ROSBAG2_METADATA_NAME!r} is reserved for rosbag2')
        for name, values in self._metadata.items():
            if not all(isinstance(x, str) for kv in values.items() for x in kv):
                raise ValueError(f'metadata {name!r}: keys and values must be strings')
        self._path = Path(path)
        self._directory = directory
        self._splitting = split_bytes is not None or split_duration_s is not None
        self._split_bytes = split_bytes
        self._split_duration_ns = (None if split_duration_s is None
                                   else round(split_duration_s * 1e9))
        self._chunk_bytes = chunk_bytes
        self._flush_interval_s = flush_interval_s
        self._flush_interval_ns = round(flush_interval_s * 1e9)
        self._compression = COMPRESSIONS[compression]
        self._topics: Dict[str, _Topic] = {}
        self._files: List[_FileStats] = []
        self._lock = threading.Lock()
        self._closed = False
        self._error: Optional[BaseException] = None
        if directory:
            # one call that fails on anything already there, as ros2 bag record refuses an
            # existing output folder, even an empty one
            self._path.mkdir()
        self._open_file()
        self._stop = threading.Event()
        self._flusher = threading.Thread(target=self._flush_idle, name='bag-flush', daemon=True)
        self._flusher.start()

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
            self._register(entry)

    def write(self, topic: str, data: bytes, log_time_ns: int,
              publish_time_ns: Optional[int] = None) -> None:
        """
        Write one message, serialised (CDR; rclpy's ``serialize_message`` or :mod:`.cdr`).

        ``log_time_ns`` is the receive time (rosbag2's recv_timestamp),
        ``publish_time_ns`` the send time (the log time when not given).
        """
        with self._lock:
            self._check_usable()
            entry = self._topics.get(topic)
            if entry is None:
                raise ValueError(f'topic {topic!r} was not added')
            if self._splitting and self._split_due(log_time_ns):
                self._close_file()
                self._open_file()
            self._mcap.add_message(
                self._channel_ids[topic], log_time_ns, data,
                log_time_ns if publish_time_ns is None else publish_time_ns)
            entry.message_count += 1
            self._files[-1].add(log_time_ns)
            if self._pending_bytes == 0:
                self._pending_first_log_ns = log_time_ns
                self._pending_since_s = time.monotonic()
            self._pending_bytes += len(data) + _MESSAGE_RECORD_OVERHEAD_BYTES
            if (self._pending_bytes >= self._chunk_bytes
                    or log_time_ns - self._pending_first_log_ns >= self._flush_interval_ns
                    or time.monotonic() - self._pending_since_s >= self._flush_interval_s):
                self._close_chunk()

    def close(self) -> None:
        """Write the last chunk, the rosbag2 metadata and the summary, and close the file."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        self._stop.set()
        self._flusher.join()
        with self._lock:
            bag_yaml = self._close_file()
            if self._directory and bag_yaml is not None:
                self._write_metadata_yaml(bag_yaml)
        if self._error is not None:
            raise OSError(f'writing {self._files[-1].path} failed') from self._error

    def _check_usable(self) -> None:
        if self._closed:
            raise ValueError('the bag writer is closed')
        if self._error is not None:
            raise OSError(f'writing {self._files[-1].path} failed') from self._error

    def _split_due(self, log_time_ns: int) -> bool:
        current = self._files[-1]
        if current.message_count == 0:
            return False  # never leave a file without messages behind
        return ((self._split_bytes is not None and self._file_bytes >= self._split_bytes)
                or (self._split_duration_ns is not None
                    and log_time_ns - current.start_ns >= self._split_duration_ns))

    def _open_file(self) -> None:
        if self._directory:
            path = self._path / f'{self._path.name}_{len(self._files)}.mcap'
        elif self._splitting:
            stem = self._path.name[:-5] if self._path.name.endswith('.mcap') else self._path.name
            path = self._path.with_name(f'{stem}_{len(self._files)}.mcap')
        else:
            path = self._path
        self._file = open(path, 'xb')
        self._files.append(_FileStats(path))
        # Chunks are closed by this class (size, log time, wall time): the mcap writer's own
        # size limit is put out of reach so that there is one place deciding it.
        self._mcap = Writer(self._file, chunk_size=2 ** 62, compression=self._compression)
        self._mcap.start(profile='ros2', library=LIBRARY)
        self._schema_ids: Dict[str, int] = {}
        self._channel_ids: Dict[str, int] = {}
        for entry in self._topics.values():
            self._register(entry)
        for name, values in self._metadata.items():
            self._mcap.add_metadata(name, values)
        bag_yaml = self._write_rosbag2_metadata()
        self._pending_bytes = 0
        self._close_chunk()  # header and metadata reach the disk now, before any message
        if self._directory:  # the new file is listed before it holds a message
            self._write_metadata_yaml(bag_yaml)

    def _register(self, entry: _Topic) -> None:
        schema_id = self._schema_ids.get(entry.type_name)
        if schema_id is None:
            schema_id = self._mcap.register_schema(
                entry.type_name, 'ros2msg', entry.definition.encode())
            self._schema_ids[entry.type_name] = schema_id
        self._channel_ids[entry.name] = self._mcap.register_channel(
            entry.name, 'cdr', schema_id,
            {'offered_qos_profiles': entry.qos_yaml, 'topic_type_hash': entry.type_hash})

    def _close_chunk(self) -> None:
        self._mcap.flush()
        self._file_bytes = self._file.tell()
        self._pending_bytes = 0

    def _close_file(self) -> Optional[str]:
        """Finish the current file; return the YAML of its last rosbag2 record (None: no file)."""
        if self._file.closed:  # the next file of a split could not be opened
            return None
        try:
            self._close_chunk()
            bag_yaml = self._write_rosbag2_metadata()
            self._mcap.finish()
        finally:
            self._file.close()
        return bag_yaml

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
        self._mcap.add_metadata(ROSBAG2_METADATA_NAME, {ROSBAG2_METADATA_KEY: bag_yaml})
        return bag_yaml

    def _write_metadata_yaml(self, bag_yaml: str) -> None:
        """Replace the directory's metadata.yaml whole (a reader never sees half of one)."""
        # the record's YAML, indented under the root key (a block mapping nests so): PyYAML's
        # representer is the dear part of a split, about 10 ms for the recorder's 32 topics
        text = f'{ROSBAG2_METADATA_ROOT}:\n' + textwrap.indent(bag_yaml, '  ') + '\n'
        target = self._path / ROSBAG2_METADATA
        temporary = target.with_name(f'.{ROSBAG2_METADATA}.partial')
        temporary.write_text(text)
        os.replace(temporary, target)

    def _flush_idle(self) -> None:
        """Close the chunk when its oldest message waited ``flush_interval_s`` (no new message)."""
        while not self._stop.wait(self._flush_interval_s * _IDLE_CHECK_FRACTION):
            with self._lock:
                if self._closed or self._error is not None or self._pending_bytes == 0:
                    continue
                if time.monotonic() - self._pending_since_s < self._flush_interval_s:
                    continue
                try:
                    self._close_chunk()
                except OSError as exc:  # disk full...: reported by the next write or close
                    self._error = exc
