"""
Inputs by configuration, without ROS: the specification's checks, the units, the decoding.

The decoders read the CDR bytes that the package's encoders write (and, in
the last tests, rclpy's own serialisation when rclpy is there); a batched
block taken as arrays steps the estimator exactly as its samples taken one
by one.
"""

import math

import numpy as np
import pytest
from wet_eha_thermal import interface
from wet_eha_thermal.bag import cdr
from wet_eha_thermal.config import ConfigError, load_config
from wet_eha_thermal.estimator.core import INPUTS
from wet_eha_thermal.estimator.session import EstimatorSession
from wet_eha_thermal.inputs import (decoders, encode_batch, Inputs, inputs_from_yaml,
                                    load_inputs, thermocouple_channel, TopicDecoder)
import yaml


def spec(text):
    return inputs_from_yaml(yaml.safe_dump({'inputs': yaml.safe_load(text)}))


def test_default_is_todays_topics_in_si():
    s = load_inputs('')
    for name, topic in interface.INPUT_TOPICS.items():
        sig = getattr(s, name)
        assert (sig.topic, sig.message_type) == (topic, interface.INPUT_TYPES[name])
        assert sig.to_si() == (1.0, 0.0)
    decs = decoders(s, INPUTS)
    assert [d.channels for d in decs] == [(n,) for n in INPUTS]
    assert Inputs() == spec('{}')


@pytest.mark.parametrize('text, message', [
    ('speed_rad_s: {topic: /s, message_type: std_msgs/msg/Float64, unit: bar}',
     "inputs.speed_rad_s.unit = 'bar': not a unit of rad/s; allowed: rad/s, r/min, rpm, deg/s"),
    ('speed_rad_s: {topic: /s, message_type: std_msgs/msg/Float64, unit: furlong}',
     "inputs.speed_rad_s.unit = 'furlong': unknown; allowed: A, "),
    ('current_A: {topic: /j, message_type: sensor_msgs/msg/JointState, unit: A}',
     'inputs.current_A.joint: missing'),
    ('current_A: {topic: /j, message_type: sensor_msgs/msg/JointState, joint: m, field: torque,'
     ' unit: A}', "inputs.current_A.field = 'torque': a sensor_msgs/msg/JointState input reads "
     'one of position, velocity, effort'),
    ('current_A: {topic: /c, message_type: std_msgs/msg/Float64, joint: m, unit: A}',
     'inputs.current_A: joint and field are for sensor_msgs/msg/JointState only'),
    ('current_A: {topic: /b, message_type: std_msgs/msg/Float64MultiArray, column: 4, '
     'columns: 4, unit: A}', 'inputs.current_A.column = 4: must be below'),
    ('position_m: {topic: /p, message_type: std_msgs/msg/Float64, unit: mm, sign: 0}',
     'inputs.position_m.sign = 0: expected 1 or -1'),
    ('position_m: {topic: /p, message_type: std_msgs/msg/Float64, unit: mm, gain: 2.0}',
     'inputs.position_m.gain: unknown key'),
    ('position_m: {topic: /p, message_type: geometry_msgs/msg/Point, unit: m}',
     "inputs.position_m.message_type = 'geometry_msgs/msg/Point': unknown"),
])
def test_a_bad_specification_names_its_key(text, message):
    with pytest.raises(ConfigError) as err:
        spec(text)
    assert message in str(err.value)


def test_one_topic_two_types_is_refused():
    s = spec("""
        current_A: {topic: /rig, message_type: std_msgs/msg/Float64, unit: A}
        speed_rad_s: {topic: /rig, message_type: sensor_msgs/msg/JointState, joint: m,
                      field: velocity, unit: rad/s}""")
    with pytest.raises(ConfigError, match='topic /rig is declared with different types'):
        decoders(s, INPUTS)


def test_a_missing_file_is_named():
    with pytest.raises(ConfigError, match="inputs_file 'no_such.inputs.yaml': cannot read"):
        load_inputs('no_such.inputs.yaml')


def test_units_scale_offset_and_sign():
    s = spec("""
        speed_rad_s: {topic: /speed, message_type: std_msgs/msg/Float64, unit: r/min}
        p_a_Pa: {topic: /pa, message_type: sensor_msgs/msg/FluidPressure, unit: bar,
                 offset: 1.01325}
        position_m: {topic: /pos, message_type: std_msgs/msg/Float64, unit: mm, sign: -1,
                     scale: 0.5}
        current_A: {topic: /i, message_type: std_msgs/msg/Float64, unit: A_peak}""")
    by_channel = {d.channels[0]: d for d in decoders(s, INPUTS)}
    # 3000 r/min = 100 pi rad/s; 2 bar gauge = 301 325 Pa absolute; -0.5 * 8 mm; the RMS of
    # a sine of 10 A amplitude is 10 / sqrt(2)
    assert by_channel['speed_rad_s'].decode(cdr.encode_float64(3000.0)) == \
        (0, [pytest.approx(100.0 * math.pi, rel=1e-15)])
    stamp_ns, (p,) = by_channel['p_a_Pa'].decode(
        cdr.encode_stamped([12_000_000_345], 'pa', [[2.0, 0.0]])[0])
    assert (stamp_ns, p) == (12_000_000_345, pytest.approx(301325.0, rel=1e-15))
    assert by_channel['position_m'].decode(cdr.encode_float64(8.0))[1] == \
        [pytest.approx(-0.004, rel=1e-15)]
    assert by_channel['current_A'].decode(cdr.encode_float64(10.0))[1] == \
        [pytest.approx(10.0 / math.sqrt(2.0), rel=1e-15)]


