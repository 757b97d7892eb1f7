"""Offline replay of bags through the estimator: round trip, determinism, damaged input."""

import itertools
import json
import math
import shutil
from types import SimpleNamespace

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from rosbags.rosbag2 import Reader
from rosbags.typesys import get_typestore, Stores
from sensor_msgs.msg import FluidPressure, Temperature
from std_msgs.msg import Float64, Float64MultiArray
from wet_eha_thermal import inputs, interface
from wet_eha_thermal.bag import cdr
from wet_eha_thermal.bag.reader import iter_raw, open_bag
from wet_eha_thermal.bag.writer import BagWriter
from wet_eha_thermal.cli import main
from wet_eha_thermal.config import ConfigError, default_config_path, with_values
from wet_eha_thermal.estimator.alerts import Level
from wet_eha_thermal.estimator.session import EstimatorSession
from wet_eha_thermal.estimator.uncertainty import HEATING_STEPS, HEATING_WAIT_PER_STEP_S
from wet_eha_thermal.interface import LimitStatus
from wet_eha_thermal.offline import replay as rp
from wet_eha_thermal.ros.recorder_node import recorded_topics

pytestmark = pytest.mark.slow     # measured: see docs/development.md#tests-and-ci

#: the log's length (s): every claim here holds from the first limits' tick (0.5 s) and the
#: correction's start (a few seconds of readings) on; 12 s give 24 ticks and 600 estimates
SECONDS = 12.0


@pytest.fixture(scope='module')
def bag(tmp_path_factory, record_rig_log):
    """SECONDS of stage 6 on the simulated rig (one differential pressure), config stored."""
    return record_rig_log(tmp_path_factory.mktemp('bags') / 'stage6.mcap', SECONDS, seed=7)


@pytest.fixture(scope='module')
def result(bag):
    return rp.replay(rp.plan_replay(bag), output_rate_Hz=50.0)


def test_cli_writes_estimates_and_report(bag, tmp_path, capsys):
    out = tmp_path / 'out'
    assert main(['replay', str(bag), '--out', str(out)]) == 0
    text = capsys.readouterr().out
    assert 'stored in stage6.mcap' in text
    assert 'dp_Pa <- /eha/pressure_diff' in text and 'outputs under /eha' in text
    assert 'winding_mean      - winding' in text
    for name in ('estimates.csv', 'estimates.mcap', 'limits.csv', 'report.md', 'inputs.png',
                 'temperatures.png', 'errors.png', 'alerts.png', 'limits.png'):
        assert (out / name).stat().st_size > 0, name
    assert not list(out.glob('*.partial*'))
    table = np.genfromtxt(out / 'estimates.csv', delimiter=',', names=True)
    assert abs(len(table) - SECONDS * 10) <= 2            # 10 Hz by default
    assert np.all(np.diff(table['stamp_s']) > 0)
    report = (out / 'report.md').read_text()
    assert '| winding | winding_mean |' in report


