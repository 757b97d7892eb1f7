"""
The bag writer on a full disk: each file finished with the reserve, writing suspended, resumed.

The fault seam is the writer's own: ``sink`` (a :class:`FileSink` whose
``write_at`` makes the one system call that writes) and ``free_space``.
:class:`Disk` is a folder of a given capacity that counts the size of every
file in it, the reserve included: a write beyond it writes what fits and
raises ENOSPC, as Linux does. After the fault every file of the bag is read
by mcap's strict reader (it needs the summary; its statistics are checked
against the chunks and messages the file holds) and the bag directory by
rosbags, ``metadata.yaml`` must list exactly the files with their counts,
and the messages read back must be those sent but the ones dropped while
suspended, which the writer counts. A real 3 MiB tmpfs repeats this as root.
"""

import errno
import os
from pathlib import Path
import time

from child_process import kill_writer
from mcap.reader import make_reader
from mcap.records import Chunk
from mcap.stream_reader import StreamReader
import pytest
from rosbags.rosbag2 import Reader
from wet_eha_thermal.bag import cdr
from wet_eha_thermal.bag.reader import iter_raw, open_bag, ROSBAG2_METADATA
from wet_eha_thermal.bag.writer import (BagWriter, CLOSED, FileSink, RECORDING, RESERVE_NAME,
                                        SUSPENDED)
import yaml

pytestmark = pytest.mark.slow     # measured: see docs/development.md#tests-and-ci

T0_NS = 1_700_000_000_000_000_000
STEP_NS = 1_000_000                 # 1 kHz of log time
FLOAT64, STRING = 'std_msgs/msg/Float64', 'std_msgs/msg/String'
KIB = 1024


class Disk:
    """A folder that holds ``capacity`` bytes of files."""

    def __init__(self, folder: Path, capacity: int = 10 ** 9):
        self.folder = folder
        self.capacity = capacity
        self.refuse_new = False     # creating a file fails (ENOSPC), as on a full file system
        self.faults = []            # (file name, bytes written by the failing call's flush)

    def used(self) -> int:
        return sum(p.stat().st_size for p in self.folder.rglob('*') if p.is_file())

    def free(self, _path=None) -> int:
        return max(0, self.capacity - self.used())

    def fill(self, leave: int = 0) -> None:
        """Leave ``leave`` bytes free from now on."""
        self.capacity = self.used() + leave

    def sink(self, path: Path) -> FileSink:
        if self.refuse_new:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
        return DiskSink(path, self)


class DiskSink(FileSink):
    """A file of a :class:`Disk`: writes what fits, then ENOSPC."""

    def __init__(self, path: Path, disk: Disk):
        super().__init__(path)
        self.disk = disk

    def write_at(self, data: memoryview, offset: int) -> int:
        room = self.disk.free()
        if room <= 0:
            self.disk.faults.append((self.path.name, offset - self.size))
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return super().write_at(data[:room], offset)


class Run:
    """A writer on a bag directory and the messages sent to it: message i is /f = i, then /s."""

    def __init__(self, bag: Path, **options):
        self.bag = bag
        self.changes = []
        self.writer = BagWriter(bag, directory=True, on_state_change=self.changes.append,
                                **options)
        self.writer.add_topic('/f', FLOAT64)
        self.writer.add_topic('/s', STRING)
        self.sent = []              # (topic, log time, data, state before the write)
        self.i = 0

    @property
    def state(self) -> str:
        return self.changes[-1].state if self.changes else RECORDING

    def send(self, n: int = 1) -> None:
        for _ in range(n):
            t = T0_NS + self.i * STEP_NS
            for topic, data in (('/f', cdr.encode_float64(self.i)),
                                ('/s', cdr.encode_string(f'{self.i:08d} ' + 'x' * 150))):
                self.sent.append((topic, t, data, self.state))
                self.writer.write(topic, data, t)
            self.i += 1

    def send_until(self, state: str, timeout_s: float = 60.0) -> None:
        """Send at about 20 kHz until the writer says it is in ``state`` (a deadline: hangs)."""
        deadline = time.monotonic() + timeout_s
        while self.state != state:
            assert time.monotonic() < deadline, f'still {self.state} after {timeout_s} s'
            self.send(20)
            time.sleep(0.001)


