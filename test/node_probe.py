"""A node under test and a probe node beside it, spun together in this process."""

import time

from rclpy.experimental import EventsExecutor
from rclpy.task import Future

#: a busy machine slows the node and the probe alike: a condition's deadline is this many
#: times the seconds it takes on a quiet one (a deadline, never a rate)
PATIENCE = 5.0


class NodeAndProbe:
    """``node`` (under test) and ``probe`` (feeds and listens) in one EventsExecutor."""

    def __init__(self, context, node, probe):
        self.node, self.probe = node, probe
        self.executor = EventsExecutor(context=context)
        self.executor.add_node(node)
        self.executor.add_node(probe)
        self._never = Future()

    def spin(self, seconds):
        """Spin both for ``seconds``: a timeout, so no test can hang."""
        self.executor.spin_until_future_complete(self._never, timeout_sec=seconds)

    def paced(self, publish, seconds, until=None):
        """
        Call ``publish()`` at 1 kHz for ``seconds``, or until ``until()``; return whether it held.

        With ``until``, ``seconds`` is what a quiet machine needs and the
        deadline ``PATIENCE`` times that.
        """
        end = time.monotonic() + seconds * (1.0 if until is None else PATIENCE)
        next_t = time.monotonic()
        while time.monotonic() < end:
            now = time.monotonic()
            if now >= next_t:
                publish()
                next_t = max(next_t + 0.001, now - 0.005)   # no bursts after a stall
            self.spin(0.0005)
            if until is not None and until():
                return True
        return until is None

    def close(self):
        """Stop the executor and destroy both nodes."""
        self.executor.shutdown()
        self.node.destroy_node()
        self.probe.destroy_node()