def test_temperatures_in_degc_degf_or_kelvin_by_name():
    s = spec("""
        ambient: {topic: /air, message_type: std_msgs/msg/Float64, unit: degF}
        thermocouples:
          frame: {topic: /tc, message_type: std_msgs/msg/Float64MultiArray, columns: 2,
                  column: 1, unit: K}
          winding: {topic: /tc, message_type: std_msgs/msg/Float64MultiArray, columns: 2,
                    column: 0, unit: degC, offset: -0.4}""")
    channels = ['ambient'] + [thermocouple_channel(tc) for tc in interface.THERMOCOUPLES]
    by_topic = {d.topic: d for d in decoders(s, channels)}
    # 68 degF is 20 degC (NIST SP 811: T/K = (t/degF + 459.67) / 1.8)
    assert by_topic['/air'].decode(cdr.encode_float64(68.0))[1] == \
        [pytest.approx(293.15, rel=1e-15)]
    # one block carries two thermocouples; the winding's reads 0.4 K high
    block = by_topic['/tc']
    assert block.channels == (thermocouple_channel('winding'), thermocouple_channel('frame'))
    _, values = block.decode_batch(encode_batch(5.0, 0.1, np.array([[30.4, 303.15]])))
    assert values.tolist() == [[pytest.approx(303.15, rel=1e-15)] * 2]
    # the thermocouples not named keep today's topic, a Temperature in degC
    pump = s.signal(thermocouple_channel('pump_case'))
    assert (pump.topic, pump.message_type) == ('/eha/measured/pump_case', interface.TEMPERATURE)
    assert pump.to_si() == (1.0, 273.15)
    for text, message in [
            ('thermocouples: {elbow: {topic: /x, message_type: std_msgs/msg/Float64, unit: K}}',
             'inputs.thermocouples: unknown elbow; allowed: winding, frame, '),
            ('ambient: {topic: /x, message_type: std_msgs/msg/Float64, unit: bar}',
             "inputs.ambient.unit = 'bar': not a unit of K; allowed: K, degC, degF")]:
        with pytest.raises(ConfigError, match=message):
            spec(text)


ROS2_CONTROL = """
    current_A: {topic: /joint_states, message_type: sensor_msgs/msg/JointState,
                joint: motor_joint, field: effort, unit: A_peak}
    speed_rad_s: {topic: /joint_states, message_type: sensor_msgs/msg/JointState,
                  joint: motor_joint, field: velocity, unit: rad/s}
    position_m: {topic: /joint_states, message_type: sensor_msgs/msg/JointState,
                 joint: rod_joint, field: position, unit: m, sign: -1}
"""


@pytest.mark.parametrize('frame_id', ['', 'a', 'base_link', 'abcdefg'])
def test_joint_state_by_name_and_field_in_one_decode(frame_id):
    dec, = [d for d in decoders(spec(ROS2_CONTROL), INPUTS) if d.topic == '/joint_states']
    assert dec.channels == ('current_A', 'speed_rad_s', 'position_m')
    names = ['wheel', 'rod_joint', 'motor_joint']
    msg = cdr.encode_joint_state(5_000_000_007, frame_id, names, [0.1, 0.02, 3.0],
                                 [1.0, 0.0, 300.0], [0.5, 0.0, 20.0])
    ns, values = dec.decode(msg)
    assert ns == 5_000_000_007
    assert values == pytest.approx([20.0 / math.sqrt(2.0), 300.0, -0.02], rel=1e-15)
    # the names cached from that message are checked, not trusted: a new order is read
    msg = cdr.encode_joint_state(6_000_000_000, frame_id, ['motor_joint', 'rod_joint'],
                                 [3.0, 0.03], [250.0, 0.0], [10.0, 0.0])
    assert dec.decode(msg)[1] == pytest.approx([10.0 / math.sqrt(2.0), 250.0, -0.03])
    assert dec.decode(msg)[1] == pytest.approx([10.0 / math.sqrt(2.0), 250.0, -0.03])


def test_joint_state_without_the_joint_or_its_field_says_which():
    dec, = decoders(spec(ROS2_CONTROL), ['current_A'])
    with pytest.raises(ValueError, match="no joint 'motor_joint' in the message"):
        dec.decode(cdr.encode_joint_state(1, '', ['rod_joint'], [0.0], [0.0], [0.0]))
    with pytest.raises(ValueError, match="joint 'motor_joint' has no effort"):
        dec.decode(cdr.encode_joint_state(1, '', ['motor_joint'], [0.0], [1.0], []))


