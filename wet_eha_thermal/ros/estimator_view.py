"""
The estimator node's Foxglove view: started beside the node, fed after everything ROS gets.

With ``foxglove_address`` (HOST:PORT) the node serves the view
(:mod:`wet_eha_thermal.live_view`): each estimate, alert summary and count of
the inputs goes to it through a bounded hand-off where the newest wins; the
view's thread and the Foxglove SDK do the rest. An address in use is one
error line, and the node estimates without the view. Foxglove may set the
publication rates (``FOXGLOVE_SETTABLE``), applied on the node's thread as a
ROS parameter change; thresholds and limits are shown read-only. The
recorder's health (``interface.RECORDER_HEALTH_TOPIC``) is shown beside the
estimates.
"""

import json
from typing import Callable, Dict, Mapping, Optional, Tuple

from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import String
from wet_eha_thermal import interface
from wet_eha_thermal.estimator.session import EstimatorSession, Output
from wet_eha_thermal.layouts import where_to_get
from wet_eha_thermal.live_view import app_url, LiveView
from wet_eha_thermal.model.quantity_table import LIMITED
from wet_eha_thermal.ros import topics

#: Parameters Foxglove may set: rates of publication only, which change what is shown,
#: never what is estimated or when an alert is raised (those stay read-only there).
FOXGLOVE_SETTABLE = ('publish_rate_Hz', 'diagnostics_rate_Hz', 'foxglove_inputs_rate_Hz')


class EstimatorView:
    """The node's Foxglove view, or the reason it is not there (``view`` None)."""

    def __init__(self, node: Node, session: EstimatorSession, topic: Callable[[str], str],
                 failed: Callable[[str, BaseException], None]) -> None:
        self.node, self.session, self._failed = node, session, failed
        self.view: Optional[LiveView] = None
        self.error = ''
        self._topic = topic

    def start(self, address: Tuple[str, int], parameters: Mapping[str, object],
              settable: Mapping[str, Tuple[float, float]], prefix: str) -> None:
        """
        Start the view at ``address`` (host, port) with ``parameters`` shown.

        ``settable``: the range of each parameter of ``FOXGLOVE_SETTABLE``.
        An address in use is one error line: the node estimates without it.
        """
        host, port = address
        s = self.session
        limits = {f'limits.{q}_C': v for q, v in s.limits_C.items()}
        alerts = {f'alerts.{r.quantity}.{k}': getattr(r, k) for r in s.alert_rules
                  for k in ('warn_C', 'critical_C', 'hysteresis_K', 'min_duration_s', 'latch')}
        try:
            self.view = LiveView(host, port, estimates=interface.ESTIMATES, limited=LIMITED,
                                 inputs=s.inputs, thermocouples=interface.THERMOCOUPLES,
                                 inputs_rate_Hz=parameters['foxglove_inputs_rate_Hz'],
                                 prefix=prefix, parameters={**parameters, **alerts, **limits},
                                 settable=settable,
                                 whatif_request_topic=self._topic(
                                     interface.WHATIF_REQUEST_TOPIC)
                                 if parameters['whatif'] else None)
        except RuntimeError as exc:
            self.error = f'{host}:{port}: {exc}'
            self.node.get_logger().error(f'Foxglove view not started on {self.error}; '
                                         'estimating without it')
            return
        namespace = self.node.get_namespace()
        layout = where_to_get('live', namespace,
                              None if prefix == interface.namespace_prefix(namespace) else prefix)
        self.node.get_logger().info(f'Foxglove view on {self.view.url}: open '
                                    f'{app_url(host, self.view.port)}; layout: {layout}')
        self.node.create_subscription(String, self._topic(interface.RECORDER_HEALTH_TOPIC),
                                      self._on_recorder_health, topics.latched_qos())

    def offer(self, out: Output) -> None:
        """Show what a session published: the last estimate, the alert summary."""
        if self.view is None:
            return
        if out.estimates:
            self.view.offer(out.estimates[-1], self.session.measured_C)
        if out.alerts is not None:
            self.view.offer_alerts(out.alerts)

    def offer_health(self) -> None:
        """Show each input's received and rejected counts."""
        if self.view is not None:
            self.view.offer_health({n: (h.received, h.rejected)
                                    for n, h in self.session.health.items()})

    def apply_requests(self) -> None:
        """Set the parameters Foxglove asked for, here on the node's thread, as ROS would."""
        if self.view is None:
            return
        for name, value in self.view.take_requests().items():
            result = self.node.set_parameters([Parameter(name, value=value)])[0]
            if not result.successful:
                self.node.get_logger().warning(f'Foxglove set {name} = {value:g}: refused: '
                                               f'{result.reason}')
                self.view.show_parameters({name: self.node.get_parameter(name).value})

    def show_parameters(self, values: Dict[str, object]) -> None:
        """Show parameters that changed."""
        if self.view is not None:
            self.view.show_parameters(values)

    def text(self) -> str:
        """Return the view's state in words, for the diagnostics."""
        v = self.view
        if v is None:
            return f'not started: {self.error}' if self.error else 'off'
        text = (f'{v.url}, {len(v.watched())} channels watched; {v.shown} of {v.offered} '
                'estimates shown')
        return text + (f'; {v.errors} errors (last: {v.last_error})' if v.errors else '')

    def _on_recorder_health(self, msg: String) -> None:
        try:
            health = json.loads(msg.data)
            if isinstance(health, dict):
                self.view.offer_recorder(health)
        except Exception as exc:  # noqa: B902
            self._failed('recorder health', exc)

    def close(self) -> None:
        """Stop the view."""
        if self.view is not None:
            self.view.close()
