"""
Ask a running estimator for a what-if over ROS: ``wet-eha-thermal whatif`` without ``--bag``.

Publishes the request (std_msgs/String JSON) on the request topic once an
estimator subscribes to it, and waits for the answer with the request's
``id`` on the answer topic (:data:`~wet_eha_thermal.interface.WHATIF_REQUEST_TOPIC`).
The domain is the environment's (``ROS_DOMAIN_ID``), as for any ROS tool.
"""

import json
import time

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile
from std_msgs.msg import String
from wet_eha_thermal import interface

#: How long to wait for an estimator to subscribe to the requests (s).
FIND_TIMEOUT_S = 10.0


class NoAnswer(RuntimeError):
    """No estimator took the request, or none answered it in time; the message says which."""


def ask(text: str, request_id: str, prefix: str = interface.PREFIX,
        timeout_s: float = 300.0) -> str:
    """Return the answer (JSON text) to the request ``text`` whose id is ``request_id``."""
    request_topic = interface.prefixed(interface.WHATIF_REQUEST_TOPIC, prefix)
    answer_topic = interface.prefixed(interface.WHATIF_RESPONSE_TOPIC, prefix)
    context = Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node('eha_whatif_client', context=context)
        answers = []
        node.create_subscription(String, answer_topic, lambda m: answers.append(m.data),
                                 QoSProfile(depth=10))
        pub = node.create_publisher(String, request_topic, QoSProfile(depth=10))
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)

        def wait(until, seconds: float) -> bool:
            end = time.monotonic() + seconds
            while not until() and time.monotonic() < end:
                executor.spin_once(timeout_sec=0.05)
            return until()

        if not wait(lambda: pub.get_subscription_count() > 0, FIND_TIMEOUT_S):
            raise NoAnswer(f'no estimator subscribes to {request_topic} (waited '
                           f'{FIND_TIMEOUT_S:g} s): is one running, on this ROS_DOMAIN_ID and '
                           'topic prefix? Or start from a bag (--bag) or cold (--cold)')
        # and its answers reach us before we ask
        wait(lambda: node.count_publishers(answer_topic) > 0 and
             pub.get_subscription_count() > 0, FIND_TIMEOUT_S)
        pub.publish(String(data=text))

        def mine():
            return any(json.loads(a).get('id') == request_id for a in answers)

        if not wait(mine, timeout_s):
            raise NoAnswer(f'no answer to what-if {request_id!r} on {answer_topic} within '
                           f'{timeout_s:g} s (--timeout)')
        executor.shutdown()
        node.destroy_node()
        return next(a for a in answers if json.loads(a).get('id') == request_id)
    finally:
        rclpy.try_shutdown(context=context)
