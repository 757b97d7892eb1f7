"""
When a bag goes on in a new file, what each file is called, and what each one holds.

Without splitting a bag is the one file ``path``; with ``split_bytes`` or
``split_duration_s`` it is ``<stem>_0.mcap``, ``<stem>_1.mcap``, ... next to
``path`` (rosbag2's naming); a bag directory holds ``<name>_0.mcap``, ...
split or not. A suspended writer that resumes goes on in the next name
(a lone ``run.mcap`` in ``run_1.mcap``, ...).
"""

from pathlib import Path
from typing import Optional


class Span:
    """Message count and log time span of some messages."""

    def __init__(self):
        self.message_count = 0
        self.start_ns = 0
        self.end_ns = 0

    def add(self, log_time_ns: int) -> None:
        """Count one message logged at ``log_time_ns``."""
        if self.message_count == 0 or log_time_ns < self.start_ns:
            self.start_ns = log_time_ns
        self.end_ns = max(self.end_ns, log_time_ns)
        self.message_count += 1

    def merge(self, other: 'Span') -> None:
        """Count the messages of ``other`` too."""
        if other.message_count == 0:
            return
        if self.message_count == 0 or other.start_ns < self.start_ns:
            self.start_ns = other.start_ns
        self.end_ns = max(self.end_ns, other.end_ns)
        self.message_count += other.message_count


class FileStats(Span):
    """What one file of the bag holds: messages of complete chunks, and bytes."""

    def __init__(self, path: Path):
        super().__init__()
        self.path = path
        self.bytes = 0

    def as_rosbag2(self) -> dict:
        """Return the file's entry of rosbag2's BagMetadata ``files``."""
        return {'path': self.path.name,
                'starting_time': {'nanoseconds_since_epoch': self.start_ns},
                'duration': {'nanoseconds': self.end_ns - self.start_ns},
                'message_count': self.message_count}


class SplitPolicy:
    """The files of a bag at ``path``: their names and when the next one begins."""

    def __init__(self, path: Path, directory: bool, split_bytes: Optional[int],
                 split_duration_s: Optional[float]):
        self._path = path
        self._directory = directory
        self.splitting = split_bytes is not None or split_duration_s is not None
        self._split_bytes = split_bytes
        self._split_duration_ns = (None if split_duration_s is None
                                   else round(split_duration_s * 1e9))

    def path_of(self, k: int) -> Path:
        """Return the path of the bag's file number ``k`` (from 0)."""
        if self._directory:
            return self._path / f'{self._path.name}_{k}.mcap'
        if self.splitting or k:
            stem = self._path.name[:-5] if self._path.name.endswith('.mcap') else self._path.name
            return self._path.with_name(f'{stem}_{k}.mcap')
        return self._path

    def due(self, current: FileStats, chunk: Span, log_time_ns: int) -> bool:
        """Return whether a message at ``log_time_ns`` begins the next file."""
        if current.message_count == 0 and chunk.message_count == 0:
            return False  # never leave a file without messages behind
        start_ns = current.start_ns if current.message_count else chunk.start_ns
        return ((self._split_bytes is not None and current.bytes >= self._split_bytes)
                or (self._split_duration_ns is not None
                    and log_time_ns - start_ns >= self._split_duration_ns))