def strict_count(path: Path) -> int:
    """Read a file with mcap's strict reader; check its summary; return its message count."""
    with open(path, 'rb') as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None, path
        messages = sum(1 for _ in reader.iter_messages(log_time_order=False))
        f.seek(0)
        chunks = sum(isinstance(r, Chunk) for r in StreamReader(f, emit_chunks=True).records)
    stats = summary.statistics
    assert stats.message_count == messages, path
    assert stats.chunk_count == len(summary.chunk_indexes) == chunks, path
    return messages


def listed(bag: Path) -> dict:
    return yaml.safe_load((bag / ROSBAG2_METADATA).read_text())['rosbag2_bagfile_information']


def check_bag(run: Run, health, cut=(), at_fault=0) -> list:
    """
    Check the whole bag after close; return the messages read back, (topic, log time, data).

    ``cut``: the names of files left without their summary (read by our reader).
    ``at_fault``: messages sent while recording that met the fault and no open file.
    """
    bag = run.bag
    info = listed(bag)
    names = [p.name for p in health.files]
    assert info['relative_file_paths'] == [f['path'] for f in info['files']] == names
    assert sorted(p.name for p in bag.glob('*.mcap')) == sorted(names)
    assert not (bag / RESERVE_NAME).exists() and health.reserve_bytes == 0
    assert health.state == CLOSED and health.current_file is None
    for entry in info['files']:
        if entry['path'] in cut:
            recovered = open_bag(bag / entry['path'])
            assert recovered.truncated and recovered.message_count == entry['message_count']
        else:
            assert strict_count(bag / entry['path']) == entry['message_count'], entry['path']
    assert info['message_count'] == health.messages_written
    assert health.bytes_written == sum(p.stat().st_size for p in health.files)
    # what is missing was sent while suspended, and is counted as dropped, per topic too
    if cut:
        read = [(m.topic, m.log_time_ns, m.data) for m in iter_raw(bag)]
    else:
        with Reader(bag) as reader:
            assert reader.message_count == health.messages_written
            read = [(c.topic, t, raw) for c, t, raw in reader.messages()]
    kept = set(read)
    assert len(kept) == len(read) == health.messages_written
    assert kept <= {m[:3] for m in run.sent}
    for topic in ('/f', '/s'):
        times = [t for tp, t, _ in read if tp == topic]
        assert times == sorted(times), topic
    missing = [m for m in run.sent if m[:3] not in kept]
    assert len(missing) == health.messages_dropped
    if cut:     # the chunk that could not be written: the last messages sent
        assert missing == run.sent[len(run.sent) - len(missing):]
    else:
        assert sum(state != SUSPENDED for *_, state in missing) == at_fault
    dropped = {}
    for topic, *_ in missing:
        dropped[topic] = dropped.get(topic, 0) + 1
    assert health.dropped_by_topic == dropped
    return read


def suspend_options(disk: Disk, **more) -> dict:
    return {'chunk_bytes': 4 * KIB, 'flush_interval_s': 60.0, 'compression': 'none',
            'on_error': 'suspend', 'reserve_bytes': 256 * KIB, 'resume_margin_bytes': 64 * KIB,
            'sink': disk.sink, 'free_space': disk.free, **more}