def test_estimates_mcap_reads_back_with_an_independent_decoder(result, tmp_path):
    # the live node's form: each estimate with its own variance, the state with its names,
    # the alert summary as JSON
    path = rp.write_mcap(result, tmp_path / 'estimates.mcap')
    got, state, summaries, numbers, names = {}, {}, [], [], None
    with open(path, 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, msg in reader.iter_decoded_messages():
            if channel.topic.startswith(interface.ESTIMATE_PREFIX):
                assert schema.name == 'sensor_msgs/msg/Temperature'
            if channel.topic == '/eha/estimate/winding_hotspot':
                stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
                got[round(stamp, 6)] = (msg.temperature, msg.variance)
            elif channel.topic == interface.STATE_TOPIC:
                state[message.log_time] = list(msg.data)
            elif channel.topic == interface.STATE_NAMES_TOPIC:
                names = json.loads(msg.data)['names']
            elif channel.topic == interface.ALERT_TOPIC:
                summaries.append(json.loads(msg.data))
            elif channel.topic == interface.DRIVE_ALERTS_TOPIC:
                numbers.append(interface.DriveAlerts.from_data(list(msg.data)))
    assert len(got) == len(state) == len(result.stamp_s)
    for k, stamp in enumerate(result.stamp_s):
        temperature, variance = got[round(float(stamp), 6)]
        assert temperature == result.temperatures_C['winding_hotspot'][k]
        assert variance == result.uncertainty_K['winding_hotspot'][k] ** 2
        assert state[round(float(stamp) * 1e9)] == result.state_K[k].tolist()
    assert names == list(result.state_names) and len(names) == result.state_K.shape[1]
    # the first summary is the one a node publishes at its start; the last the run's end
    assert len(summaries) == len(result.alerts) >= 1
    assert summaries[-1]['level'] == result.alert_level[-1]
    assert {'data_gaps', 'clock_jumps', 'events', 'quantities'} <= set(summaries[-1])
    # each summary again as the drive's numbers, numbered from 1
    assert [a.sequence for a in numbers] == list(range(1, len(summaries) + 1))
    assert [(a.level, [(q.quantity, q.reported, q.acknowledged) for q in a.quantities])
            for a in numbers] == [
        (s['level'], [(q, Level[d['reported']], d['acknowledged'])
                      for q, d in s['quantities'].items()]) for s in summaries]
    assert open_bag(path).metadata[interface.CONFIG_METADATA][interface.CONFIG_METADATA_KEY]


def test_replay_equals_the_live_estimator_fed_sample_by_sample(bag, result):
    # the live node adds each sample as it arrives and advances when one may close a
    # step; the replay adds 10 s blocks: in sample time both must give the same numbers
    # (the thermocouples too: the live correction uses each reading by its stamp)
    plan = rp.plan_replay(bag)
    limits = []
    est = EstimatorSession(plan.cfg, outlook='inline',
                           publish=lambda out: limits.extend(out.limits))
    by_topic = {topic: name for name, topic in plan.inputs.items()}
    by_tc = {topic: tc for tc, topic in plan.thermocouples.items()}
    live, margin = {}, {}
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
        for e in est.take(name, t, v):
            live[e.stamp_s] = e.temperatures_C
            margin[e.stamp_s] = e.margin_current_A
    # 50 estimates and correction steps a second, less the start
    assert len(live) == len(result.stamp_s) > 45 * SECONDS
    assert result.correction['active'] and est.correction_summary()['updates'] > 45 * SECONDS
    assert est.correction_summary()['updates'] == result.correction['updates']
    for k, stamp in enumerate(result.stamp_s):
        for name in ('winding_hotspot', 'magnet', 'oil', 'chamber_a'):
            assert live[stamp][name] == result.temperatures_C[name][k], (stamp, name)
    # the limits, forecast and margin too, at the same ticks: every 0.5 s of sample time
    assert len(limits) == len(result.current_limits) >= 2 * SECONDS - 2
    assert limits == result.current_limits
    assert np.array_equal([math.nan if margin[s] is None else margin[s] for s in result.stamp_s],
                          result.margin_current_A, equal_nan=True)
    assert est.latest.time_to_limit_s and est.latest.time_to_limit_s == {
        q: None if math.isinf(v[-1]) else v[-1] for q, v in result.time_to_limit_s.items()}
    again = rp.replay(rp.plan_replay(bag), output_rate_Hz=50.0)
    for name, values in result.temperatures_C.items():
        assert np.array_equal(again.temperatures_C[name], values), name
    assert again.current_limits == result.current_limits
    assert np.array_equal(again.limits_current_A, result.limits_current_A, equal_nan=True)
    for q, values in result.time_to_limit_s.items():
        assert np.array_equal(again.time_to_limit_s[q], values, equal_nan=True), q


def test_limits_csv_and_mcap_topics_hold_every_tick(result, tmp_path):
    # the live node's messages, read back with rosbags (an independent reader), and the
    # CSV at full precision: the numbers of the result, bit for bit
    mcap = rp.write_mcap(result, tmp_path / 'estimates.mcap')
    lims = result.current_limits
    assert len(lims) >= 2 * SECONDS - 2
    # the first ticks the fallback while the uncertainty's copies are heated on a cold start,
    # at least HEATING_WAIT_PER_STEP_S for each of the heating's fewest steps
    # (docs/live.md#current-limits-for-the-drive), every later one computed
    heating = list(itertools.takewhile(lambda lim: lim.code == LimitStatus.UNCERTAIN, lims))
    assert heating and (heating[-1].stamp_s - heating[0].stamp_s
                        >= HEATING_STEPS * HEATING_WAIT_PER_STEP_S - 0.5)
    first_ok = lims[len(heating)]
    assert all(b - a == pytest.approx(0.5) for a, b in zip(
        [lim.stamp_s for lim in lims], [lim.stamp_s for lim in lims[1:]]))
    typestore = get_typestore(Stores.ROS2_JAZZY)
    got = {interface.CURRENT_LIMITS_TOPIC: [], interface.CURRENT_LIMIT_TOPIC: []}
    with Reader(mcap) as reader:
        # the topics and types a live recording has (the recorder's), for a comparison
        for topic in got:
            assert reader.topics[topic].msgtype == recorded_topics()[topic][0]
        wanted = [c for c in reader.connections if c.topic in got]
        for connection, log_ns, data in reader.messages(connections=wanted):
            got[connection.topic].append(
                (log_ns, typestore.deserialize_cdr(data, connection.msgtype)))
    assert len(got[interface.CURRENT_LIMITS_TOPIC]) == len(got[interface.CURRENT_LIMIT_TOPIC]) \
        == len(lims)
    for lim, (log_ns, msg), (log_ns1, scalar) in zip(lims, *got.values()):
        stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        assert log_ns == log_ns1 == stamp_ns == round(lim.stamp_s * 1e9)
        assert msg.header.frame_id == lim.frame_id
        assert lim.status == ('ok' if lim.stamp_s >= first_ok.stamp_s else 'fallback')
        assert tuple(msg.name) == lim.names == ('continuous', '10s', '60s', '600s')
        assert tuple(msg.position.tolist()) == lim.horizons_s
        assert tuple(msg.effort.tolist()) == lim.limits_A and not msg.velocity.size
        assert scalar.data == lim.binding_A == lim.limits_A[1]
    assert min(lim.binding_A for lim in lims) > 0.0
    path = rp.write_limits_csv(result, tmp_path / 'limits.csv')
    rows = np.genfromtxt(path, delimiter=',', names=True, dtype=None, encoding='utf-8')
    assert len(rows) == len(lims)
    assert rows['stamp_s'].tolist() == [lim.stamp_s for lim in lims]
    assert rows['binding_A'].tolist() == [lim.binding_A for lim in lims]
    assert rows['limit_600s_A'].tolist() == [lim.limits_A[3] for lim in lims]
    assert rows['binds_continuous'].tolist() == [lim.binds[0] for lim in lims]
    assert rows['held_s'].tolist() == result.limits_held_s.tolist()
    assert np.array_equal(rows['current_rms_A'], result.limits_current_A, equal_nan=True)
    # the current under each tick's limits: RMS of a positive, moving signal
    assert np.all(result.limits_current_A[:-1] > 0.0)
    # and the estimates' columns: the forecast from the first tick on, the margin from the
    # first computed one
    table = np.genfromtxt(rp.write_csv(result, tmp_path / 'estimates.csv'), delimiter=',',
                          names=True)
    forecast = table['stamp_s'] >= lims[0].stamp_s - 1e-6
    ticked = table['stamp_s'] >= first_ok.stamp_s - 1e-6
    assert ticked.any() and not ticked.all()
    assert np.all(np.isnan(table['margin_current_A'][~ticked]))
    assert not np.isnan(table['margin_current_A'][ticked]).any()
    for column in ('forecast_stamp_s', 'time_to_limit_winding_hotspot_s'):
        assert np.all(np.isnan(table[column][~forecast])), column
        assert not np.isnan(table[column][forecast]).any(), column
    assert np.allclose(table['margin_current_A'], result.margin_current_A, atol=1e-3,
                       equal_nan=True)
    assert np.all(table['margin_current_A'][ticked] > 0.0)
    assert np.all(table['time_to_limit_winding_hotspot_s'][ticked] > 0.0)


def test_no_outlook_writes_no_limits(bag, tmp_path, capsys):
    out = tmp_path / 'out'
    assert main(['replay', str(bag), '--out', str(out), '--no-outlook']) == 0
    assert 'limits.csv' not in capsys.readouterr().out
    assert not (out / 'limits.csv').exists() and not (out / 'limits.png').exists()
    assert not set(open_bag(out / 'estimates.mcap').topics) & {
        interface.CURRENT_LIMITS_TOPIC, interface.CURRENT_LIMIT_TOPIC}
    header = (out / 'estimates.csv').read_text().splitlines()[0]
    assert 'margin' not in header and 'time_to_limit' not in header
    assert 'Not computed (`--no-outlook`)' in (out / 'report.md').read_text()


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
    mapped = rp.replay(plan, output_rate_Hz=50.0, outlook=False)
    for name, values in result.temperatures_C.items():
        assert np.array_equal(mapped.temperatures_C[name], values), name
    assert math.isclose(mapped.stamp_s[-1], result.stamp_s[-1])


def test_a_topic_mapped_to_several_names_feeds_each(bag, result):
    # each name reads the topic it is mapped to, whatever else reads it too
    plan = rp.plan_replay(bag, mapping={'speed_rad_s': '/eha/current',
                                        'measured/frame': '/eha/ambient'})
    assert plan.inputs['current_A'] == plan.inputs['speed_rad_s'] == '/eha/current'
    shared = rp.replay(plan, output_rate_Hz=50.0, outlook=False)
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
    # below the log's current (about 1.5 A RMS), the conservative limit binds
    plan.cfg = with_values(plan.cfg, {'estimator.limits.fallback_current_A': 1.0})
    res = rp.replay(plan)
    assert res.steps > 45 * SECONDS and res.stale_inputs.max() == 1
    # a stale input all along: every tick on the fallback, saying why
    assert {(lim.status, lim.reason, lim.binding_A) for lim in res.current_limits} == {
        ('fallback', 'stale inputs: speed_rad_s', 1.0)}
    report = rp.write_report(res, tmp_path / 'report').read_text()
    # the ticks' limits hold from the first tick to the log's end
    held = res.limits_held_s.sum()
    assert held == pytest.approx(res.sample_time_s - 0.5, abs=0.5)
    assert f'On the fallback (1 A at most): {held:.1f} s of {held:.1f} s' in report
    assert f'| stale inputs | {held:.1f} | ' in report
    # and the current was above that limit all along
    assert np.all(res.limits_current_A > 1.0)
    assert '| 10s (binding) | 1.00 | ' in report and f'| fallback | {held:.1f} |' in report
    assert (tmp_path / 'report' / 'limits.png').stat().st_size > 0


def test_a_given_config_with_the_other_pressure_mode_is_stored_in_the_output(bag, tmp_path):
    # the shipped file says three pressures, the bag holds one differential: the mode is
    # switched, and the output stores the given file's text and says what was switched
    plan = rp.plan_replay(bag, config_path=default_config_path())
    assert 'pressure_inputs: differential' in plan.config_source
    assert plan.config_yaml == default_config_path().read_text()
    result = rp.replay(plan, outlook=False)
    out = rp.write_mcap(result, tmp_path / 'estimates.mcap')
    stored = open_bag(out).metadata[interface.CONFIG_METADATA]
    assert stored[interface.CONFIG_METADATA_KEY] == plan.config_yaml
    assert 'differential' in stored['source']


def test_open_loop_replay_leaves_the_thermocouples_out_of_the_model(bag, tmp_path, capsys):
    # the shipped config corrects the model with the thermocouples; --open-loop must give the
    # estimates of a configuration with the correction off, so that the errors against the
    # thermocouples validate the model rather than the filter
    closed, opened = tmp_path / 'closed', tmp_path / 'open'
    # (the outlook is not what this is about: off, for speed)
    assert main(['replay', str(bag), '--out', str(closed), '--no-report', '--no-outlook']) == 0
    assert main(['replay', str(bag), '--out', str(opened), '--open-loop', '--no-outlook']) == 0
    capsys.readouterr()
    plan = rp.plan_replay(bag)
    assert plan.cfg.estimator.correction.enabled
    plan.cfg = with_values(plan.cfg, {'estimator.correction.enabled': False})
    off = rp.replay(plan, output_rate_Hz=10.0, outlook=False)
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


#: The bag's inputs as a ros2_control rig publishes them: joint_state_broadcasters, each in
#: its rig's units (A amplitude, r/min, mm the other way round, bar, degF for the air)
JOINT_INPUTS = """
inputs:
  current_A: {topic: /joint_states, message_type: sensor_msgs/msg/JointState,
              joint: eha_motor, field: effort, unit: A_peak}
  speed_rad_s: {topic: /joint_states, message_type: sensor_msgs/msg/JointState,
                joint: eha_motor, field: velocity, unit: r/min}
  position_m: {topic: /joint_states, message_type: sensor_msgs/msg/JointState,
               joint: eha_rod, field: position, unit: mm, sign: -1}
  dp_Pa: {topic: /pressure_state_broadcaster/joint_states,
          message_type: sensor_msgs/msg/JointState, joint: pressure_diff, field: effort,
          unit: bar}
  ambient: {topic: /air_state_broadcaster/joint_states, message_type: sensor_msgs/msg/JointState,
            joint: air, field: effort, unit: degF}
  thermocouples:
    frame: {topic: /temperature_state_broadcaster/joint_states,
            message_type: sensor_msgs/msg/JointState, joint: tc_frame, field: effort,
            unit: degC}
"""
#: default topic -> (joint_states topic, joint, its field, the rig's raw value of the SI one)
AS_JOINTS = {
    '/eha/current': ('/joint_states', 'eha_motor', 'effort', lambda v: v * math.sqrt(2.0)),
    '/eha/speed': ('/joint_states', 'eha_motor', 'velocity', lambda v: v * 30.0 / math.pi),
    '/eha/position': ('/joint_states', 'eha_rod', 'position', lambda v: -v * 1e3),
    '/eha/pressure_diff': ('/pressure_state_broadcaster/joint_states', 'pressure_diff',
                           'effort', lambda v: v / 1e5),
    '/eha/ambient': ('/air_state_broadcaster/joint_states', 'air', 'effort',
                     lambda v: v * 1.8 + 32.0),
    '/eha/measured/frame': ('/temperature_state_broadcaster/joint_states', 'tc_frame', 'effort',
                            lambda v: v),
}


def _as_joint_states(bag, path):
    """Write ``bag`` again as a ros2_control rig would publish it, its inputs file stored."""
    info = open_bag(bag)
    joints = {}                        # (topic, log time, stamp) -> {joint: {field: value}}
    others = []
    for m in iter_raw(bag):
        if m.topic not in AS_JOINTS:
            others.append((m.log_time_ns, m.topic, m.data))
            continue
        topic, joint, field, raw = AS_JOINTS[m.topic]
        if m.type_name == interface.FLOAT64:     # stamped on arrival: the log time
            stamp, value = m.log_time_ns, cdr.float64_data(m.data)
        else:
            stamp, value = cdr.header_stamp_and_value(m.data)
            stamp = stamp or m.log_time_ns
        joints.setdefault((topic, m.log_time_ns, stamp), {}).setdefault(joint, {})[field] = \
            raw(value)
    for (topic, log_ns, stamp), by_joint in joints.items():
        names = sorted(by_joint)
        per_field = [[by_joint[j].get(f, 0.0) for j in names]
                     for f in ('position', 'velocity', 'effort')]
        others.append((log_ns, topic, cdr.encode_joint_state(stamp, 'rig', names, *per_field)))
    metadata = {interface.CONFIG_METADATA: info.metadata[interface.CONFIG_METADATA]}
    metadata[interface.INPUTS_METADATA] = {'path': 'rig.inputs.yaml',
                                           interface.CONFIG_METADATA_KEY: JOINT_INPUTS}
    with BagWriter(path, metadata=metadata) as w:
        for topic, t in info.topics.items():
            if topic not in AS_JOINTS:
                w.add_topic(topic, t.type_name, None)
        for topic in {t for t, *_ in AS_JOINTS.values()}:
            w.add_topic(topic, interface.JOINT_STATE, None)
        for log_ns, topic, data in sorted(others, key=lambda x: x[0]):
            w.write(topic, data, log_ns)
    return path


def test_a_ros2_control_bag_replays_by_its_stored_inputs_file(bag, result, tmp_path):
    """The same samples as JointStates in the rig's units give the same estimates."""
    rig = _as_joint_states(bag, tmp_path / 'joint_states.mcap')
    plan = rp.plan_replay(rig)
    assert plan.inputs_source == 'stored in joint_states.mcap (rig.inputs.yaml)'
    assert plan.inputs == {'current_A': '/joint_states', 'speed_rad_s': '/joint_states',
                           'dp_Pa': '/pressure_state_broadcaster/joint_states',
                           'position_m': '/joint_states'}
    assert plan.ambient == '/air_state_broadcaster/joint_states'
    assert plan.thermocouples['frame'] == '/temperature_state_broadcaster/joint_states'
    # the other thermocouples stay on their default topics
    assert plan.thermocouples['winding'] == '/eha/measured/winding'
    assert set(plan.decoded) == {'/joint_states', '/pressure_state_broadcaster/joint_states',
                                 '/air_state_broadcaster/joint_states',
                                 '/temperature_state_broadcaster/joint_states'}
    assert not any(t.startswith('/eha/') and t != '/eha/measured/winding'
                   and '/measured/' not in t for t in plan.specs)
    joint = rp.replay(plan, output_rate_Hz=50.0, outlook=False)
    assert np.array_equal(joint.stamp_s, result.stamp_s)
    # the units' round trips (A peak, r/min, mm, bar, degF) cost a few ulps of each sample:
    # the estimates agree far below what any figure of the twin shows (1 nK)
    for name, values in result.temperatures_C.items():
        np.testing.assert_allclose(joint.temperatures_C[name], values, rtol=0.0, atol=1e-9,
                                   err_msg=name)
    for tc, (t, v) in result.measured.items():
        np.testing.assert_allclose(joint.measured[tc][1], v, rtol=0.0, atol=1e-12, err_msg=tc)
        assert np.array_equal(joint.measured[tc][0], t), tc
    assert {n: h['received'] for n, h in joint.health.items()} == \
        {n: h['received'] for n, h in result.health.items()}


def test_without_its_inputs_file_a_ros2_control_bag_says_what_to_give(bag, tmp_path):
    rig = _as_joint_states(bag, tmp_path / 'joint_states.mcap')
    with pytest.raises(rp.ReplayError, match='no topic of the mapping is in the bag .* inputs '
                       'file: given.*give the inputs file with --inputs'):
        rp.plan_replay(rig, inputs=inputs.Inputs())
    # a given inputs file wins over the stored one; its type must be the bag's
    wrong = inputs.inputs_from_yaml(JOINT_INPUTS.replace(
        '/pressure_state_broadcaster/joint_states', '/eha/measured/winding'))
    with pytest.raises(rp.ReplayError, match=r'topic /eha/measured/winding \(dp_Pa\) holds '
                       'sensor_msgs/msg/Temperature; expected sensor_msgs/msg/JointState'):
        rp.plan_replay(rig, inputs=wrong)


def test_an_actuator_in_a_namespace_replays_under_its_recorded_prefix(bag, result, tmp_path):
    """A recorder under /left stored its topic_prefix: the replay reads /left, no --map."""
    left = tmp_path / 'left.mcap'
    info = open_bag(bag)
    metadata = {interface.CONFIG_METADATA: info.metadata[interface.CONFIG_METADATA],
                interface.RECORDER_METADATA: {'parameters': 'topic_prefix: /left\n'}}
    with BagWriter(left, metadata=metadata) as w:
        for topic, t in info.topics.items():
            w.add_topic(interface.prefixed(topic, '/left'), t.type_name, None)
        for m in iter_raw(bag):
            w.write(interface.prefixed(m.topic, '/left'), m.data, m.log_time_ns)
    plan = rp.plan_replay(left)
    assert plan.inputs['current_A'] == '/left/current'
    assert plan.thermocouples['frame'] == '/left/measured/frame'
    assert plan.ambient == '/left/ambient'
    moved = rp.replay(plan, output_rate_Hz=50.0, outlook=False)
    for name, values in result.temperatures_C.items():
        assert np.array_equal(moved.temperatures_C[name], values), name
    # its estimates.mcap is under /left too, each topic with the type a live node under
    # /left publishes it with: the replay compares topic for topic with that recording
    assert plan.prefix == '/left'
    written = open_bag(rp.write_mcap(moved, tmp_path / 'left_estimates.mcap')).topics
    live = interface.topic_table('/left')
    assert {t: i.type_name for t, i in written.items()} == {t: live[t][0] for t in written}
    assert '/left/estimate/winding_hotspot' in written and '/left/drive/alerts' in written
    # message for message the /eha replay's, the state naming where its names are now
    eha = {}
    for m in iter_raw(rp.write_mcap(result, tmp_path / 'eha_estimates.mcap')):
        eha.setdefault(m.topic, []).append(m.data)
    for m in iter_raw(tmp_path / 'left_estimates.mcap', ['/left/estimate/magnet']):
        assert m.data == eha['/eha/estimate/magnet'].pop(0)
    assert not eha['/eha/estimate/magnet']          # as many, none left over
    state = next(iter_raw(tmp_path / 'left_estimates.mcap', ['/left/state']))
    msg = deserialize_message(state.data, Float64MultiArray)
    assert msg.layout.dim[0].label == 'state_K: names on /left/state_names'
    assert msg.data.tolist() == result.state_K[0].tolist()
    # --prefix puts them elsewhere; it must be a prefix
    options = rp.ReplayOptions(prefix='/right/')
    assert options.plan(left).prefix == '/right'
    with pytest.raises(rp.ReplayError, match="--prefix 'right'"):
        rp.ReplayOptions(prefix='right')
