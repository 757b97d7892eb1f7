"""
Bag writer and reader: rosbag2 layout, crash safety, splitting, damage, fast decoding.

The bag directories the writer makes are read back with rosbags, a rosbag2
reader written apart from rosbag2 and from this package.
"""

from collections import Counter
import multiprocessing
import os
from pathlib import Path
import shutil
import struct
import sys
import time

from bag_blocks import assert_prefetched_blocks_are_the_same, SPECS
from builtin_interfaces.msg import Time
from child_process import in_a_fresh_process, kill_writer
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from mcap.reader import make_reader
from mcap.writer import CompressionType, IndexType, Writer
from mcap_ros2.decoder import DecoderFactory
import numpy as np
import pytest
from rclpy.qos import qos_profile_sensor_data, QoSProfile
from rclpy.serialization import serialize_message
from rosbags.rosbag2 import Reader
from rosbags.typesys import get_types_from_msg, get_typestore, Stores
from sensor_msgs.msg import FluidPressure, Temperature
from std_msgs.msg import Float64, String
from wet_eha_thermal import processes
from wet_eha_thermal.bag.reader import (BagError, iter_column_blocks, iter_raw, open_bag,
                                        read_columns, ROSBAG2_METADATA)
from wet_eha_thermal.bag.writer import BagWriter, message_definition, offered_qos, qos_profiles
from wet_eha_thermal.interface import FLOAT64, FLUID_PRESSURE, TEMPERATURE
from wet_eha_thermal.ros import topics
import yaml

STRING = 'std_msgs/msg/String'
DIAGNOSTICS = 'diagnostic_msgs/msg/DiagnosticArray'
T0_NS = 1_700_000_000_123_456_789
# frame_id lengths with the NUL of 1 to 14 bytes: every alignment of the float64 after it
FRAME_IDS = ['', 'a', 'ab', 'abc', 'port_a', 'x' * 13, 'tc_7']


def stamp(ns: int) -> Time:
    sec, nanosec = divmod(ns, 1_000_000_000)
    return Time(sec=sec, nanosec=nanosec)


