"""Offline replay of bags through the estimator: round trip, determinism, damaged input."""

import math
import shutil
from types import SimpleNamespace

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import FluidPressure, Temperature
from std_msgs.msg import Float64
from wet_eha_thermal import interface
from wet_eha_thermal.bag.reader import iter_raw, open_bag
from wet_eha_thermal.bag.writer import BagWriter
from wet_eha_thermal.cli import main
from wet_eha_thermal.config import ConfigError, default_config_path, with_values
from wet_eha_thermal.estimator.core import Estimator
from wet_eha_thermal.offline import replay as rp

SECONDS = 20.0


@pytest.fixture(scope='module')
def bag(tmp_path_factory, record_rig_log):
    """20 s of stage 6 on the simulated rig (one differential pressure), config stored."""
    return record_rig_log(tmp_path_factory.mktemp('bags') / 'stage6.mcap', SECONDS, seed=7)


@pytest.fixture(scope='module')
def result(bag):
    return rp.replay(rp.plan_replay(bag), output_rate_Hz=50.0)


def test_cli_writes_estimates_and_report(bag, tmp_path, capsys):
    out = tmp_path / 'out'
    assert main(['replay', str(bag), '--out', str(out)]) == 0
    text = capsys.readouterr().out
    assert 'stored in stage6.mcap' in text
    assert 'dp_Pa <- /eha/pressure_diff' in text
    assert 'winding_mean      - winding' in text
    for name in ('estimates.csv', 'estimates.mcap', 'report.md', 'inputs.png',
                 'temperatures.png', 'errors.png', 'alerts.png'):
        assert (out / name).stat().st_size > 0, name
    assert not list(out.glob('*.partial*'))
    table = np.genfromtxt(out / 'estimates.csv', delimiter=',', names=True)
    assert abs(len(table) - SECONDS * 10) <= 2            # 10 Hz by default
    assert np.all(np.diff(table['stamp_s']) > 0)
    report = (out / 'report.md').read_text()
    assert '| winding | winding_mean |' in report


