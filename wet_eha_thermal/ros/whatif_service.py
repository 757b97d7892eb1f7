"""
The live estimator's what-if service: requests in, answers out, never in the estimates' way.

Each request (``interface.WHATIF_REQUEST_TOPIC``, from ROS or from the
Foxglove view) takes a snapshot of the model as it arrives and runs in a
worker process (:class:`~wet_eha_thermal.offline.whatif_worker.WhatIfWorker`),
one at a time; a steady timer polls for its answer and publishes it on
``interface.WHATIF_RESPONSE_TOPIC`` (and to the view), so the node's steps
never wait for a what-if. Under sim time a paused /clock holds no answer back.
"""

import json
from typing import Callable, Optional

from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import QoSProfile
from std_msgs.msg import String
from wet_eha_thermal import interface
from wet_eha_thermal.estimator.session import EstimatorSession
from wet_eha_thermal.offline.whatif_worker import WhatIfWorker

#: How often the node looks for a what-if's answer (s, steady clock): a what-if takes seconds.
WHATIF_POLL_S = 0.1


class WhatIfService:
    """Serve what-ifs for ``node`` from the model of ``session``, in a worker process."""

    def __init__(self, node: Node, session: EstimatorSession, topic: Callable[[str], str],
                 view, failed: Callable[[str, BaseException], None]) -> None:
        self.node, self.session, self.view, self._failed = node, session, view, failed
        self.worker = WhatIfWorker(session.cfg, session.model.quantities.names)
        self.worker.start()
        self.pub = node.create_publisher(String, topic(interface.WHATIF_RESPONSE_TOPIC),
                                         QoSProfile(depth=10))
        node.create_subscription(String, topic(interface.WHATIF_REQUEST_TOPIC),
                                 lambda msg: self.request(msg.data), QoSProfile(depth=10))
        node.create_timer(WHATIF_POLL_S, self.poll, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def request(self, text: str) -> None:
        """Start a what-if from the model as it is now, or answer at once why not."""
        try:
            s = self.session
            refused = self.worker.submit(text, s.model if s.t_model is not None else None,
                                         s.ambient_C, 'live estimator', s.t_model)
            if refused is not None:
                self._answer(refused)
        except Exception as exc:  # noqa: B902
            self._failed('whatif', exc)

    def poll(self) -> None:
        """Take the view's what-if requests; publish the answer of one that finished."""
        try:
            for text in self.view.take_whatif_requests() if self.view is not None else ():
                self.request(text)
            answer: Optional[str] = self.worker.poll()
            if answer is not None:
                self._answer(answer)
        except Exception as exc:  # noqa: B902
            self._failed('whatif', exc)

    def _answer(self, answer: str) -> None:
        """Publish a what-if answer (JSON text), log it in a line, show it in the view."""
        self.pub.publish(String(data=answer))
        data = json.loads(answer)
        outcome = f"error: {data['error']}" if not data['ok'] else (
            f"{data['duty']}, {data['duration_s']:g} s in {data['wall_s']:.1f} s; time to "
            'limit: ' + ', '.join(f'{q} {"-" if t is None else f"{t:.0f} s"}'
                                  for q, t in data['time_to_limit_s'].items()))
        self.node.get_logger().info(f"what-if {data['id']!r}: {outcome}")
        if self.view is not None:
            self.view.offer_whatif(answer)

    def close(self) -> None:
        """Stop the worker process."""
        self.worker.close()