def sample_messages(n: int):
    """Return (topic, type, message, log_time_ns) of a mixed run, Float64 to DiagnosticArray."""
    out = []
    for i in range(n):
        log_ns = T0_NS + i * 1_000_000
        out.append(('/f', FLOAT64, Float64(data=np.sin(i) * 1e3), log_ns))
        p = FluidPressure(fluid_pressure=1e5 + i * 0.25, variance=i * 1e-3)
        p.header.frame_id = FRAME_IDS[i % len(FRAME_IDS)]
        if i % 3:  # every third stamp zero: the time falls back to the log time
            p.header.stamp = stamp(log_ns - 12_345)
        out.append(('/p', FLUID_PRESSURE, p, log_ns + 1))
        if i >= 100 and i % 4 == 0:  # a topic that starts late, in a later chunk
            t = Temperature(temperature=20.0 + i / 7, variance=0.01)
            t.header.frame_id = FRAME_IDS[(i // 4) % len(FRAME_IDS)]
            t.header.stamp = stamp(log_ns + 3)
            out.append(('/t', TEMPERATURE, t, log_ns + 2))
        if i % 50 == 0:
            out.append(('/s', STRING, String(data=f'note {i} é'), log_ns + 3))
            d = DiagnosticArray(status=[DiagnosticStatus(
                level=DiagnosticStatus.WARN, name='oil', message=f'step {i}', hardware_id='eha',
                values=[KeyValue(key='T_K', value=str(300 + i)), KeyValue(key='k', value='')])])
            d.header.stamp = stamp(log_ns)
            out.append(('/diagnostics', DIAGNOSTICS, d, log_ns + 4))
    return out


def write(path, messages, qos=None, **kwargs):
    """Write ``messages``, adding each topic just before its first message."""
    with BagWriter(path, **kwargs) as bag:
        for topic, type_name, msg, log_ns in messages:
            if topic not in bag.topics:
                offered = (qos or {}).get(topic)
                bag.add_topic(topic, type_name, offered and qos_profiles(offered))
            bag.write(topic, serialize_message(msg), log_ns)
    return bag


def assert_same(expected, decoded, where='msg'):
    """Compare an rclpy message with mcap_ros2's decoding of it, field by field."""
    if hasattr(expected, 'get_fields_and_field_types'):
        for name in expected.get_fields_and_field_types():
            assert_same(getattr(expected, name), getattr(decoded, name), f'{where}.{name}')
    elif isinstance(expected, (list, tuple)):
        assert len(expected) == len(decoded), where
        for k, (a, b) in enumerate(zip(expected, decoded)):
            assert_same(a, b, f'{where}[{k}]')
    elif isinstance(expected, bytes):  # a ROS byte: rclpy b'\x01', mcap_ros2 1
        assert expected[0] == decoded, where
    else:
        assert expected == decoded, where


def mcap_messages(path):
    """Return [(topic, schema, log_time_ns, data)] in file order, read by mcap itself."""
    with open(path, 'rb') as f:
        return [(c.topic, s, m.log_time, m.data)
                for s, c, m in make_reader(f).iter_messages(log_time_order=False)]


def expected_columns(path):
    """Decode the SPECS topics through iter_raw and mcap_ros2's decoder (the reference)."""
    schemas = {s.name: s for _, s, _, _ in mcap_messages(path)}
    factory = DecoderFactory()
    out = {topic: {'log': [], 'time': [], 'values': {}} for topic in SPECS}
    for topic, type_name, log_ns, data in iter_raw(path, SPECS):
        msg = factory.decoder_for('cdr', schemas[type_name])(data)
        col = out[topic]
        col['log'].append(log_ns)
        if type_name == FLOAT64:
            col['time'].append(log_ns)
            fields = {'data': msg.data}
        else:
            stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            col['time'].append(stamp_ns or log_ns)
            value = 'fluid_pressure' if type_name == FLUID_PRESSURE else 'temperature'
            fields = {value: getattr(msg, value), 'variance': msg.variance}
        for name, v in fields.items():
            col['values'].setdefault(name, []).append(v)
    return out


def assert_columns_equal(columns, expected, prefix=False):
    """Check read_columns output against expected_columns (or a prefix of it, for cut files)."""
    for topic, col in expected.items():
        got = columns[topic]
        n = len(got) if prefix else len(col['log'])
        assert len(got) == n and n <= len(col['log']), topic
        assert np.array_equal(got.log_time_ns, np.array(col['log'][:n], np.int64)), topic
        assert np.array_equal(got.time_ns, np.array(col['time'][:n], np.int64)), topic
        for name, values in col['values'].items():
            assert np.array_equal(got.values[name], np.array(values[:n])), (topic, name)


def rewrite(src, dst, **writer_options):
    """Copy a bag message by message with mcap's Writer (other chunking, index, compression)."""
    with open(src, 'rb') as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        with open(dst, 'wb') as out:
            w = Writer(out, **writer_options)
            w.start(profile='ros2', library='test')
            for s in summary.schemas.values():
                w.register_schema(s.name, s.encoding, s.data)
            for c in summary.channels.values():
                w.register_channel(c.topic, c.message_encoding, c.schema_id, c.metadata)
            for _, c, m in reader.iter_messages(log_time_order=False):
                w.add_message(c.id, m.log_time, m.data, m.publish_time)
            w.finish()


@pytest.fixture(scope='module')
def sample_bag(tmp_path_factory):
    path = tmp_path_factory.mktemp('bag') / 'run.mcap'
    messages = sample_messages(400)
    write(path, messages, {'/f': QoSProfile(depth=7), '/p': qos_profile_sensor_data},
          chunk_bytes=3000, metadata={'estimator': {'config': 'a: 1\n'}})
    return path, messages


def test_round_trip_is_rosbag2_layout(sample_bag):
    path, messages = sample_bag
    with open(path, 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == 'ros2'
        assert reader.get_header().library.startswith('wet_eha_thermal/')
        summary = reader.get_summary()
        decoded = list(reader.iter_decoded_messages(log_time_order=False))
        records = {m.name: m.metadata for m in reader.iter_metadata()}
    assert len(decoded) == len(messages)
    for (topic, type_name, msg, log_ns), (schema, channel, message, dec) in zip(
            messages, decoded):
        assert (channel.topic, schema.name, message.log_time) == (topic, type_name, log_ns)
        assert_same(msg, dec, topic)
    types = {m[0]: m[1] for m in messages}
    for schema in summary.schemas.values():
        assert schema.encoding == 'ros2msg'
        assert schema.data.decode() == message_definition(schema.name)
    assert {s.name for s in summary.schemas.values()} == set(types.values())
    for channel in summary.channels.values():
        assert channel.message_encoding == 'cdr'
        assert channel.metadata['topic_type_hash'].startswith('RIHS01_')
        qos = yaml.safe_load(channel.metadata['offered_qos_profiles'])
        if channel.topic == '/p':
            assert qos[0]['reliability'] == 'best_effort' and qos[0]['depth'] == 5
            assert qos[0]['deadline'] == {'sec': 0, 'nsec': 0}
        elif channel.topic == '/f':
            assert (qos[0]['history'], qos[0]['depth']) == ('keep_last', 7)
        else:
            assert qos == []
    stats = summary.statistics
    assert stats.message_count == len(messages)
    counts = {t: sum(m[0] == t for m in messages) for t in types}
    assert {summary.channels[c].topic: n for c, n in stats.channel_message_counts.items()} == (
        counts)
    bag = yaml.safe_load(records['rosbag2']['serialized_metadata'])
    assert (bag['version'], bag['storage_identifier']) == (9, 'mcap')
    assert bag['message_count'] == len(messages)
    assert {t['topic_metadata']['name']: t['message_count']
            for t in bag['topics_with_message_count']} == counts
    assert bag['starting_time']['nanoseconds_since_epoch'] == messages[0][3]
    assert records['estimator'] == {'config': 'a: 1\n'}
    info = open_bag(path)
    assert not info.truncated and info.message_count == len(messages)
    assert {t: i.message_count for t, i in info.topics.items()} == counts
    assert info.topics['/p'].type_name == FLUID_PRESSURE


@pytest.mark.parametrize('ours,rclpy_qos', [
    ({'depth': 10}, lambda: QoSProfile(depth=10)),
    ({'durability': 'transient_local', 'depth': 1}, topics.latched_qos),
    ({'reliability': 'best_effort', 'depth': 100}, lambda: topics.input_qos('sensor_data')),
    ({'depth': 1000}, lambda: topics.input_qos('reliable', 1000))])
def test_offered_qos_is_what_rclpy_profiles_give(ours, rclpy_qos):
    # what the bags written without ROS (replay, simulated rig) claim their publishers offered,
    # as the YAML the channel stores (no anchors where rclpy's profiles give none)
    assert yaml.safe_dump(offered_qos(**ours)) == yaml.safe_dump(qos_profiles(rclpy_qos()))


def test_read_columns_matches_mcap_ros2(sample_bag, tmp_path):
    path, messages = sample_bag
    # iter_raw is mcap's view of the file
    assert [(m.topic, m.log_time_ns, m.data) for m in iter_raw(path)] == [
        (t, log_ns, data) for t, _, log_ns, data in mcap_messages(path)]
    expected = expected_columns(path)
    data = read_columns(path, SPECS)
    assert not data.truncated and data.problem is None
    assert data.message_count == sum(len(c['log']) for c in expected.values())
    assert_columns_equal(data.topics, expected)
    assert data.topics['/f'].time_ns is data.topics['/f'].log_time_ns
    blocks = iter_column_blocks(path, SPECS, max_block_s=0.05)
    parts = list(blocks)
    assert len(parts) > 3 and not blocks.truncated
    for topic in SPECS:
        log_ns = np.concatenate([b[topic].log_time_ns for b in parts])
        assert np.array_equal(log_ns, data.topics[topic].log_time_ns)
    # the same messages as other writers lay them out: no chunks (rosbag2's 'fastwrite'),
    # chunks without message index (the record walk)
    for name, options in (('flat', {'use_chunking': False}),
                          ('no_index', {'index_types': IndexType.NONE, 'chunk_size': 2000,
                                        'compression': CompressionType.LZ4})):
        other = tmp_path / f'{name}.mcap'
        rewrite(path, other, **options)
        assert_columns_equal(read_columns(other, SPECS).topics, expected)


@pytest.fixture
def fork_server(monkeypatch):
    """Take the reading process from the fork server, as a caller that runs threads does."""
    monkeypatch.setattr(processes, 'can_fork', lambda: False)


def test_prefetched_blocks_are_the_same_blocks(sample_bag, tmp_path, fork_server):
    path, _ = sample_bag
    assert_prefetched_blocks_are_the_same(path, tmp_path)


def test_forked_prefetched_blocks_are_the_same_blocks(sample_bag, tmp_path):
    in_a_fresh_process('bag_blocks', 'assert_prefetched_blocks_are_the_same',
                       str(sample_bag[0]), str(tmp_path), timeout_s=300.0)


def test_stopping_early_ends_the_reading_process(sample_bag, fork_server):
    path, _ = sample_bag
    blocks = iter(iter_column_blocks(path, SPECS, max_block_s=0.05, prefetch=True))
    next(blocks)
    assert len(multiprocessing.active_children()) == 1
    blocks.close()          # what a for loop left by break or an exception does
    assert multiprocessing.active_children() == []


def test_cut_files_read_up_to_the_cut(sample_bag, tmp_path):
    path, _ = sample_bag
    expected = expected_columns(path)
    flat = tmp_path / 'flat.mcap'
    rewrite(path, flat, use_chunking=False)
    for source in (path, flat):
        whole = source.read_bytes()
        for fraction in (0.05, 0.3, 0.5, 0.77, 0.99):
            cut = tmp_path / 'cut.mcap'
            cut.write_bytes(whole[:int(len(whole) * fraction)])
            data = read_columns(cut, SPECS)
            assert data.truncated and 'byte' in data.problem
            assert_columns_equal(data.topics, expected, prefix=True)
            info = open_bag(cut)
            assert info.truncated
            assert info.message_count == sum(1 for _ in iter_raw(cut))
            if fraction > 0.1:
                assert data.message_count > 0
            if source == path and fraction > 0.1:
                assert info.metadata['estimator'] == {'config': 'a: 1\n'}


@pytest.mark.slow
def test_sigkill_loses_at_most_about_a_second(tmp_path):
    path = tmp_path / 'killed.mcap'
    written, last_ns = kill_writer(path, 3000, pressure=True,
                                   metadata={'estimator': {'config': 'rate_Hz: 1000'}})
    info = open_bag(path)
    assert info.truncated and info.metadata['estimator'] == {'config': 'rate_Hz: 1000'}
    data = read_columns(path, {'/f': FLOAT64, '/p': FLUID_PRESSURE})
    assert data.truncated and data.message_count == info.message_count
    f, p = data.topics['/f'], data.topics['/p']
    assert np.array_equal(f.values['data'], np.arange(len(f)))
    assert np.array_equal(p.values['fluid_pressure'], 1e5 + np.arange(len(p)))
    assert np.array_equal(p.time_ns, p.log_time_ns)
    lost_s = (last_ns - f.log_time_ns[-1]) / 1e9
    print(f'SIGKILL after {written} samples at 1 kHz: {len(f)} recovered, the last '
          f'{lost_s:.2f} s of log time lost')
    # a chunk closes every 1 s of log time: what was lost is the open chunk at most, counted
    # in the log time of what the writer had written (not in how late the kill came)
    assert 0 < len(f) <= written and lost_s < 1.5


def test_idle_writer_flushes_by_wall_time(tmp_path):
    path = tmp_path / 'idle.mcap'
    with BagWriter(path, flush_interval_s=0.2) as bag:
        bag.add_topic('/f', FLOAT64)
        bag.write('/f', serialize_message(Float64(data=1.5)), T0_NS)
        # no further message: the background check closes the chunk (waited for as a fact:
        # a loaded machine may wake the thread late; 30 s is a deadline, not the interval)
        deadline = time.monotonic() + 30.0
        while open_bag(path).message_count == 0 and time.monotonic() < deadline:
            time.sleep(0.05)
        live = open_bag(path)
        assert live.truncated and live.message_count == 1
    assert not open_bag(path).truncated


@pytest.mark.parametrize('split', [{'split_bytes': 15_000}, {'split_duration_s': 0.1}])
def test_split_files_are_complete_and_cover_everything(tmp_path, split):
    messages = sample_messages(300)
    bag = write(tmp_path / 'run.mcap', messages, chunk_bytes=1500,
                metadata={'estimator': {'config': 'x'}}, **split)
    assert len(bag.paths) > 2
    assert [p.name for p in bag.paths] == [f'run_{k}.mcap' for k in range(len(bag.paths))]
    assert not (tmp_path / 'run.mcap').exists()
    seen = set()  # every file declares the topics added so far, even those it has no message of
    for path in bag.paths:
        info = open_bag(path)
        assert not info.truncated and seen <= set(info.topics) <= set(bag.topics)
        seen = set(info.topics)
        assert info.metadata['estimator'] == {'config': 'x'}
        assert yaml.safe_load(info.metadata['rosbag2']['serialized_metadata'])[
            'relative_file_paths'][-1] == path.name
    raw = [m for path in bag.paths for m in iter_raw(path)]
    assert [(m.topic, m.log_time_ns) for m in raw] == [(m[0], m[3]) for m in messages]


def read_with_rosbags(bag_dir):
    """Return rosbags' view of a bag directory: its reader's figures and decoded messages."""
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    own = get_typestore(Stores.EMPTY)    # from the definitions stored in the bag alone
    with Reader(bag_dir) as reader:
        for connection in reader.connections:
            own.register(get_types_from_msg(connection.msgdef.data, connection.msgtype))
        messages = [(c.topic, t, jazzy.deserialize_cdr(raw, c.msgtype),
                     own.deserialize_cdr(raw, c.msgtype)) for c, t, raw in reader.messages()]
        figures = {
            'count': reader.message_count, 'start_ns': reader.start_time,
            'end_ns': reader.end_time, 'ros_distro': reader.ros_distro,
            'topics': {t: (i.msgtype, i.msgcount) for t, i in reader.topics.items()},
            'qos': {c.topic: c.ext.offered_qos_profiles for c in reader.connections},
            'files': list(reader.storage.files)}   # emptied when the reader closes
    return figures, messages


def bag_yaml(bag_dir):
    """Return the rosbag2_bagfile_information of a bag directory's metadata.yaml."""
    return yaml.safe_load((bag_dir / ROSBAG2_METADATA).read_text())['rosbag2_bagfile_information']


def test_bag_directory_is_what_rosbags_reads(tmp_path):
    messages = sample_messages(300)
    bag = write(tmp_path / 'run', messages, {'/f': QoSProfile(depth=7)}, chunk_bytes=1500,
                split_duration_s=0.1, directory=True, metadata={'estimator': {'config': 'x'}})
    names = [f'run_{k}.mcap' for k in range(3)]
    assert bag.paths == [tmp_path / 'run' / n for n in names]
    assert sorted(os.listdir(tmp_path / 'run')) == [ROSBAG2_METADATA, *names]
    figures, decoded = read_with_rosbags(tmp_path / 'run')
    assert figures['count'] == len(messages)
    assert figures['start_ns'] == messages[0][3]
    assert figures['end_ns'] == messages[-1][3] + 1          # rosbags: one past the last
    assert figures['ros_distro'] == os.environ.get('ROS_DISTRO', 'jazzy')
    counts = Counter(m[0] for m in messages)
    assert figures['topics'] == {m[0]: (m[1], counts[m[0]]) for m in messages}
    assert figures['qos']['/f'][0].depth == 7 and figures['qos']['/s'] == []
    assert [f['path'] for f in figures['files']] == names
    for entry, path in zip(figures['files'], bag.paths):
        info = open_bag(path)
        assert entry['message_count'] == info.message_count > 0
        assert entry['starting_time']['nanoseconds_since_epoch'] == info.start_time_ns
        assert entry['duration']['nanoseconds'] == info.end_time_ns - info.start_time_ns
    assert [(topic, t) for topic, t, _, _ in decoded] == [(m[0], m[3]) for m in messages]
    for (topic, _, msg, _), (_, _, jazzy, own) in zip(messages, decoded):
        assert_same(msg, jazzy, topic)
        assert_same(msg, own, topic)
    # metadata.yaml says what the last file's rosbag2 record says
    record = open_bag(bag.paths[-1]).metadata['rosbag2']['serialized_metadata']
    assert bag_yaml(tmp_path / 'run') == yaml.safe_load(record)
    # and this package's reader takes the directory as one run
    info = open_bag(tmp_path / 'run')
    assert not info.truncated and info.files == tuple(bag.paths)
    assert info.message_count == len(messages) and info.metadata['estimator'] == {'config': 'x'}
    assert [(m.topic, m.log_time_ns) for m in iter_raw(tmp_path / 'run')] == [
        (m[0], m[3]) for m in messages]


def test_metadata_yaml_is_current_from_the_start(tmp_path):
    # as a recorder killed mid-run leaves it: copies of the directory while it is written
    messages = sample_messages(300)
    with BagWriter(tmp_path / 'run', directory=True, split_duration_s=0.1,
                   chunk_bytes=1500) as bag:
        opened = bag_yaml(tmp_path / 'run')
        assert (opened['message_count'], opened['relative_file_paths']) == (0, ['run_0.mcap'])
        assert not list((tmp_path / 'run').glob('.*'))      # the temporary file is gone
        copies = []
        for topic, type_name, msg, log_ns in messages:
            if topic not in bag.topics:
                bag.add_topic(topic, type_name)
            files = len(bag.paths)
            bag.write(topic, serialize_message(msg), log_ns)
            if len(bag.paths) > files:                       # the write began a file
                copy = tmp_path / f'copy_{files}'
                shutil.copytree(tmp_path / 'run', copy)
                copies.append((copy, files))
    assert [files for _, files in copies] == [1, 2]
    for copy, done in copies:
        listed = bag_yaml(copy)
        names = [f'run_{k}.mcap' for k in range(done + 1)]
        assert listed['relative_file_paths'] == [f['path'] for f in listed['files']] == names
        complete = [open_bag(copy / n).message_count for n in names[:done]]
        assert [f['message_count'] for f in listed['files']] == complete + [0]
        assert listed['message_count'] == sum(complete)
        info = open_bag(copy)          # the last file is cut: the rest reads, in order
        assert info.truncated and names[-1] in info.problem
        assert info.message_count >= sum(complete)   # the new file's first chunk is not out yet
        raw = [(m.topic, m.log_time_ns) for m in iter_raw(copy)]
        assert raw == [(m[0], m[3]) for m in messages[:len(raw)]]
    # closed: rosbags reads what the last metadata.yaml says
    figures, decoded = read_with_rosbags(tmp_path / 'run')
    assert figures['count'] == len(decoded) == len(messages)


def test_a_bag_directory_never_overwrites(tmp_path):
    empty, used, afile = tmp_path / 'empty', tmp_path / 'used', tmp_path / 'afile'
    empty.mkdir()
    used.mkdir()
    (used / 'notes.txt').write_text('keep me')
    afile.write_text('keep me too')
    for path in (empty, used, afile):   # as ros2 bag record: not even an empty folder
        with pytest.raises(FileExistsError) as err:
            BagWriter(path, directory=True)
        assert err.value.filename == str(path)
    assert list(empty.iterdir()) == [] and [p.name for p in used.iterdir()] == ['notes.txt']
    assert afile.read_text() == 'keep me too'
    with BagWriter(tmp_path / 'quiet', directory=True):   # no message: still a bag rosbags opens
        pass
    figures, decoded = read_with_rosbags(tmp_path / 'quiet')
    assert (figures['count'], decoded) == (0, [])
    assert [f['path'] for f in figures['files']] == ['quiet_0.mcap']


def test_not_mcap_files_are_refused(tmp_path):
    text = tmp_path / 'notes.mcap'
    text.write_text('not a bag at all')
    empty = tmp_path / 'empty.mcap'
    empty.write_bytes(b'')
    for path, why in ((text, 'not an MCAP file'), (empty, 'empty'),
                      (tmp_path / 'missing.mcap', 'cannot open')):
        for read in (open_bag, lambda p: read_columns(p, SPECS), lambda p: next(iter_raw(p))):
            with pytest.raises(BagError, match=why) as err:
                read(path)
            assert str(path) in str(err.value)


def test_refused_contents(sample_bag, tmp_path):
    path, _ = sample_bag
    with pytest.raises(BagError, match='expected sensor_msgs/msg/Temperature'):
        read_columns(path, {'/p': TEMPERATURE})
    with pytest.raises(BagError, match='not one read as columns'):
        read_columns(path, {'/s': STRING})
    big_endian = tmp_path / 'be.mcap'
    with open(big_endian, 'wb') as out:
        w = Writer(out)
        w.start(profile='ros2')
        schema = w.register_schema(FLOAT64, 'ros2msg', b'float64 data')
        channel = w.register_channel('/f', 'cdr', schema)
        w.add_message(channel, 1, b'\x00\x00\x00\x00' + struct.pack('>d', 1.0), 1)
        w.finish()
    with pytest.raises(BagError, match='encapsulation 0000'):
        read_columns(big_endian, {'/f': FLOAT64})
    with pytest.raises(FileExistsError):
        BagWriter(path)


def test_absent_topic_reads_empty(sample_bag):
    path, _ = sample_bag
    data = read_columns(path, {'/nothing': TEMPERATURE})
    assert len(data.topics['/nothing']) == 0 and data.message_count == 0
    assert set(data.topics['/nothing'].values) == {'temperature', 'variance'}


def test_schema_text_is_rosbag2s():
    text = message_definition(FLUID_PRESSURE)
    share = Path(sys.prefix) / 'share'
    parts = text.split('\n' + '=' * 80 + '\n')
    assert parts[0] == (share / 'sensor_msgs/msg/FluidPressure.msg').read_text()
    assert parts[1] == 'MSG: std_msgs/Header\n' + (share / 'std_msgs/msg/Header.msg').read_text()
    assert parts[2].startswith('MSG: builtin_interfaces/Time\n')
    assert len(parts) == 3