def test_a_full_disk_mid_chunk_finishes_the_file_suspends_and_resumes(tmp_path):
    disk = Disk(tmp_path)
    run = Run(tmp_path / 'run', **suspend_options(disk))
    assert (run.bag / RESERVE_NAME).stat().st_size == 256 * KIB
    run.send(300)
    disk.fill(leave=1000)           # the next chunk (4 KiB) stops 1000 bytes in
    run.send_until(SUSPENDED)
    fault = run.changes[-1]
    assert disk.faults[0] == ('run_0.mcap', 1000)
    assert fault.errors == 1 and 'No space left on device' in fault.last_error
    assert fault.last_error_time_s == pytest.approx(time.time(), abs=5.0)
    assert fault.current_file is None and fault.reserve_bytes == 0
    assert not (run.bag / RESERVE_NAME).exists()
    # finished with the reserve's space: complete, listed with its count, nothing lost
    before = sum(state == RECORDING for *_, state in run.sent)
    assert strict_count(run.bag / 'run_0.mcap') == fault.messages_written == before
    assert listed(run.bag)['files'][0]['message_count'] == fault.messages_written
    assert fault.messages_dropped == 0
    run.send(500)                   # suspended: dropped, counted, no exception
    health = run.writer.health()
    assert health.state == SUSPENDED and health.messages_dropped == len(run.sent) - before
    assert health.dropped_by_topic == {'/f': health.messages_dropped // 2,
                                       '/s': health.messages_dropped // 2}
    assert health.free_bytes < 256 * KIB + 64 * KIB
    disk.capacity += 10 ** 6        # room again: the writer sees it within about a second
    start = time.monotonic()
    run.send_until(RECORDING)
    assert time.monotonic() - start < 2.5
    resumed = run.changes[-1]
    assert resumed.current_file == run.bag / 'run_1.mcap'
    assert resumed.reserve_bytes == 256 * KIB and (run.bag / RESERVE_NAME).is_file()
    assert listed(run.bag)['relative_file_paths'] == ['run_0.mcap', 'run_1.mcap']
    run.send(300)
    health = run.writer.close()
    read = check_bag(run, health)
    assert [m[1] for m in read[:2]] == [T0_NS, T0_NS]
    assert len(read) + health.messages_dropped == len(run.sent)
    assert health.messages_dropped >= 1000 and health.errors == 1
    states = [c.state for c in run.changes if c.errors == health.errors]
    assert states[-2:] == [RECORDING, CLOSED]


@pytest.mark.parametrize('how', ['closing', 'opening'])
def test_a_full_disk_at_a_split(tmp_path, how):
    # closing: the old file's last chunk meets the full disk; opening: the new file cannot be made
    disk = Disk(tmp_path)
    run = Run(tmp_path / 'run', **suspend_options(disk, split_duration_s=0.5))
    run.send(1200)                  # run_0, run_1, and run_2 begun
    assert len(run.writer.paths) == 3
    run.send(300)                   # the next message begins run_3
    if how == 'closing':
        disk.fill()
    else:
        disk.refuse_new = True
    run.send()
    fault = run.changes[-1]
    assert fault.state == SUSPENDED and fault.errors == 1
    names = ['run_0.mcap', 'run_1.mcap', 'run_2.mcap']
    assert [p.name for p in fault.files] == names
    assert strict_count(run.bag / 'run_2.mcap') == 2 * 500
    assert listed(run.bag)['relative_file_paths'] == names
    assert fault.messages_dropped == 1      # /f of the message that was to begin run_3
    assert run.writer.health().dropped_by_topic == {'/f': 1, '/s': 1}
    run.send(200)
    disk.capacity, disk.refuse_new = 10 ** 9, False
    run.send_until(RECORDING)
    assert run.changes[-1].current_file == run.bag / 'run_3.mcap'
    run.send(600)                   # into run_4: splitting goes on
    health = run.writer.close()
    assert [p.name for p in health.files] == [f'run_{k}.mcap' for k in range(5)]
    check_bag(run, health, at_fault=1)


def test_a_full_disk_at_close(tmp_path):
    # a long file: its summary (a chunk index per chunk) outgrows the 8 KiB asked for
    disk = Disk(tmp_path)
    run = Run(tmp_path / 'run', **suspend_options(disk, chunk_bytes=KIB, reserve_bytes=8 * KIB))
    run.send(3000)
    grown = run.writer.health().reserve_bytes
    assert grown > 100 * KIB and (run.bag / RESERVE_NAME).stat().st_size == grown
    disk.fill()
    health = run.writer.close()
    assert health.errors == 1 and health.messages_dropped == 0
    assert health.messages_written == len(run.sent)
    with open(run.bag / 'run_0.mcap', 'rb') as f:
        assert len(make_reader(f).get_summary().chunk_indexes) > 500
    check_bag(run, health)


def test_without_room_to_close_the_file_is_cut_at_its_last_chunk(tmp_path):
    # no reserve: nothing can finish the file; its last chunk is lost and counted
    disk = Disk(tmp_path)
    run = Run(tmp_path / 'run', **suspend_options(disk, reserve_bytes=0))
    run.send(250)
    before = run.writer.health()
    disk.fill()
    health = run.writer.close()
    assert health.errors == 1
    assert health.messages_written == before.messages_written > 0
    assert health.messages_dropped == before.messages_pending > 0
    with pytest.raises(Exception):
        strict_count(run.bag / 'run_0.mcap')
    read = check_bag(run, health, cut={'run_0.mcap'})
    assert read == [m[:3] for m in run.sent[:len(read)]]


def test_raise_mode_still_fails_loudly_and_leaves_whole_chunks(tmp_path):
    disk = Disk(tmp_path)
    w = BagWriter(tmp_path / 'run.mcap', chunk_bytes=4 * KIB, flush_interval_s=60.0,
                  sink=disk.sink, free_space=disk.free)
    w.add_topic('/f', FLOAT64)
    for i in range(300):
        w.write('/f', cdr.encode_float64(i), T0_NS + i * STEP_NS)
    disk.fill(leave=100)
    with pytest.raises(OSError) as err:
        for i in range(300, 3000):
            w.write('/f', cdr.encode_float64(i), T0_NS + i * STEP_NS)
    assert err.value.errno == errno.ENOSPC
    with pytest.raises(OSError, match='writing .*run.mcap failed'):
        w.write('/f', cdr.encode_float64(0.0), T0_NS)
    with pytest.raises(OSError) as err:
        w.close()
    assert err.value.errno == errno.ENOSPC
    assert not list(tmp_path.glob('.*'))       # no reserve in raise mode
    info = open_bag(tmp_path / 'run.mcap')     # cut at the end of a chunk, not inside one
    assert disk.faults[0] == ('run.mcap', 100)
    assert info.truncated and info.problem.endswith('without the MCAP footer')
    assert info.message_count > 250


def test_the_writer_resumes_on_its_own_and_tells(tmp_path):
    # no message while suspended: the background thread finds the room and opens the next file
    disk = Disk(tmp_path)
    run = Run(tmp_path / 'run', **suspend_options(disk))
    run.send(100)
    disk.fill()
    run.send_until(SUSPENDED)
    disk.capacity = 10 ** 9
    # a check a second, the thread's wake-up too; 30 s is a deadline for a loaded machine
    deadline = time.monotonic() + 30.0
    while run.state != RECORDING and time.monotonic() < deadline:
        time.sleep(0.02)
    assert run.state == RECORDING and run.changes[-1].current_file.name == 'run_1.mcap'
    run.send(100)
    health = run.writer.close()
    check_bag(run, health)


def test_a_lone_file_goes_on_in_numbered_files(tmp_path):
    disk = Disk(tmp_path)
    changes = []
    w = BagWriter(tmp_path / 'run.mcap', on_state_change=changes.append,
                  **suspend_options(disk))
    assert (tmp_path / f'.run.mcap{RESERVE_NAME}').is_file()
    w.add_topic('/f', FLOAT64)
    i = 0
    for state in (SUSPENDED, RECORDING):
        if state == SUSPENDED:
            disk.fill()
        else:
            disk.capacity = 10 ** 9
        deadline = time.monotonic() + 5.0
        while not (changes and changes[-1].state == state):
            w.write('/f', cdr.encode_float64(i), T0_NS + i * STEP_NS)
            i += 1
            assert time.monotonic() < deadline
    health = w.close()
    assert [p.name for p in health.files] == ['run.mcap', 'run_1.mcap']
    assert sum(strict_count(p) for p in health.files) == health.messages_written
    assert health.messages_written + health.messages_dropped == i
    assert not list(tmp_path.glob('.*'))


def test_a_taken_name_leaves_no_reserve_behind(tmp_path):
    (tmp_path / 'taken.mcap').write_bytes(b'keep me')
    with pytest.raises(FileExistsError):
        BagWriter(tmp_path / 'taken.mcap', on_error='suspend')
    assert [p.name for p in tmp_path.iterdir()] == ['taken.mcap']


def test_a_full_disk_at_the_start_is_waited_out(tmp_path):
    disk = Disk(tmp_path, capacity=0)
    disk.refuse_new = True
    run = Run(tmp_path / 'run', **suspend_options(disk))
    assert run.state == SUSPENDED and run.changes[-1].files == ()
    run.send(10)
    disk.capacity, disk.refuse_new = 10 ** 9, False
    run.send_until(RECORDING)
    run.send(10)
    health = run.writer.close()
    assert [p.name for p in health.files] == ['run_0.mcap']
    check_bag(run, health)


# ------------------------------------------------------------ splits, closed as they complete
@pytest.mark.parametrize('split', [{'split_bytes': 20 * KIB}, {'split_duration_s': 0.3}])
@pytest.mark.parametrize('on_error', ['raise', 'suspend'])
def test_each_split_is_complete_and_listed_as_soon_as_the_next_begins(tmp_path, split, on_error):
    run = Run(tmp_path / 'run', chunk_bytes=4 * KIB, on_error=on_error, reserve_bytes=64 * KIB,
              **split)
    seen = 1
    while seen < 5:
        run.send(10)
        paths = run.writer.paths
        if len(paths) > seen:
            seen = len(paths)
            done = listed(run.bag)
            assert done['relative_file_paths'] == [p.name for p in paths]
            for entry in done['files'][:-1]:    # the closed ones: complete while writing goes on
                assert strict_count(run.bag / entry['path']) == entry['message_count'] > 0
            assert done['files'][-1]['message_count'] == 0
    health = run.writer.close()
    assert health.errors == 0 and len(health.files) == 5
    check_bag(run, health)


# ------------------------------------------------------------ a real small file system
def test_a_real_full_file_system(small_fs):
    ballast = small_fs / 'ballast'
    ballast.write_bytes(os.urandom(1024 * KIB))
    run = Run(small_fs / 'run', chunk_bytes=16 * KIB, flush_interval_s=60.0,
              compression='none', on_error='suspend', reserve_bytes=256 * KIB,
              resume_margin_bytes=256 * KIB)
    run.send_until(SUSPENDED)
    fault = run.changes[-1]
    assert 'No space left on device' in fault.last_error
    assert fault.messages_dropped == 0 and fault.reserve_bytes == 0
    assert strict_count(run.bag / 'run_0.mcap') == fault.messages_written > 1000
    assert listed(run.bag)['files'][0]['message_count'] == fault.messages_written
    run.send(300)
    dropped = sum(state == SUSPENDED for *_, state in run.sent)
    assert run.writer.health().messages_dropped == dropped >= 600
    ballast.unlink()                # room again
    run.send_until(RECORDING)
    assert run.changes[-1].current_file == run.bag / 'run_1.mcap'
    run.send_until(SUSPENDED)       # and full again
    health = run.writer.close()
    assert [p.name for p in health.files] == ['run_0.mcap', 'run_1.mcap']
    check_bag(run, health)


def test_a_small_file_system_records_with_the_default_reserve(small_fs):
    """
    3 MiB, and the default reserve of 4 MiB: it shrinks to half the free space, not to none.

    The user's case of issue 29 (a recorder on a 3 MB file system): the bag must hold what
    fitted, closed cleanly, and the writer must resume once the file system is empty enough
    (half of it free), not after a 20 MiB that can never be free there.
    """
    run = Run(small_fs / 'run', flush_interval_s=60.0, compression='none', on_error='suspend')
    assert run.writer.health().reserve_bytes <= 1.6 * 2 ** 20
    run.send_until(SUSPENDED)
    fault = run.changes[-1]
    assert fault.messages_written > 5000 and strict_count(run.bag / 'run_0.mcap') == \
        fault.messages_written
    (run.bag / 'run_0.mcap').unlink()           # room again: the first file taken away
    run.send_until(RECORDING)
    assert run.changes[-1].current_file == run.bag / 'run_1.mcap'
    # the background check may resume before a write does: what comes next goes to run_1
    run.send(100)
    health = run.writer.close()
    assert health.errors == 1 and strict_count(run.bag / 'run_1.mcap') >= 100


# ------------------------------------------------------------ SIGKILL with splits
def test_sigkill_while_splitting_loses_at_most_about_a_second(tmp_path):
    bag = tmp_path / 'killed'
    written, last_ns = kill_writer(bag, 2700, directory=True, split_duration_s=0.5,
                                   on_error='suspend')
    info = listed(bag)
    names = info['relative_file_paths']
    assert len(names) >= 4 and sorted(p.name for p in bag.glob('*.mcap')) == sorted(names)
    assert (bag / RESERVE_NAME).is_file()      # a SIGKILL leaves the reserve behind
    for entry in info['files'][:-1]:            # every closed split is complete
        assert strict_count(bag / entry['path']) == entry['message_count'] > 0
    read = [float(cdr.float64_data(m.data)) for m in iter_raw(bag)]
    assert read == list(range(len(read)))       # the start, in order, nothing missing
    lost_s = (last_ns - max(m.log_time_ns for m in iter_raw(bag))) / 1e9
    print(f'SIGKILL after {written} messages at 1 kHz, split every 0.5 s: {len(names)} files, '
          f'{len(read)} messages kept, the last {lost_s:.2f} s of log time lost')
    assert len(read) <= written and lost_s < 1.5
