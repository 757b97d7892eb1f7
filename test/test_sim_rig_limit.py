"""
The simulated rig's drive honours the estimator's current limit, with a drive's watchdog.

The rig node runs in this process on stage 1 (33 A at its peaks, noise off,
200 Hz); a probe node plays the estimator's limits as a drive reads them
(std_msgs/Float64MultiArray, the layout of
:class:`~wet_eha_thermal.interface.DriveLimits`) and listens to the current
the rig publishes.
"""

import math
import os
import time

from node_probe import NodeAndProbe
import pytest
import rclpy
from rclpy.parameter import Parameter
from ros_domains import claim_domain
from std_msgs.msg import Float64, Float64MultiArray
from wet_eha_thermal import interface
from wet_eha_thermal.ros import topics
from wet_eha_thermal.ros.sim_rig_node import clamp_text, SimRigNode

pytestmark = pytest.mark.slow     # measured: see docs/development.md#tests-and-ci

# this module's own domain, this machine only; conftest puts it in ROS_DOMAIN_ID while it runs
DOMAIN_ID = claim_domain()
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

WATCHDOG_S, FALLBACK_A = 0.5, 5.0


class Drive(NodeAndProbe):
    """The rig under test, a probe that sends limits and keeps the published current."""

    def __init__(self, context):
        super().__init__(context, SimRigNode(context=context, parameter_overrides=[
            Parameter('stage', value=1), Parameter('rate_Hz', value=200.0),
            Parameter('noise', value=False), Parameter('honour_limit', value=True),
            Parameter('limit_watchdog_s', value=WATCHDOG_S),
            Parameter('limit_fallback_A', value=FALLBACK_A)]),
            rclpy.create_node('drive_test_probe', context=context))
        self.pub = self.probe.create_publisher(Float64MultiArray, interface.DRIVE_LIMITS_TOPIC,
                                               10)
        self.sequence = 0
        self.currents = []
        self.probe.create_subscription(Float64, interface.INPUT_TOPICS['current_A'],
                                       lambda m: self.currents.append(m.data),
                                       topics.input_qos('sensor_data', 1000))

    def run(self, seconds, limits=None, status=interface.LimitStatus.OK, age_s=0.0, skip=0):
        """
        Spin ``seconds``, sending ``limits`` ({horizon s: A}) at 10 Hz; return the currents.

        The messages are stamped ``age_s`` before the probe's clock; ``skip``
        sequence numbers are left out before the first.
        """
        self.sequence += skip
        self.currents.clear()
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            if limits is not None:
                now = self.probe.get_clock().now().nanoseconds - int(age_s * 1e9)
                self.sequence += 1
                shortest = min(limits)
                self.pub.publish(Float64MultiArray(data=interface.DriveLimits(
                    stamp_ns=now, sequence=self.sequence, status=status,
                    binding_A=limits[shortest], binding_horizon_s=shortest,
                    horizons_s=list(limits), limits_A=list(limits.values())).to_data()))
            self.spin(0.1)
        # what the last block was computed with (blocks run 0.1 s ahead of the published)
        return list(self.currents[-self.node.n_block:])


@pytest.fixture
def drive(context):
    d = Drive(context)
    yield d
    d.close()


def test_the_drive_carries_the_binding_limit_and_falls_back_on_its_watchdog(drive):
    node = drive.node
    # no limit yet: the drive's own fallback
    drive.run(1.0)
    assert node.rig.current_limit_A == FALLBACK_A
    assert node.limit_source == 'fallback: no limit yet'
    # the estimator's limits: the shortest horizon binds (the continuous one is lower)
    currents = drive.run(2.5, {10.0: 15.0, 60.0: 12.0, math.inf: 8.0})
    assert node.rig.current_limit_A == 15.0 and node.limit_source == 'estimator'
    assert max(currents) <= 15.0
    # over 2.5 s of stage 1 the demand passed 15 A: the drive carried exactly the limit
    assert max(drive.currents + currents) == pytest.approx(15.0, abs=1e-3)
    # the estimator on its fallback: applied, never above the drive's own
    drive.run(0.5, {10.0: 30.0}, status=interface.LimitStatus.STALE_INPUTS)
    assert node.rig.current_limit_A == FALLBACK_A
    assert node.limit_source == 'estimator fallback: stale_inputs'
    # a status code this drive does not know is a fallback too; lost messages are counted
    drive.run(0.5, {10.0: 30.0}, status=17, skip=3)
    assert node.rig.current_limit_A == FALLBACK_A
    assert node.limit_source == 'estimator fallback: other'
    # limits stamped too long ago, then no limits at all: the watchdog
    drive.run(0.5, {10.0: 30.0}, age_s=2 * WATCHDOG_S)
    assert node.rig.current_limit_A == FALLBACK_A
    assert node.limit_source.startswith('fallback: the last limit is')
    drive.run(0.5, {10.0: math.inf, math.inf: 30.0})       # no limit within 10 s
    assert node.rig.current_limit_A == math.inf and node.limit_source == 'estimator'
    drive.run(2 * WATCHDOG_S)
    assert node.rig.current_limit_A == FALLBACK_A
    # malformed messages are counted and left to the watchdog
    drive.pub.publish(Float64MultiArray(data=[1.0, 0.0, 0.0, 1.0, 0.0, math.nan, 10.0, 0.0]))
    drive.run(0.2)
    figures = node.report().figures
    assert figures['limits_rejected'] == 1 and figures['limits_received'] > 20
    assert figures['limits_missed'] == 3
    # the counts: clamped only while the demand was over the limit, cut at most 33 - 5 A
    assert 0.0 < figures['limit_clamped_s'] < figures['duty_time_s']
    assert 0.0 < figures['limit_first_clamp_s'] < 1.5
    assert 25.0 < figures['limit_largest_cut_A'] < 29.0
    assert 1.5 < figures['limit_fallback_s'] < figures['duty_time_s'] - 2.0
    assert math.isfinite(figures['truth_winding_hotspot_peak_C'])
    assert 'clamped' in clamp_text(figures) and 'largest cut' in clamp_text(figures)
