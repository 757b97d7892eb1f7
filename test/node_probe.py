"""A node under test and a probe node beside it, spun together in this process."""

from rclpy.experimental import EventsExecutor
from rclpy.task import Future


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

    def close(self):
        """Stop the executor and destroy both nodes."""
        self.executor.shutdown()
        self.node.destroy_node()
        self.probe.destroy_node()
