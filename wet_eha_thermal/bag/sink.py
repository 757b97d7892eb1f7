"""
Where a bag's bytes go: a file written whole at each flush, and the space held to finish it.

:class:`FileSink` is the file mcap writes through (see the write errors in
:mod:`.writer`); :class:`Reserve` the hidden file whose space finishes the
current file when the disk fills up (suspend mode), sized by
:func:`reserve_size`; :func:`resume_free_bytes` the free space a suspended
writer waits for.
"""

import contextlib
import errno
import os
from pathlib import Path
import shutil
from typing import List, Optional

#: The name of the reserve inside a bag directory (``.<file name>`` + it beside a lone file).
RESERVE_NAME = '.wet_eha_reserve'


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


def free_bytes(path: Path) -> int:
    """Return the free bytes of the file system holding ``path``."""
    return shutil.disk_usage(path).free


def resume_free_bytes(folder: Path, reserve_bytes: int, margin_bytes: int) -> int:
    """Return the free space to wait for before writing again: the reserve and a margin."""
    # on a small file system (a few MiB) the reserve and the room to resume in scale with
    # it: at most half of it each, or nothing would ever be recorded there
    try:
        half = shutil.disk_usage(folder).total // 2
    except OSError:
        half = reserve_bytes + margin_bytes
    return min(reserve_bytes + margin_bytes, half)


def reserve_size(reserve_bytes: int, need: int, free: Optional[int],
                 held: int) -> Optional[int]:
    """
    Return the reserve to hold, or None when the ``held`` one is enough.

    ``reserve_bytes``, or twice the close ``need`` when that is more; never
    more than half of what is ``free`` (the reserve held counted as free;
    None: not measurable), but never less than the close: a small file system
    still records, and closes cleanly.
    """
    target = reserve_bytes if free is None else min(reserve_bytes, (free + held) // 2)
    if held >= max(target, need):
        return None
    if need <= target:
        return target
    # twice the close when there is room for it: a long file grows it seldom
    room = 2 * need if free is None else min(2 * need, free + held)
    return max(need, room)


class Reserve:
    """A hidden file of allocated space, deleted to finish a file when the disk is full."""

    def __init__(self, path: Optional[Path]):
        #: None: no reserve is kept (raise mode, or a reserve of 0 bytes).
        self.path = path
        #: Bytes allocated now (0: none, or freed).
        self.held = 0

    def hold(self, size: int) -> None:
        """Allocate ``size`` bytes (OSError: what was held stays, or nothing)."""
        fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_CLOEXEC, 0o600)
        try:
            os.posix_fallocate(fd, 0, size)
        except OSError:
            with contextlib.suppress(OSError):  # no half reserve: what was held, or nothing
                if self.held:
                    os.ftruncate(fd, self.held)
                else:
                    self.path.unlink()
            raise
        finally:
            os.close(fd)
        self.held = size

    def free(self) -> None:
        """Delete the file (an OSError but its absence is raised; nothing is held then)."""
        self.held = 0
        try:
            self.path.unlink()
        except FileNotFoundError:
            pass                        # someone deleted it: its space is free all the same
