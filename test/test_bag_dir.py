"""
Bag directories as ros2 bag record leaves them: several MCAP files read as one run.

The directories are made by splitting one recording of the simulated rig
into files of 1.5 s each with our writer (14 files, so that ``_10`` must come
after ``_2``), as a folder of files alone and as the recorder's bag directory
(with metadata.yaml); reading either must give what the single file gives,
message for message, and a replay of it the same estimates, bit for bit.
"""

import shutil

import numpy as np
import pytest
from wet_eha_thermal import interface
from wet_eha_thermal.bag.reader import (bag_files, BagError, iter_column_blocks, iter_raw,
                                        open_bag, read_columns, ROSBAG2_METADATA)
from wet_eha_thermal.bag.writer import BagWriter
from wet_eha_thermal.calibration import load_log
from wet_eha_thermal.cli import main
from wet_eha_thermal.offline import replay as rp
import yaml

pytestmark = pytest.mark.slow     # measured: see docs/development.md#tests-and-ci

SECONDS = 20.0
SPLIT_S = 1.5
SPECS = {'/eha/current': 'std_msgs/msg/Float64',
         '/eha/pressure_diff': 'sensor_msgs/msg/FluidPressure',
         '/eha/measured/winding': 'sensor_msgs/msg/Temperature'}


@pytest.fixture(scope='module')
def single(tmp_path_factory, record_rig_log):
    """20 s of stage 6 on the simulated rig at 200 Hz, configuration stored: one file."""
    return record_rig_log(tmp_path_factory.mktemp('single') / 'run.mcap', SECONDS, seed=3,
                          rate_Hz=200.0)


def split(single, folder, directory=False):
    """
    Write the messages of ``single`` again, split every SPLIT_S s; return the files.

    They are run_0.mcap, run_1.mcap, ... in ``folder``, or with ``directory``
    in the bag directory ``folder`` that the writer makes (named run: the same names).
    """
    info = open_bag(single)
    ours = {k: v for k, v in info.metadata.items() if k != 'rosbag2'}   # the writer adds it
    if directory:
        w = BagWriter(folder, directory=True, split_duration_s=SPLIT_S, metadata=ours)
    else:
        folder.mkdir()
        w = BagWriter(folder / 'run.mcap', split_duration_s=SPLIT_S, metadata=ours)
    with w:
        for topic, t in info.topics.items():
            w.add_topic(topic, t.type_name)
        for m in iter_raw(single):
            w.write(m.topic, m.data, m.log_time_ns)
        return w.paths


@pytest.fixture(scope='module')
def folder(single, tmp_path_factory):
    """Return the split run, without metadata.yaml (the files are taken by name)."""
    path = tmp_path_factory.mktemp('dirs') / 'by_name'
    files = split(single, path)
    assert len(files) == 14 and files[10].name == 'run_10.mcap'
    return path


@pytest.fixture(scope='module')
def recorded(single, tmp_path_factory):
    """Return the split run as the recorder writes it: the bag directory run/ and its listing."""
    path = tmp_path_factory.mktemp('recorded') / 'run'
    assert split(single, path, directory=True) == list(bag_files(path))
    assert (path / ROSBAG2_METADATA).is_file()
    return path


@pytest.fixture(params=['folder', 'recorded'])
def run_dir(request):
    """Each kind of split run in turn."""
    return request.getfixturevalue(request.param)


def test_the_files_are_taken_in_number_order_and_read_as_the_single_file(single, run_dir):
    assert [f.name for f in bag_files(run_dir)] == [f'run_{k}.mcap' for k in range(14)]
    one, many = open_bag(single), open_bag(run_dir)
    assert many.message_count == one.message_count > 0
    assert {k: t.message_count for k, t in many.topics.items()} == \
        {k: t.message_count for k, t in one.topics.items()}
    assert (many.start_time_ns, many.end_time_ns) == (one.start_time_ns, one.end_time_ns)
    assert many.metadata[interface.CONFIG_METADATA] == one.metadata[interface.CONFIG_METADATA]
    assert not many.truncated and len(many.files) == 14
    a, b = read_columns(single, SPECS), read_columns(run_dir, SPECS)
    for topic in SPECS:
        assert len(a.topics[topic]) > 0, topic
        assert np.array_equal(a.topics[topic].log_time_ns, b.topics[topic].log_time_ns)
        for name, values in a.topics[topic].values.items():
            assert np.array_equal(values, b.topics[topic].values[name]), (topic, name)
    assert [m.log_time_ns for m in iter_raw(run_dir)] == [m.log_time_ns for m in iter_raw(single)]
    # blocks of 10 s span the files; progress runs over the bytes of all of them
    seen = []
    blocks = list(iter_column_blocks(run_dir, SPECS, on_progress=lambda d, n: seen.append((d, n))))
    assert sum(len(b['/eha/current']) for b in blocks) == \
        one.topics['/eha/current'].message_count
    assert seen[-1][1] == sum(f.stat().st_size for f in bag_files(run_dir))
    assert all(x[0] <= y[0] for x, y in zip(seen, seen[1:])) and seen[-1][0] <= seen[-1][1]


