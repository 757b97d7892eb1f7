"""
The managed (lifecycle) estimator, driven as an operator would: lifecycle_msgs services.

A client node calls ``/<node>/change_state`` and ``/<node>/get_state``:
configured, the estimator publishes nothing; active, estimates and limits
flow; deactivated, its last limits say STOPPED (the drive falls back at
once) and nothing more is published; activated again, it goes on; cleanup
and shutdown end it.
"""

import os
from pathlib import Path
import signal
import subprocess
import sys
import threading
import time

from lifecycle_msgs.msg import State, Transition
from lifecycle_msgs.srv import ChangeState, GetState
from node_probe import NodeAndProbe
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from ros_domains import claim_domain
from sensor_msgs.msg import FluidPressure, JointState, Temperature
from std_msgs.msg import Float64, Float64MultiArray
from wet_eha_thermal import interface
from wet_eha_thermal.config import default_config_path
from wet_eha_thermal.ros import topics
from wet_eha_thermal.ros.estimator_node import ManagedEstimatorNode, NODE_NAME
import yaml

pytestmark = pytest.mark.slow

# this module's own domain, this machine only; conftest puts it in ROS_DOMAIN_ID while it runs
DOMAIN_ID = claim_domain()
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
ROOT = Path(__file__).resolve().parents[1]
VALUES = {'current_A': 20.0, 'speed_rad_s': 800.0, 'p_a_Pa': 1.0e6, 'p_b_Pa': 1.0e6,
          'p_acc_Pa': 1.0e6, 'position_m': 0.002}


class Operator(NodeAndProbe):
    """
    The managed estimator and a client that drives its lifecycle, feeds it and listens.

    The node starts no what-if worker (``whatif`` false): nothing here asks it one, and
    its warm-up (1.5 s of a core) would run beside the transitions these tests time.
    """

    def __init__(self, context):
        super().__init__(context, ManagedEstimatorNode(context=context, parameter_overrides=[
            Parameter('diagnostics_rate_Hz', value=5.0), Parameter('whatif', value=False)]),
            rclpy.create_node('lifecycle_operator', context=context))
        p = self.probe
        self.change = p.create_client(ChangeState, f'/{NODE_NAME}/change_state')
        self.get = p.create_client(GetState, f'/{NODE_NAME}/get_state')
        in_qos = topics.input_qos('sensor_data', 100)
        self.pubs = {name: p.create_publisher(
            FluidPressure if name in interface.PRESSURE_INPUTS else Float64,
            interface.INPUT_TOPICS[name], in_qos) for name in VALUES}
        self.estimates, self.limits, self.drive = [], [], []
        p.create_subscription(Temperature, f'{interface.ESTIMATE_PREFIX}/oil',
                              self.estimates.append, 100)
        p.create_subscription(JointState, interface.CURRENT_LIMITS_TOPIC, self.limits.append, 50)
        p.create_subscription(Float64MultiArray, interface.DRIVE_LIMITS_TOPIC,
                              lambda m: self.drive.append(interface.DriveLimits.from_data(m.data)),
                              50)

    def call(self, client, request, timeout_s=300.0):
        """Call a service and return its answer (configure loads the model: allow minutes)."""
        assert client.wait_for_service(timeout_sec=10.0)
        future = client.call_async(request)
        end = time.monotonic() + timeout_s
        while not future.done() and time.monotonic() < end:
            self.spin(0.01)
        assert future.done(), f'{client.srv_name}: no answer in {timeout_s} s'
        return future.result()

    def transition(self, transition_id):
        """Ask for a transition; return whether it succeeded."""
        return self.call(self.change, ChangeState.Request(
            transition=Transition(id=transition_id))).success

    def state(self):
        return self.call(self.get, GetState.Request()).current_state.id

    def publish_inputs(self):
        """Publish one sample of every input, stamped now."""
        stamp = self.probe.get_clock().now().to_msg()
        for name, pub in self.pubs.items():
            if name in interface.PRESSURE_INPUTS:
                msg = FluidPressure(fluid_pressure=VALUES[name])
                msg.header.stamp = stamp
            else:
                msg = Float64(data=VALUES[name])
            pub.publish(msg)

    def feed(self, seconds, until=None):
        """Publish every input at 1 kHz (``NodeAndProbe.paced``)."""
        return self.paced(self.publish_inputs, seconds, until)

    def published_topics(self):
        return {name for name, _ in self.node.get_publisher_names_and_types_by_node(
            NODE_NAME, '/')}


@pytest.fixture
def operator(context):
    op = Operator(context)
    yield op
    op.close()


