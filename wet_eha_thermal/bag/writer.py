"""
Record ROS 2 messages to MCAP files that rosbag2 (Jazzy) reads as its own.

What this writes is what rosbag2's MCAP storage plugin writes (the details
and where they were checked: :mod:`.rosbag2`): profile ``ros2``; one schema
per type and one channel per topic, message encoding ``cdr``; a Metadata
record ``rosbag2`` with the bag's BagMetadata, written when a file is opened
and again when it is closed (readers keep the last one); as a bag directory
(``directory=True``, what ``ros2 bag record -s mcap`` makes) the files
``<dir name>_0.mcap``, ``_1``, ... inside it (:mod:`.split`) and
``metadata.yaml`` with the same BagMetadata (the tests read it with rosbags,
an independent rosbag2 reader).

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
import os
from pathlib import Path
import threading
import time
from typing import Callable, Dict, List, Optional, Tuple

from mcap.writer import CompressionType, LIBRARY_IDENTIFIER, Writer

# rosbag2's and the sink's names are imported from here by the recorder, the tools and the tests
from .rosbag2 import (bag_metadata, message_definition, offered_qos,  # noqa: F401
                      qos_profiles, ROSBAG2_METADATA, ROSBAG2_METADATA_KEY,
                      ROSBAG2_METADATA_NAME, ROSBAG2_METADATA_ROOT, ROSBAG2_METADATA_VERSION,
                      to_yaml, Topic, type_hash, write_metadata_yaml)
from .sink import (FileSink, free_bytes, Reserve, RESERVE_NAME,  # noqa: F401
                   reserve_size, resume_free_bytes)
from .split import FileStats, Span, SplitPolicy

LIBRARY = f'wet_eha_thermal/{version("wet_eha_thermal")} ({LIBRARY_IDENTIFIER})'
DEFAULT_CHUNK_BYTES = 768 * 1024  # rosbag2's MCAP default (mcap C++ McapWriterOptions)
COMPRESSIONS = {'zstd': CompressionType.ZSTD, 'lz4': CompressionType.LZ4,
                'none': CompressionType.NONE}

# A record costs its data plus 9 bytes of opcode and length and 22 of message header.
_MESSAGE_RECORD_OVERHEAD_BYTES = 31
# The background check for messages waiting too long runs this often (fraction of the interval).
_IDLE_CHECK_FRACTION = 0.1

ON_ERROR = ('raise', 'suspend')
#: The states of :class:`BagHealth`.
RECORDING, SUSPENDED, CLOSED = 'recording', 'suspended', 'closed'
#: Space held back to finish a file when the disk is full, and free space asked for on top of it
#: before writing again (suspend mode).
DEFAULT_RESERVE_BYTES = 4 * 2 ** 20
DEFAULT_RESUME_MARGIN_BYTES = 16 * 2 ** 20
#: While suspended, the free space is measured this often (s).
RESUME_CHECK_S = 1.0
# What closing a file may write besides its last chunk, to size the reserve: a Chunk Index
# record of the summary is 85 bytes and 10 a channel (mcap records.py); the header-sized rest
# (statistics, metadata indexes, footer) and a large last message fit in the slack.
_CHUNK_INDEX_BYTES, _CHUNK_INDEX_CHANNEL_BYTES = 100, 10
_CLOSE_SLACK_BYTES = 64 * 1024


def _check_options(chunk_bytes: int, flush_interval_s: float, split_bytes: Optional[int],
                   split_duration_s: Optional[float], compression: str, on_error: str,
                   reserve_bytes: int, resume_margin_bytes: int) -> None:
    """Raise ValueError for the first option of :class:`BagWriter` out of its range."""
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


def _checked_metadata(metadata: Optional[Dict[str, Dict[str, str]]]) -> Dict[str, Dict[str, str]]:
    """Return a copy of the metadata records to store; ValueError if one cannot be stored."""
    records = {name: dict(values) for name, values in (metadata or {}).items()}
    if ROSBAG2_METADATA_NAME in records:
        raise ValueError(f'metadata name {ROSBAG2_METADATA_NAME!r} is reserved for rosbag2')
    for name, values in records.items():
        if not all(isinstance(x, str) for kv in values.items() for x in kv):
            raise ValueError(f'metadata {name!r}: keys and values must be strings')
    return records


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
                 free_space: Callable[[Path], int] = free_bytes):
        _check_options(chunk_bytes, flush_interval_s, split_bytes, split_duration_s,
                       compression, on_error, reserve_bytes, resume_margin_bytes)
        self._metadata = _checked_metadata(metadata)
        self._path = Path(path)
        self._directory = directory
        self._destination = self._path if directory else self._path.parent
        self._policy = SplitPolicy(self._path, directory, split_bytes, split_duration_s)
        self._chunk_bytes = chunk_bytes
        self._flush_interval_s = flush_interval_s
        self._flush_interval_ns = round(flush_interval_s * 1e9)
        self._compression = COMPRESSIONS[compression]
        self._suspending = on_error == 'suspend'
        reserve_path = None
        if self._suspending and reserve_bytes:
            reserve_path = (self._path / RESERVE_NAME if directory else
                            self._path.with_name(f'.{self._path.name}{RESERVE_NAME}'))
        self._reserve = Reserve(reserve_path)
        self._reserve_bytes = reserve_bytes
        self._resume_free_bytes = resume_free_bytes(   # the bag is not made yet: its parent
            self._path.parent, reserve_bytes, resume_margin_bytes)
        self._on_state_change = on_state_change
        self._make_sink = sink
        self._free_space = free_space
        self._init_state()
        self._begin()

    def _init_state(self) -> None:
        """Set up the state of a writer that has written nothing yet."""
        self._topics: Dict[str, Topic] = {}
        self._files: List[FileStats] = []
        self._lock = threading.Lock()
        self._closed = False
        self._error: Optional[BaseException] = None     # raise mode: what every call raises
        self._state = RECORDING
        self._sink: Optional[FileSink] = None
        self._mcap: Optional[Writer] = None
        self._chunk = Span()            # the messages of the chunk being built
        self._pending_bytes = 0
        self._tail_built = False        # the current file's summary is in its sink
        self._chunks_in_file = 0
        self._definition_bytes = 0      # schema and channel records of a file, about
        self._bag_yaml_bytes = 0
        self._written = self._dropped = self._bytes_written = 0
        self._errors = self._changes = 0
        self._last_error = ''
        self._last_error_time_s: Optional[float] = None
        self._notice = False            # on_state_change is due
        self._next_check_s = 0.0

    def _begin(self) -> None:
        """Make the bag directory, open the first file (or suspend), start the idle flusher."""
        if self._directory:
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
                free_bytes=free, reserve_bytes=self._reserve.held, changes=self._changes,
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
        entry = Topic(topic, msg_type_name, qos)  # reads the definition outside the lock
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
            elif self._policy.splitting and self._policy.due(self._files[-1], self._chunk,
                                                             log_time_ns):
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

    def _add(self, entry: Topic, data: bytes, log_time_ns: int,
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
        self._chunk = Span()
        for entry in self._topics.values():
            entry.message_count += entry.pending
            entry.pending = 0
        self._chunks_in_file += 1
        if self._reserve.held and self._close_cost() > self._reserve.held:
            with contextlib.suppress(OSError):  # the disk is nearly full: the next write says so
                self._ensure_reserve()

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

    def _open_file(self) -> None:
        """Begin the next file of the bag, listed in metadata.yaml; on OSError none is left."""
        path = self._policy.path_of(len(self._files))
        self._chunks_in_file = 0
        self._ensure_reserve()
        sink = self._make_sink(path)
        self._files.append(FileStats(path))
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
                write_metadata_yaml(self._path, bag_yaml)
        except BaseException:
            sink.close()
            self._files.pop()
            self._sink = self._mcap = None
            with contextlib.suppress(OSError):
                path.unlink()
            raise

    def _register(self, entry: Topic) -> None:
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
        self._chunk = Span()
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
        """Hold the reserve that finishes the current file (:func:`.sink.reserve_size`)."""
        if self._reserve.path is None:
            return
        size = reserve_size(self._reserve_bytes, self._close_cost(), self._measure_free(),
                            self._reserve.held)
        if size is not None:
            self._reserve.hold(size)

    def _release_reserve(self) -> bool:
        """Delete the reserve; return whether there was one to free."""
        if not self._reserve.held:
            return False
        try:
            self._reserve.free()
        except OSError as exc:
            self._note_error(exc, f'deleting {self._reserve.path}')
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
    def _write_rosbag2_metadata(self) -> str:
        """Add the bag's metadata to the current file (rosbag2's record); return its YAML."""
        bag_yaml = to_yaml(bag_metadata(self._topics.values(), self._files))
        self._bag_yaml_bytes = len(bag_yaml)
        self._mcap.add_metadata(ROSBAG2_METADATA_NAME, {ROSBAG2_METADATA_KEY: bag_yaml})
        return bag_yaml

    def _rewrite_metadata_yaml(self) -> None:
        """Bring a bag directory's metadata.yaml up to date (suspend mode: an error is noted)."""
        if not self._directory or not self._files:
            return
        try:
            write_metadata_yaml(self._path,
                                to_yaml(bag_metadata(self._topics.values(), self._files)))
        except OSError as exc:
            if not self._suspending:
                raise
            self._note_error(exc, f'writing {ROSBAG2_METADATA}')

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
