"""
The files of a bag: one MCAP file, or a rosbag2 bag directory's, opened one after another.

A bag directory is what ``ros2 bag record -s mcap`` leaves when it splits:
``metadata.yaml`` and the files it lists; a folder without it is a bag when
its ``.mcap`` files are one split series (:func:`bag_files`).
"""

import os
from pathlib import Path
import re
from typing import Iterator, List, Optional, Sequence, Tuple

import yaml

from .records import BagError, Scanner
from .rosbag2 import ROSBAG2_METADATA, ROSBAG2_METADATA_ROOT


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


def scans(path: os.PathLike, problems: List[str]) -> Iterator[Scanner]:
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
            scan = Scanner(name)
        except BagError as exc:
            if lone:
                raise
            problems.append(str(exc))
            continue
        with scan:
            yield scan
        if scan.problem is not None:
            problems.append(scan.problem if lone else f'{name.name}: {scan.problem}')


def join_problems(problems: List[str]) -> Optional[str]:
    """Return the problems met reading a bag as one message (None: there were none)."""
    return '; '.join(problems) if problems else None


def total_bytes(path: os.PathLike) -> int:
    """Return the size of the bag's files that exist (bytes), for progress."""
    return sum(f.stat().st_size for f in bag_files(path) if f.is_file())
