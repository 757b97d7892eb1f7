"""
Two actuators side by side, each an estimator and its simulated rig started with ``-r __ns:=``.

The nodes are those the launch file plans for two actuators (with their
Foxglove views). Every topic of a node follows its namespace (``topic_prefix``
left empty): the left pair and the right pair share no topic but /diagnostics,
no diagnostic status name, hardware_id or view port, and each estimator
estimates from its own rig. A node started plainly keeps /eha.
"""

import os
from pathlib import Path
import socket
import time

from diagnostic_msgs.msg import DiagnosticArray
import pytest
import rclpy
from rclpy.experimental import EventsExecutor
from rclpy.parameter import Parameter
from rclpy.task import Future
from ros_domains import claim_domain
from sensor_msgs.msg import Temperature
from wet_eha_thermal import launch_plan
from wet_eha_thermal.launch_plan import Actuator
from wet_eha_thermal.ros import topics
from wet_eha_thermal.ros.estimator_node import EstimatorNode
from wet_eha_thermal.ros.runtime import declare_parameters, shared_parameters
from wet_eha_thermal.ros.sim_rig_node import SimRigNode

# this module's own domain, this machine only; conftest puts it in ROS_DOMAIN_ID while it runs
DOMAIN_ID = claim_domain()
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
#: what every node has whatever its namespace: the aggregator's topic and rclpy's own
SHARED = {'/diagnostics', '/rosout', '/parameter_events'}
ROOT = Path(__file__).resolve().parents[1]


def _published(node):
    return {name for name, _ in node.get_publisher_names_and_types_by_node(
        node.get_name(), node.get_namespace())}


def _subscribed(node):
    return {name for name, _ in node.get_subscriber_names_and_types_by_node(
        node.get_name(), node.get_namespace())}


def _free_ports(n):
    """Return a port whose next ``n - 1`` are free too, as the launch plan numbers views."""
    for _ in range(20):
        with socket.socket() as probe:
            probe.bind(('127.0.0.1', 0))
            first = probe.getsockname()[1]
        if first + n > 65536:
            continue
        socks = [socket.socket() for _ in range(n)]
        try:
            for i, sock in enumerate(socks):
                sock.bind(('127.0.0.1', first + i))
            return first
        except OSError:
            continue
        finally:
            for sock in socks:
                sock.close()
    raise RuntimeError(f'no {n} free ports in a row')


def test_two_actuators_by_namespace_share_no_topic_status_id_or_port(context):
    """The launch file's plan for /left and /right, each with its rig and Foxglove view."""
    base = _free_ports(2)
    plan = launch_plan.plan([Actuator('/left', stage=6), Actuator('/right', stage=1)],
                            str(ROOT), record=False, view=True, foxglove_port=base)
    nodes, estimates, statuses = {}, {'left': [], 'right': []}, {}
    executor = EventsExecutor(context=context)
    probe = rclpy.create_node('namespace_probe', context=context)
    try:
        for n in plan:
            side = n.namespace.strip('/')
            params_file, own = n.parameters
            overrides = [Parameter(k, value=v) for k, v in own.items()]
            args = ['--ros-args', '-r', f'__ns:={n.namespace}', '--params-file', params_file]
            # light: two of each in one thread on a shared machine
            if n.executable == launch_plan.ESTIMATOR_EXE:
                nodes[side, 'estimator'] = EstimatorNode(
                    context=context, cli_args=args, parameter_overrides=overrides + [
                        Parameter('background_budget_ms', value=0.0)])
            else:
                assert n.executable == launch_plan.RIG_EXE
                nodes[side, 'rig'] = SimRigNode(
                    context=context, cli_args=args, parameter_overrides=overrides + [
                        Parameter('rate_Hz', value=50.0), Parameter('noise', value=False)])
        for side in estimates:
            probe.create_subscription(Temperature, f'/{side}/estimate/winding_hotspot',
                                      estimates[side].append, 100)
        probe.create_subscription(
            DiagnosticArray, '/diagnostics',
            lambda msg: statuses.update((s.name, s.hardware_id) for s in msg.status), 100)
        # on the one /diagnostics, each node's statuses carry its namespace and node name
        wanted = {f'{side}/eha_thermal_estimator: estimate' for side in ('left', 'right')} | {
            f'{side}/eha_sim_rig: rig' for side in ('left', 'right')}
        for node in [*nodes.values(), probe]:
            executor.add_node(node)
        never = Future()
        end = time.monotonic() + 40.0
        while time.monotonic() < end and (min(len(v) for v in estimates.values()) < 20
                                          or not wanted <= set(statuses)):
            executor.spin_until_future_complete(never, timeout_sec=0.2)
        counts = {side: len(v) for side, v in estimates.items()}
        assert min(counts.values()) >= 20, counts
        assert wanted <= set(statuses), sorted(statuses)
        # every status of a side is named under its namespace and carries its own id,
        # derived from the namespace alone (no hardware_id parameter given)
        for name, hardware_id in statuses.items():
            side = name.split('/')[0]
            assert side in ('left', 'right'), name
            assert hardware_id == f'wet-eha-rig/{side}', (name, hardware_id)
        # each view serves on the port the plan gave its actuator, and only there
        ports = {side: nodes[side, 'estimator'].runner.view.view.port
                 for side in ('left', 'right')}
        assert ports == {'left': base, 'right': base + 1}, ports
        for side in ('left', 'right'):
            est, rig = nodes[side, 'estimator'], nodes[side, 'rig']
            assert est.get_fully_qualified_name() == f'/{side}/eha_thermal_estimator'
            assert est.runner.prefix == f'/{side}'
            assert est.runner.topic_names['current_A'] == f'/{side}/current'
            assert est.runner.view.view.topics['temperatures'] == f'/{side}/view/temperatures'
            own = (_published(est) | _subscribed(est) | _published(rig) | _subscribed(rig)) \
                - SHARED
            assert own and all(t.startswith(f'/{side}/') for t in own), own
            # each estimator takes its own rig's samples
            assert est.session.health['current_A'].accepted > 20
        # stage 1 and stage 6 drive different currents: the estimates part
        left = nodes['left', 'estimator'].session.health['current_A'].last_value
        right = nodes['right', 'estimator'].session.health['current_A'].last_value
        assert left != right
    finally:
        executor.shutdown()
        for node in [*nodes.values(), probe]:
            node.destroy_node()


def test_a_plain_node_keeps_eha_and_a_prefix_must_be_absolute(context):
    node = rclpy.create_node('prefix_probe', context=context)
    try:
        assert topics.resolve_prefix(node, '') == '/eha'
        assert topics.resolve_prefix(node, '/rig_b/') == '/rig_b'
        with pytest.raises(ValueError, match="topic_prefix = 'left': must start with /"):
            topics.resolve_prefix(node, 'left')
    finally:
        node.destroy_node()


def test_hardware_id_follows_the_namespace_unless_given(context):
    def declared(namespace, overrides=()):
        node = rclpy.create_node('id_probe', namespace=namespace, context=context,
                                 parameter_overrides=list(overrides))
        try:
            return declare_parameters(node, shared_parameters('hardware_id'))['hardware_id']
        finally:
            node.destroy_node()

    assert declared('/left') == 'wet-eha-rig/left'
    assert declared('/rig_b/right') == 'wet-eha-rig/rig_b/right'
    assert declared('/') == 'wet-eha-rig'
    assert declared('/left', [Parameter('hardware_id', value='eha-sn-0042')]) == 'eha-sn-0042'