def test_estimates_mcap_reads_back_with_an_independent_decoder(result, tmp_path):
    path = rp.write_mcap(result, tmp_path / 'estimates.mcap')
    got = {}
    with open(path, 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, msg in reader.iter_decoded_messages():
            assert schema.name == 'sensor_msgs/msg/Temperature' or channel.topic == '/eha/alerts'
            if channel.topic == '/eha/estimate/winding_hotspot':
                stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
                got[round(stamp, 6)] = (msg.temperature, msg.variance)
    assert len(got) == len(result.stamp_s)
    for k, stamp in enumerate(result.stamp_s):
        temperature, variance = got[round(float(stamp), 6)]
        assert temperature == result.temperatures_C['winding_hotspot'][k]
        assert variance == pytest.approx(result.sigma_K[k] ** 2, rel=1e-15)
    assert open_bag(path).metadata[interface.CONFIG_METADATA][interface.CONFIG_METADATA_KEY]


def test_replay_equals_the_live_estimator_fed_sample_by_sample(bag, result):
    # the live node adds each sample as it arrives and advances when one may close a
    # step; the replay adds 10 s blocks: in sample time both must give the same numbers
    # (the thermocouples too: the live correction uses each reading by its stamp)
    plan = rp.plan_replay(bag)
    est = Estimator(plan.cfg)
    by_topic = {topic: name for name, topic in plan.inputs.items()}
    by_tc = {topic: tc for tc, topic in plan.thermocouples.items()}
    live = {}
    for m in iter_raw(bag, list(by_topic) + [plan.ambient] + list(by_tc)):
        if m.topic == plan.ambient or m.topic in by_tc:
            msg = deserialize_message(m.data, Temperature)
            stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
            if m.topic in by_tc:
                est.add_measured(by_tc[m.topic], stamp, msg.temperature)
            else:
                est.add_ambient(stamp, msg.temperature)
            continue
        name = by_topic[m.topic]
        if m.type_name.endswith('FluidPressure'):
            msg = deserialize_message(m.data, FluidPressure)
            t, v = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec, msg.fluid_pressure
        else:
            t, v = m.log_time_ns * 1e-9, deserialize_message(m.data, Float64).data
        for e in est.take(name, t, v, budget_s=0.0):
            live[e.stamp_s] = e.temperatures_C
    assert len(live) == len(result.stamp_s) > 900
    assert result.correction['active'] and est.correction.updates > 900
    assert est.correction.updates == result.correction['updates']
    for k, stamp in enumerate(result.stamp_s):
        for name in ('winding_hotspot', 'magnet', 'oil', 'chamber_a'):
            assert live[stamp][name] == result.temperatures_C[name][k], (stamp, name)
    again = rp.replay(rp.plan_replay(bag), output_rate_Hz=50.0)
    for name, values in result.temperatures_C.items():
        assert np.array_equal(again.temperatures_C[name], values), name


def test_truncated_bag_replays_up_to_the_cut_with_a_warning(bag, tmp_path, capsys):
    cut = tmp_path / 'cut.mcap'
    data = bag.read_bytes()
    cut.write_bytes(data[:int(len(data) * 0.6)])
    out = tmp_path / 'out'
    assert main(['replay', str(cut), '--out', str(out), '--no-report']) == 0
    err = capsys.readouterr().err
    assert 'is truncated' in err and 'messages recovered' in err
    rows = np.genfromtxt(out / 'estimates.csv', delimiter=',', names=True)
    assert 0.3 * SECONDS * 10 < len(rows) < 0.75 * SECONDS * 10


def test_bad_inputs_give_one_error_and_no_output(bag, tmp_path, capsys):
    out = tmp_path / 'out'
    text_file = tmp_path / 'notes.mcap'
    text_file.write_text('not a bag\n')
    empty = tmp_path / 'empty.mcap'
    empty.write_bytes(b'')
    cases = [
        ([str(text_file)], 'not an MCAP file'),
        ([str(empty)], str(empty)),
        ([str(tmp_path / 'missing.mcap')], 'missing.mcap'),
        ([str(bag), '--map', 'current_A=/eha/measured/frame'],
         'holds sensor_msgs/msg/Temperature; expected std_msgs/msg/Float64'),
        ([str(bag)] + [f'--map={n}=/rig/{n}' for n in ('current_A', 'speed_rad_s', 'dp_Pa',
                                                       'position_m')],
         'no topic of the mapping is in the bag'),
        ([str(bag), '--map', 'torque=/eha/torque'], "cannot map 'torque'"),
        ([str(bag), '--map', 'current_A'], 'expected name=/topic'),
        ([str(bag), str(bag), '--workers', '0'], '--workers 0: must be at least 1'),
    ]
    for argv, expected in cases:
        assert main(['replay'] + argv + ['--out', str(out)]) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith('error:') and expected in err[0], err
    assert not out.exists() or not any(out.iterdir())


def test_foreign_topic_names_mapped_by_option(bag, result, tmp_path):
    # a bag recorded with other names (ros2 bag record on another rig): same bytes
    foreign = tmp_path / 'foreign.mcap'
    rename = {'/eha/current': '/rig/phase_current', '/eha/speed': '/rig/motor_speed',
              '/eha/pressure_diff': '/rig/load_dp', '/eha/position': '/rig/lvdt'}
    info = open_bag(bag)
    with BagWriter(foreign, compression='lz4') as w:
        for topic, t in info.topics.items():
            w.add_topic(rename.get(topic, topic), t.type_name, None)
        for m in iter_raw(bag):
            w.write(rename.get(m.topic, m.topic), m.data, m.log_time_ns)
    names = {'/rig/phase_current': 'current_A', '/rig/motor_speed': 'speed_rad_s',
             '/rig/load_dp': 'dp_Pa', '/rig/lvdt': 'position_m'}
    plan = rp.plan_replay(foreign, mapping={n: t for t, n in names.items()})
    assert 'differential' in plan.config_source        # no config stored: found from topics
    mapped = rp.replay(plan, output_rate_Hz=50.0)
    for name, values in result.temperatures_C.items():
        assert np.array_equal(mapped.temperatures_C[name], values), name
    assert math.isclose(mapped.stamp_s[-1], result.stamp_s[-1])


def test_a_topic_mapped_to_several_names_feeds_each(bag, result):
    # each name reads the topic it is mapped to, whatever else reads it too
    plan = rp.plan_replay(bag, mapping={'speed_rad_s': '/eha/current',
                                        'measured/frame': '/eha/ambient'})
    assert plan.inputs['current_A'] == plan.inputs['speed_rad_s'] == '/eha/current'
    shared = rp.replay(plan, output_rate_Hz=50.0)
    received = {name: h['received'] for name, h in shared.health.items()}
    assert received['speed_rad_s'] == received['current_A'] == \
        result.health['current_A']['received'] > 0
    assert shared.measured['frame'][0].size == \
        plan.info.topics['/eha/ambient'].message_count > 0


def test_replay_plan_falls_back_for_a_missing_input(bag, tmp_path):
    partial = tmp_path / 'no_speed.mcap'
    info = open_bag(bag)
    with BagWriter(partial) as w:
        for topic, t in info.topics.items():
            if topic != '/eha/speed':
                w.add_topic(topic, t.type_name, None)
        for m in iter_raw(bag):
            if m.topic != '/eha/speed':
                w.write(m.topic, m.data, m.log_time_ns)
    shutil.copy(partial, tmp_path / 'copy.mcap')
    plan = rp.plan_replay(tmp_path / 'copy.mcap', config_path=None)
    assert plan.missing == ['speed_rad_s']
    res = rp.replay(plan)
    assert res.steps > 900 and res.stale_inputs.max() == 1


def test_a_given_config_with_the_other_pressure_mode_is_stored_in_the_output(bag, tmp_path):
    # the shipped file says three pressures, the bag holds one differential: the mode is
    # switched, and the output stores the given file's text and says what was switched
    plan = rp.plan_replay(bag, config_path=default_config_path())
    assert 'pressure_inputs: differential' in plan.config_source
    assert plan.config_yaml == default_config_path().read_text()
    result = rp.replay(plan)
    out = rp.write_mcap(result, tmp_path / 'estimates.mcap')
    stored = open_bag(out).metadata[interface.CONFIG_METADATA]
    assert stored[interface.CONFIG_METADATA_KEY] == plan.config_yaml
    assert 'differential' in stored['source']


def test_open_loop_replay_leaves_the_thermocouples_out_of_the_model(bag, tmp_path, capsys):
    # the shipped config corrects the model with the thermocouples; --open-loop must give the
    # estimates of a configuration with the correction off, so that the errors against the
    # thermocouples validate the model rather than the filter
    closed, opened = tmp_path / 'closed', tmp_path / 'open'
    assert main(['replay', str(bag), '--out', str(closed), '--no-report']) == 0
    assert main(['replay', str(bag), '--out', str(opened), '--open-loop']) == 0
    capsys.readouterr()
    plan = rp.plan_replay(bag)
    assert plan.cfg.estimator.correction.enabled
    plan.cfg = with_values(plan.cfg, {'estimator.correction.enabled': False})
    off = rp.replay(plan, output_rate_Hz=10.0)
    table = np.genfromtxt(opened / 'estimates.csv', delimiter=',', names=True)
    # the CSV holds 4 decimals
    assert np.allclose(table['winding_mean_C'], off.temperatures_C['winding_mean'], atol=1e-4)
    corrected = np.genfromtxt(closed / 'estimates.csv', delimiter=',', names=True)
    assert np.max(np.abs(corrected['winding_mean_C'] - table['winding_mean_C'])) > 1e-3
    assert 'Off (`--open-loop`' in (opened / 'report.md').read_text()


def test_a_stored_configuration_of_an_older_model_says_to_give_one(tmp_path):
    """A bag recorded before the end spaces took published laws: its key is unknown now."""
    old = default_config_path().read_text().replace(
        '    htc_multiplier: 1.0', '    htc_still_W_m2K: 100.0')
    stored = {interface.CONFIG_METADATA: {interface.CONFIG_METADATA_KEY: old}}
    info = SimpleNamespace(path=tmp_path / 'old.mcap', metadata=stored)
    with pytest.raises(ConfigError, match=r'htc_still_W_m2K.*replay it with --config'):
        rp.choose_config(info, None)
    cfg, source, _ = rp.choose_config(info, default_config_path())
    assert source == str(default_config_path()) and cfg.motor.end_spaces.htc_multiplier == 1.0