BATCH = """
    current_A: {topic: /daq, message_type: std_msgs/msg/Float64MultiArray, column: 0,
                columns: 3, unit: A}
    p_a_Pa: {topic: /daq, message_type: std_msgs/msg/Float64MultiArray, column: 2,
             columns: 3, unit: bar}
"""


def test_batched_block_gives_each_sample_its_stamp():
    dec, = decoders(spec(BATCH), ['current_A', 'p_a_Pa'])
    assert dec.batched and dec.channels == ('current_A', 'p_a_Pa')
    rng = np.random.default_rng(1)
    block = rng.normal(size=(80, 3))
    t0, dt = 1_790_000_000.125, 2.5e-4
    stamps, values = dec.decode_batch(encode_batch(t0, dt, block))
    assert stamps == pytest.approx(t0 + dt * np.arange(80), abs=1e-6)
    assert np.array_equal(values, block[:, [0, 2]] * [1.0, 1e5])
    with pytest.raises(ValueError, match='not a block of 3 column'):
        dec.decode_batch(encode_batch(t0, dt, block[:, :2]))
    with pytest.raises(ValueError, match='dt_s > 0'):
        dec.decode_batch(encode_batch(t0, 0.0, block))


def test_big_endian_cdr_is_read_too():
    dec = TopicDecoder('/s', [('speed_rad_s', spec(
        'speed_rad_s: {topic: /s, message_type: std_msgs/msg/Float64, unit: rad/s}'
    ).speed_rad_s)])
    assert dec.decode(b'\x00\x00\x00\x00' + np.array([12.5], '>f8').tobytes()) == (0, [12.5])
    with pytest.raises(ValueError, match='only plain CDR'):
        dec.decode(b'\x00\x07\x00\x00' + bytes(8))


def test_a_block_steps_the_estimator_as_its_samples_one_by_one():
    cfg = load_config()
    one, many = EstimatorSession(cfg), EstimatorSession(cfg)
    rate, block = 4000.0, 40                       # 4 kHz in 10 ms blocks
    t = np.arange(1, 2 * 4000 + 1) / rate          # 2 s
    signals = {'current_A': 15.0 + 5.0 * np.sin(2 * np.pi * 7.0 * t),
               'speed_rad_s': 800.0 + 0.0 * t, 'p_a_Pa': 3e6 + 0.0 * t,
               'p_b_Pa': 1e6 + 0.0 * t, 'p_acc_Pa': 1e6 + 0.0 * t,
               'position_m': 1e-3 * np.sin(t)}
    got_one, got_many = [], []
    for k in range(0, t.size, block):
        for i in range(k, k + block):
            for ch in INPUTS:
                got_one += one.take(ch, t[i], signals[ch][i], t[i])
        for ch in INPUTS:
            got_many += many.take_many(ch, t[k:k + block], signals[ch][k:k + block],
                                       t[k + block - 1])
    assert len(got_one) == len(got_many) > 90
    assert [e.stamp_s for e in got_one] == [e.stamp_s for e in got_many]
    assert got_one[-1].temperatures_C == got_many[-1].temperatures_C
    for est in (one, many):              # screens what the last block left
        est.step(t[-1])
        assert (est.health['current_A'].received, est.health['current_A'].accepted) == \
            (t.size, t.size)


def test_rclpy_serialisation_decodes_the_same():
    pytest.importorskip('rclpy')
    from rclpy.serialization import deserialize_message, serialize_message
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray, MultiArrayDimension
    msg = JointState(name=['rod_joint', 'x', 'motor_joint'], position=[0.01, 0.0, 1.0],
                     velocity=[0.0, 0.0, 123.0], effort=[0.0, 0.0, 14.0])
    msg.header.stamp.sec, msg.header.stamp.nanosec = 17, 42
    msg.header.frame_id = 'rig'
    dec, = [d for d in decoders(spec(ROS2_CONTROL), INPUTS) if d.topic == '/joint_states']
    assert dec.decode(serialize_message(msg)) == (
        17_000_000_042, pytest.approx([14.0 / math.sqrt(2.0), 123.0, -0.01]))
    arr = Float64MultiArray(data=[10.0, 0.5] + list(range(9)))
    arr.layout.data_offset = 2
    arr.layout.dim = [MultiArrayDimension(label='samples', size=3, stride=9),
                      MultiArrayDimension(label='columns', size=3, stride=3)]
    data = serialize_message(arr)
    dec, = decoders(spec(BATCH), ['current_A', 'p_a_Pa'])
    stamps, values = dec.decode_batch(data)
    assert list(stamps) == [10.0, 10.5, 11.0]
    assert values.tolist() == [[0.0, 2e5], [3.0, 5e5], [6.0, 8e5]]
    # ours is rclpy's message (byte for byte but the padding, which rclpy leaves unset)
    assert deserialize_message(encode_batch(10.0, 0.5, np.arange(9.0).reshape(3, 3)),
                               Float64MultiArray) == arr