def test_configure_activate_deactivate_cleanup_shutdown(operator):
    op = operator
    assert op.state() == State.PRIMARY_STATE_UNCONFIGURED
    # configure: the configuration and the compiled model loaded, no topic of the estimator
    assert op.transition(Transition.TRANSITION_CONFIGURE)
    assert op.state() == State.PRIMARY_STATE_INACTIVE
    assert op.node.session is not None and op.node.session.t_model is None
    # an absence: fed for its length (``until`` would feed to the deadline, PATIENCE times it)
    op.feed(1.0)
    assert not op.estimates and not op.limits
    assert op.node.session.status().inputs['current_A'].received == 0
    assert not op.published_topics() & set(interface.topic_table())
    # activate: estimates and limits flow
    assert op.transition(Transition.TRANSITION_ACTIVATE)
    assert op.state() == State.PRIMARY_STATE_ACTIVE
    assert op.feed(20.0, until=lambda: sum(d.status == interface.LimitStatus.OK
                                           for d in op.drive) >= 2)
    assert interface.DRIVE_LIMITS_TOPIC in op.published_topics()
    received = op.node.session.status().inputs['current_A'].received
    # deactivate: the last limits are the fallback, STOPPED, and nothing follows
    assert op.transition(Transition.TRANSITION_DEACTIVATE)
    assert op.state() == State.PRIMARY_STATE_INACTIVE
    op.spin(0.3)
    last = op.drive[-1]
    assert last.status == interface.LimitStatus.STOPPED
    assert max(last.limits_A) <= op.node.session.cfg.estimator.limits.fallback_current_A
    assert op.limits[-1].header.frame_id == 'fallback: stopped: the estimator was deactivated'
    assert [d.sequence for d in op.drive] == list(range(1, len(op.drive) + 1))
    stamps = [d.stamp_ns for d in op.drive]
    assert stamps == sorted(stamps)
    n_drive, n_est = len(op.drive), len(op.estimates)
    op.feed(2.0)
    assert len(op.drive) == n_drive and len(op.estimates) == n_est
    # not taking samples either, and no topic of the estimator left
    st = op.node.session.status()
    assert st.inputs['current_A'].received == received
    assert not op.published_topics() & set(interface.topic_table())
    # activate again: it goes on from the state it had, the sequence continuing
    assert op.transition(Transition.TRANSITION_ACTIVATE)
    assert op.feed(20.0, until=lambda: any(d.status == interface.LimitStatus.OK
                                           for d in op.drive[n_drive:]))
    assert op.drive[n_drive].sequence == n_drive + 1
    assert op.transition(Transition.TRANSITION_DEACTIVATE)
    # cleanup drops the estimator; its counts stay for the report
    assert op.transition(Transition.TRANSITION_CLEANUP)
    assert op.state() == State.PRIMARY_STATE_UNCONFIGURED
    assert op.node.session is None
    assert op.node.report().figures['steps'] > 0
    assert op.transition(Transition.TRANSITION_UNCONFIGURED_SHUTDOWN)
    assert op.state() == State.PRIMARY_STATE_FINALIZED


def test_a_bad_configuration_fails_configure_and_stays_unconfigured(context, tmp_path):
    data = yaml.safe_load(default_config_path().read_text())
    data['estimator']['step_s'] = -1.0
    bad = tmp_path / 'bad.yaml'
    bad.write_text(yaml.safe_dump(data))
    op = NodeAndProbe(context, ManagedEstimatorNode(context=context, parameter_overrides=[
        Parameter('config_file', value=str(bad))]),
        rclpy.create_node('lifecycle_operator_bad', context=context))
    try:
        client = op.probe.create_client(ChangeState, f'/{NODE_NAME}/change_state')
        assert client.wait_for_service(timeout_sec=10.0)
        future = client.call_async(ChangeState.Request(
            transition=Transition(id=Transition.TRANSITION_CONFIGURE)))
        end = time.monotonic() + 60.0
        while not future.done() and time.monotonic() < end:
            op.spin(0.01)
        assert future.done() and not future.result().success
        assert op.node.session is None
    finally:
        op.close()


def test_an_operator_starts_it_with_managed_and_stops_it_with_ctrl_c(context):
    env = dict(os.environ, OPENBLAS_NUM_THREADS='1', PYTHONUNBUFFERED='1')
    proc = subprocess.Popen(
        [sys.executable, '-m', 'wet_eha_thermal.ros.estimator_node', '--managed', '--ros-args',
         '-r', '__ns:=/managed_main'], cwd=ROOT, env=env, stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT, text=True)
    lines = []
    reader = threading.Thread(target=lambda: lines.extend(proc.stdout), daemon=True)
    reader.start()
    client = rclpy.create_node('lifecycle_cli', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(client)
    try:
        service = f'/managed_main/{NODE_NAME}'
        change = client.create_client(ChangeState, f'{service}/change_state')
        get = client.create_client(GetState, f'{service}/get_state')
        assert get.wait_for_service(timeout_sec=60.0), ''.join(lines)

        def call(cli, request):
            future = cli.call_async(request)
            # configure loads the compiled model: minutes on a cold cache
            executor.spin_until_future_complete(future, timeout_sec=300.0)
            assert future.done(), ''.join(lines)
            return future.result()

        assert call(get, GetState.Request()).current_state.id == \
            State.PRIMARY_STATE_UNCONFIGURED
        for transition in (Transition.TRANSITION_CONFIGURE, Transition.TRANSITION_ACTIVATE):
            assert call(change, ChangeState.Request(
                transition=Transition(id=transition))).success, ''.join(lines)
        assert call(get, GetState.Request()).current_state.id == State.PRIMARY_STATE_ACTIVE
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=30) == 0, ''.join(lines)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        executor.shutdown()
        client.destroy_node()
    reader.join(timeout=5)
    text = ''.join(lines)
    assert 'Traceback' not in text, text
    # the same report line as the plain node's, for live and the logs
    report = interface.NodeReport.find(text.splitlines())
    assert report is not None and report.node == NODE_NAME, text
    assert set(report.inputs) >= {'current_A', 'speed_rad_s'}