def test_a_replay_of_the_directory_equals_that_of_the_file(single, run_dir, tmp_path, capsys):
    # the limits with the recorder's split, the plain files without (for time)
    outlook = (run_dir / ROSBAG2_METADATA).is_file()
    a = rp.replay(rp.plan_replay(single), output_rate_Hz=50.0, outlook=outlook)
    b = rp.replay(rp.plan_replay(run_dir), output_rate_Hz=50.0, outlook=outlook)
    assert a.steps == b.steps > 0 and a.messages == b.messages
    assert np.array_equal(a.stamp_s, b.stamp_s)
    for name, series in a.temperatures_C.items():
        assert np.array_equal(series, b.temperatures_C[name]), name
    assert a.current_limits == b.current_limits and (len(a.current_limits) > 0) == outlook
    assert main(['replay', str(run_dir), '--out', str(tmp_path / 'out'), '--no-outlook',
                 '--no-report']) == 0      # the command takes a directory; plots: test_replay
    assert (tmp_path / 'out' / 'estimates.csv').stat().st_size > 0
    # and a calibration log: the same data, its digest over the files in order
    config = rp.choose_config(open_bag(single), None)
    calib = config[0].calibration
    log_a, log_b = load_log(single, config, calib), load_log(run_dir, config, calib)
    assert np.array_equal(log_a.inputs['current_A'][1], log_b.inputs['current_A'][1])
    assert log_b.size_bytes == sum(f.stat().st_size for f in bag_files(run_dir))


def test_metadata_yaml_decides_the_order(folder, tmp_path):
    # rosbag2 lists its files in metadata.yaml: names that sort otherwise are read in its order
    bag = tmp_path / 'listed'
    bag.mkdir()
    names = []
    for k, f in enumerate(bag_files(folder)):
        names.append(f'z{13 - k}.mcap')
        shutil.copy(f, bag / names[-1])
    (bag / ROSBAG2_METADATA).write_text(yaml.safe_dump({'rosbag2_bagfile_information': {
        'version': 9, 'storage_identifier': 'mcap', 'relative_file_paths': names,
        'files': [{'path': n} for n in names]}}))
    assert [f.name for f in bag_files(bag)] == names
    assert [m.log_time_ns for m in iter_raw(bag)] == [m.log_time_ns for m in iter_raw(folder)]


def test_a_damaged_or_missing_file_is_named_and_the_rest_used(folder, tmp_path):
    bag = tmp_path / 'damaged'
    shutil.copytree(folder, bag)
    (bag / 'run_3.mcap').unlink()
    cut = bag / 'run_7.mcap'
    cut.write_bytes(cut.read_bytes()[:cut.stat().st_size // 2])
    (bag / 'run_11.mcap').write_bytes(b'not a bag')
    whole, info = open_bag(folder), open_bag(bag)
    assert info.truncated
    assert 'run_7.mcap' in info.problem and 'run_11.mcap' in info.problem
    assert 0.7 * whole.message_count < info.message_count < whole.message_count
    # run_3 is gone from the folder: by name the bag simply has 13 files; listed, it is missing
    (bag / ROSBAG2_METADATA).write_text(yaml.safe_dump({'rosbag2_bagfile_information': {
        'relative_file_paths': [f'run_{k}.mcap' for k in range(14)]}}))
    info = open_bag(bag)
    assert 'run_3.mcap' in info.problem and len(info.files) == 12
    cols = read_columns(bag, SPECS)
    assert cols.truncated and 'run_3.mcap' in cols.problem
    t = cols.topics['/eha/current'].log_time_ns
    assert np.all(np.diff(t) > 0) and len(t) == info.topics['/eha/current'].message_count
    # the estimates of what could be read (the limits, 2.5 times the CPU, are not the point)
    result = rp.replay(rp.plan_replay(bag), output_rate_Hz=10.0, outlook=False)
    assert result.truncated and 'run_11.mcap' in result.problem and result.steps > 0


def test_a_folder_that_is_no_bag_is_one_clear_error(tmp_path, capsys):
    with pytest.raises(BagError, match='neither metadata.yaml nor .mcap files'):
        open_bag(tmp_path)
    (tmp_path / ROSBAG2_METADATA).write_text('rosbag2_bagfile_information: [1, 2]\n')
    with pytest.raises(BagError, match='not a rosbag2 metadata file'):
        open_bag(tmp_path)
    assert main(['replay', str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'metadata.yaml' in err[0], err
