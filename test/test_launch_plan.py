"""The launch file's decisions: which nodes of which actuators, in which namespace, what port."""

import importlib.util
from pathlib import Path
import py_compile
import re

import pytest
from wet_eha_thermal import launch_plan
from wet_eha_thermal.launch_plan import Actuator, actuators_from_yaml, plan, plan_from_arguments
from wet_eha_thermal.ros import estimator_node, recorder_node

ROOT = Path(__file__).resolve().parents[1]
LAUNCH_FILE = ROOT / 'launch' / 'eha_twin.launch.py'
SHARE = '/opt/share/wet_eha_thermal'
SHIPPED_PARAMS = f'{SHARE}/config/estimator.params.yaml'


def _launch_arguments():
    """Return the launch file's ARGUMENTS (the file imports no launch at its top)."""
    spec = importlib.util.spec_from_file_location('eha_twin_launch', LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.ARGUMENTS


def _defaults(**changes):
    args = {name: default for name, (default, _) in _launch_arguments().items()}
    args.update(changes)
    return args


def _own(node):
    """Return the node's own parameter dict (the last entry; the first is the params file)."""
    return node.parameters[-1]


def test_the_launch_file_compiles_and_its_defaults_plan_the_one_eha_actuator():
    py_compile.compile(str(LAUNCH_FILE), doraise=True)
    nodes = plan_from_arguments(_defaults(), SHARE)
    assert [(n.executable, n.name, n.namespace) for n in nodes] == [
        ('wet-eha-thermal-rig', 'eha_sim_rig', '/eha'),
        ('wet-eha-thermal-estimator', 'eha_thermal_estimator', '/eha'),
        ('wet-eha-thermal-record', 'eha_recorder', '/eha')]
    assert all(n.parameters[0] == SHIPPED_PARAMS for n in nodes)
    rig, est, rec = nodes
    assert _own(rig) == {'use_sim_time': False, 'stage': 6, 'duty_file': '',
                         'honour_limit': False}
    assert _own(est) == {'use_sim_time': False}
    assert est.foxglove_port is None and 'foxglove_address' not in _own(est)
    assert _own(rec) == {'use_sim_time': False, 'params_file': SHIPPED_PARAMS, 'output': '',
                         'wait_for_estimator': True}
    assert rec.arguments == ['--executor', 'events']


def test_every_executable_is_a_console_script():
    scripts = set(re.findall(r"'([\w-]+) = wet_eha_thermal", (ROOT / 'setup.py').read_text()))
    assert {n.executable for n in plan_from_arguments(_defaults(), SHARE)} <= scripts


def test_two_actuators_share_no_namespace_port_or_output():
    nodes = plan_from_arguments(_defaults(actuators='left, right', view='true',
                                          foxglove_port='9000', record_output='runs/two',
                                          executor='single'), SHARE)
    assert [(n.name, n.namespace) for n in nodes] == [
        (name, ns) for ns in ('/left', '/right')
        for name in ('eha_sim_rig', 'eha_thermal_estimator', 'eha_recorder')]
    ests = [n for n in nodes if n.name == 'eha_thermal_estimator']
    assert [e.foxglove_port for e in ests] == [9000, 9001]
    assert [_own(e)['foxglove_address'] for e in ests] == ['127.0.0.1:9000', '127.0.0.1:9001']
    assert [_own(n)['output'] for n in nodes if n.name == 'eha_recorder'] == [
        'runs/two/left', 'runs/two/right']
    assert {tuple(n.arguments) for n in nodes if n.name != 'eha_recorder'} == {
        ('--executor', 'single')}
    # no hardware_id given: each node derives its own from its namespace
    assert not any('hardware_id' in _own(n) for n in nodes)


def test_no_rigs_no_recorder():
    nodes = plan_from_arguments(_defaults(actuators='left,right', sim_rigs='false',
                                          record='false'), SHARE)
    assert [(n.name, n.namespace) for n in nodes] == [
        ('eha_thermal_estimator', '/left'), ('eha_thermal_estimator', '/right')]


def test_managed_estimators_start_as_lifecycle_nodes():
    nodes = plan_from_arguments(_defaults(actuators='left,right', managed='true'), SHARE)
    est = [n for n in nodes if n.name == 'eha_thermal_estimator']
    assert len(est) == 2 and all('--managed' in n.arguments for n in est)
    assert all('--managed' not in n.arguments for n in nodes if n not in est)
    plain = plan_from_arguments(_defaults(actuators='left,right'), SHARE)
    assert all('--managed' not in n.arguments for n in plain)


ACTUATORS = """
actuators:
  - namespace: /rig_pc/left
    config_file: /rigs/left.yaml
    params_file: /rigs/left.params.yaml
    inputs_file: ros2_control_rig.inputs.yaml
    hardware_id: eha-sn-0042
    stage: 2
    remappings: {/joint_states: /left/joint_states}
  - namespace: right
"""


def _sim_inputs(tmp_path):
    """Return ACTUATORS with an inputs file a simulated rig feeds (the defaults, in a file)."""
    same = tmp_path / 'sim.inputs.yaml'
    same.write_text('inputs:\n  current_A: {topic: /eha/current, message_type: '
                    'std_msgs/msg/Float64, unit: A}\n')
    return ACTUATORS.replace('ros2_control_rig.inputs.yaml', str(same)), str(same)


def test_an_actuators_file_gives_each_its_own_files(tmp_path):
    path = tmp_path / 'rigs.yaml'
    text, inputs_file = _sim_inputs(tmp_path)
    path.write_text(text)
    nodes = plan_from_arguments(_defaults(actuators_file=str(path), stage='5'), SHARE)
    left = [n for n in nodes if n.namespace == '/rig_pc/left']
    right = [n for n in nodes if n.namespace == '/right']
    assert len(left) == len(right) == 3
    for n in left:
        assert n.parameters[0] == '/rigs/left.params.yaml'
        assert _own(n)['config_file'] == '/rigs/left.yaml'
        assert _own(n)['hardware_id'] == 'eha-sn-0042'
        assert n.remappings == [('/joint_states', '/left/joint_states')]
    for n in right:
        assert n.parameters[0] == SHIPPED_PARAMS and n.remappings == []
        assert 'config_file' not in _own(n) and 'hardware_id' not in _own(n)
    by_name = {(n.namespace, n.name): n for n in nodes}
    assert _own(by_name['/rig_pc/left', 'eha_sim_rig'])['stage'] == 2
    assert _own(by_name['/right', 'eha_sim_rig'])['stage'] == 5
    for node in ('eha_thermal_estimator', 'eha_recorder'):
        assert _own(by_name['/rig_pc/left', node])['inputs_file'] == inputs_file
        assert 'inputs_file' not in _own(by_name['/right', node])


def test_a_real_rigs_inputs_file_with_a_simulated_rig_is_refused_naming_both(tmp_path):
    # the ros2_control rig's inputs: JointStates that the simulated rig never publishes,
    # so its estimator would wait for ever; a real rig runs without the simulated one
    path = tmp_path / 'rigs.yaml'
    path.write_text(ACTUATORS)
    with pytest.raises(ValueError) as err:
        plan_from_arguments(_defaults(actuators_file=str(path)), SHARE)
    text = str(err.value)
    for words in ('actuator /rig_pc/left: inputs_file ros2_control_rig.inputs.yaml',
                  'current_A on /joint_states (JointState joint eha_motor effort, A_peak)',
                  'simulated rig publishes current_A on /rig_pc/left/current (Float64, A)',
                  'p_a_Pa on /rig_pc/left/pressure_a (FluidPressure, Pa)',
                  'launch with sim_rigs:=false'):
        assert words in text, text
    assert 'p_acc_Pa' in text and 'chamber_a' not in text      # only what differs
    nodes = plan_from_arguments(_defaults(actuators_file=str(path), sim_rigs='false'), SHARE)
    assert {n.name for n in nodes} == {'eha_thermal_estimator', 'eha_recorder'}
    # a unit alone differing is refused too: the rig's values would be read wrongly
    bar = tmp_path / 'bar.inputs.yaml'
    bar.write_text('inputs:\n  p_acc_Pa: {topic: /eha/pressure_acc, message_type: '
                   'sensor_msgs/msg/FluidPressure, unit: bar}\n')
    with pytest.raises(ValueError, match=r'p_acc_Pa on /left/pressure_acc \(FluidPressure, '
                       r'bar\), but its simulated rig publishes p_acc_Pa on /left/pressure_acc '
                       r'\(FluidPressure, Pa\)'):
        plan([Actuator('/left', inputs_file=str(bar))], SHARE)


def test_the_nodes_declare_every_parameter_planned_for_them(tmp_path):
    path = tmp_path / 'rigs.yaml'
    path.write_text(_sim_inputs(tmp_path)[0])
    nodes = plan_from_arguments(_defaults(actuators_file=str(path), view='true'), SHARE)
    declared = {'eha_thermal_estimator': set(estimator_node.PARAMETERS),
                'eha_recorder': set(recorder_node.PARAMETERS)}
    for n in nodes:
        if n.name in declared:
            assert set(_own(n)) - {'use_sim_time'} <= declared[n.name], n


@pytest.mark.parametrize('text, message', [
    ('actuators: [{namespace: left}, {namespace: /left}]',
     'actuators 0 and 1 share the namespace /left'),
    ('actuators: [{namespace: left, confg_file: x}]',
     r'actuators\[0\]: unknown key confg_file; allowed: namespace, config_file'),
    ('actuators: [{namespace: 2left}]', r"actuators\[0\].namespace = '2left': a namespace"),
    ('actuators: [{namespace: /}]', r"actuators\[0\].namespace = '/'"),
    ('actuators: [{namespace: left, stage: 7}]', r'actuators\[0\].stage = 7: expected'),
    ('actuators: [{namespace: left, remappings: [a]}]', r'actuators\[0\].remappings'),
    ('actuators: [{config_file: x}]', r'actuators\[0\]: expected a mapping with at least'),
    ('left: {}', 'expected a list of actuators under the key actuators'),
])
def test_a_bad_actuators_file_names_the_key(text, message):
    with pytest.raises(ValueError, match=message):
        plan(actuators_from_yaml(text, 'rigs.yaml'), SHARE)


@pytest.mark.parametrize('changes, message', [
    ({'actuators': ' , '}, 'actuators = .*: name at least one namespace'),
    ({'actuators': 'left,left'}, 'share the namespace /left'),
    ({'view': 'yes'}, "view = 'yes': expected true or false"),
    ({'managed': '1'}, "managed = '1': expected true or false"),
    ({'stage': '0'}, 'stage = 0: expected a reference stage'),
    ({'foxglove_port': 'x'}, "foxglove_port = 'x': expected a whole number"),
    ({'foxglove_port': '65535', 'view': 'true', 'actuators': 'a,b'},
     'foxglove_port = 65535: 2 views need ports 65535..65536'),
])
def test_bad_launch_arguments_are_named(changes, message):
    with pytest.raises(ValueError, match=message):
        plan_from_arguments(_defaults(**changes), SHARE)


def test_one_actuator_records_into_record_output_itself():
    nodes = plan([Actuator('/eha')], SHARE, record_output='runs/one.mcap')
    assert _own(nodes[-1])['output'] == 'runs/one.mcap'
    nodes = plan([Actuator('/left'), Actuator('/rig/right')], SHARE, record_output='runs/x.mcap')
    assert [_own(n)['output'] for n in nodes if n.name == 'eha_recorder'] == [
        'runs/x_left.mcap', 'runs/x_rig_right.mcap']
    assert launch_plan.DEFAULT_NAMESPACE == 'eha'
