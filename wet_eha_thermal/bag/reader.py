"""
Read rosbag2-style MCAP files fast, including files whose recorder was killed.

A bag is one MCAP file or a rosbag2 bag directory (``metadata.yaml`` and
the files it lists, as ``ros2 bag record -s mcap`` leaves them when it
splits), read as one run (:func:`bag_files`).

Its files are opened one after another (:mod:`.files`) and walked record by
record (:mod:`.records`), so a file cut anywhere is read up to its last
complete chunk and reported as truncated instead of failing; a file that is
not MCAP raises :class:`BagError`. The summary at the end of a complete file
is used for what it offers (topics, counts, metadata) without reading the
data. Numeric topics of a few fixed-layout types have a speed path, decoded
chunk by chunk with numpy (:func:`read_columns`, :func:`iter_column_blocks`,
:mod:`.columns`); :func:`iter_raw` yields any message as stored.
"""

from dataclasses import dataclass
import os
from pathlib import Path
from typing import Dict, Iterable, Iterator, List, NamedTuple, Optional, Tuple

import numpy as np

# the reader's public names, wherever they live: the tools and the tests import them from here
from .columns import (COLUMN_FIELDS, ColumnBlocks, ColumnData, Columns,  # noqa: F401
                      iter_column_blocks, read_columns)
from .files import bag_files, is_bag, join_problems, one_split_series, scans  # noqa: F401
from .records import (BagError, DATA_AT, HEAD_BYTES, LENGTH_AT, LOG_TIME_AT,  # noqa: F401
                      MAGIC, Scanner, take)
from .rosbag2 import ROSBAG2_METADATA, ROSBAG2_METADATA_ROOT  # noqa: F401


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


def iter_raw(path: os.PathLike, topics: Optional[Iterable[str]] = None) -> Iterator[RawMessage]:
    """Yield the messages of a bag (of ``topics`` only, when given) in file order."""
    # a bag directory's files one after another; what cannot be read is open_bag's to report
    wanted = None if topics is None else set(topics)
    for scan in scans(path, []):
        for unit, buf, pos, channel_ids in scan.located():
            ends = pos + HEAD_BYTES + take(buf, pos + LENGTH_AT, '<u8').astype(np.int64)
            times = take(buf, pos + LOG_TIME_AT, '<i8')
            for p, end, c, t in zip(pos.tolist(), ends.tolist(), channel_ids.tolist(),
                                    times.tolist()):
                channel = scan.channels.get(c)
                if channel is None:
                    raise BagError(f'{scan.path}: a message on channel {c} comes before '
                                   'the record of that channel')
                if wanted is None or channel.topic in wanted:
                    yield RawMessage(channel.topic, scan.type_name(channel), t,
                                     unit.data[p + DATA_AT:end])


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
    parts = [_describe(scan) for scan in scans(path, problems)]
    if not Path(path).is_dir():
        return parts[0]
    if not parts:
        raise BagError(f'{path}: no file of the bag can be read: {join_problems(problems)}')
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
                   bool(problems), join_problems(problems), tuple(p.path for p in parts))


def _describe(scan: Scanner) -> BagInfo:
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
            times = take(buf, pos + LOG_TIME_AT, '<i8')
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
