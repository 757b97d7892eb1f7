"""
The live estimator as a ROS 2 node: sensor topics in; estimates, diagnostics and alerts out.

The node keeps the parameters; an :class:`~.estimator_runner.EstimatorRunner`
loads the configuration, the inputs file and the compiled model and, once
started, owns the subscriptions, the publishers and the timers (what comes in,
what goes out and when: :mod:`.estimator_runner`).

Two ways to start it, on one runner:

- plain (:class:`EstimatorNode`, the default, and what ``live`` starts): it
  loads everything and starts at once;
- managed (:class:`ManagedEstimatorNode`, ``--managed``): a lifecycle node
  (``lifecycle_msgs``) for an operator or a lifecycle manager to bring up:
  configure loads and checks the configuration and the inputs file and loads
  the compiled model (the numba warm-up), and makes no topic; activate
  subscribes and publishes; deactivate sends the drive's last limits as the
  fallback (``LimitStatus.STOPPED``, so the drive falls back at once) and
  stops taking samples and publishing anything; a later activate starts again
  from the state the model had; cleanup drops the estimator (configure loads
  it again); shutdown stops it from any state.

Time: samples stamped more than ``estimator.max_future_s`` ahead of the clock
are rejected; the clock going back by more than ``estimator.clock_jump_s``
re-starts the model time; without sim time, the ROS clock moving ahead of the
steady clock by more than that between two ticks (the system clock stepped)
re-starts it too, so that the model never steps across a jump. Under sim time
a leap forward of /clock is taken as elapsed time. Data gaps (every input
silent) and clock jumps are logged, listed in the alert summary's events and
counted in /diagnostics.

At shutdown one summary line (samples received and rejected per input, gaps,
clock jumps) goes to stderr for people, and the same counts as data (an
:class:`~wet_eha_thermal.interface.NodeReport` line) to stdout.

Run it with ``wet-eha-thermal-estimator [--managed] --ros-args --params-file
config/estimator.params.yaml`` or ``python -m wet_eha_thermal.ros.estimator_node``.
"""

import gc
import sys
from typing import List, Optional, Tuple

from rcl_interfaces.msg import SetParametersResult
from rclpy.exceptions import NameValidationException, ParameterException
from rclpy.lifecycle import LifecycleNode, TransitionCallbackReturn
from rclpy.node import Node
from wet_eha_thermal import interface
from wet_eha_thermal.config import ConfigError
from wet_eha_thermal.live_view import parse_address
from wet_eha_thermal.ros.estimator_runner import EstimatorRunner, summary
from wet_eha_thermal.ros.estimator_view import FOXGLOVE_SETTABLE
from wet_eha_thermal.ros.runtime import declare_parameters, descriptor, run_node, shared_parameters

NODE_NAME = interface.ESTIMATOR_NODE


# name -> (default, descriptor); ranges are enforced by rclpy, also for --params-file values
PARAMETERS = {
    'config_file': ('', descriptor(
        'estimator configuration YAML (the estimator: section and the rig); '
        "'' = the shipped config/reference_eha.yaml")),
    'inputs_file': ('', descriptor(
        'YAML of the inputs: topic, message type, field and unit of each '
        '(wet_eha_thermal/inputs.py); a name not found is looked for in the shipped config/; '
        "'' = the /eha topics of the simulated rig")),
    'publish_rate_Hz': (50.0, descriptor(
        'rate of the estimate, state and alert publication (and of advance(now))', 1.0, 500.0,
        read_only=False)),
    'background_budget_ms': (2.0, descriptor(
        'wall time per publish tick given to the forecast and the margin', 0.0, 50.0,
        read_only=False)),
    'diagnostics_rate_Hz': (1.0, descriptor('rate of /diagnostics', 0.1, 10.0, read_only=False)),
    'frame_id': ('eha', descriptor('frame_id of the published temperatures')),
    **shared_parameters('qos', 'qos_depth', 'topic_prefix', 'hardware_id', 'executor'),
    'foxglove_address': ('', descriptor(
        'Foxglove WebSocket server of the live view (wet_eha_thermal/live_view.py), HOST:PORT, '
        "e.g. 127.0.0.1:8765 (port 0: any free one); '' = no server")),
    'whatif': (True, descriptor(
        'serve what-ifs (a worker process and its fork server: about 210 MB and 1-2 s of CPU '
        'at start, docs/live.md); false: neither they nor the whatif topics, for a rig PC '
        'that runs several actuators')),
    'foxglove_inputs_rate_Hz': (20.0, descriptor(
        'rate of the inputs, input health and thermocouples in the Foxglove view (averaged '
        'over windows of sample time)', 1.0, 50.0, read_only=False)),
}


#: what a bad parameter, configuration or inputs file raises while the estimator is made
BAD_INPUT = (ConfigError, NameValidationException, ParameterException, ValueError)


def read_parameters(node: Node) -> Tuple[dict, Optional[Tuple[str, int]]]:
    """Declare and read the parameters; return them and the view's address (or None)."""
    p = declare_parameters(node, PARAMETERS)
    view_at = None         # checked before the model's slow start
    if p['foxglove_address']:
        try:
            view_at = parse_address(p['foxglove_address'])
        except ValueError as exc:
            raise ValueError(f'parameter foxglove_address = {exc}') from None
    return p, view_at


class _Estimator:
    """What the plain and the managed node share: the parameters, the runner, the report."""

    def _declare(self) -> None:
        self.p, self._view_at = read_parameters(self)
        self.runner: Optional[EstimatorRunner] = None
        self._report: Optional[interface.NodeReport] = None    # of a runner dropped
        self.add_on_set_parameters_callback(self._on_set_parameters)

    def _make_runner(self) -> None:
        """Load the configuration, the inputs file and the compiled model (configure)."""
        ranges = {n: (PARAMETERS[n][1].floating_point_range[0].from_value,
                      PARAMETERS[n][1].floating_point_range[0].to_value)
                  for n in FOXGLOVE_SETTABLE}
        self.runner = EstimatorRunner(self, self.p, self._view_at, ranges)

    def _drop_runner(self, why: str) -> None:
        """Stop the runner and drop it, keeping its counts for the report."""
        if self.runner is not None:
            self.runner.stop(why)
            self.runner.close()
            self._report = self.runner.report(NODE_NAME)
            self.runner = None
            # the runner froze its model out of the collector's sight: let the collector
            # have it back (a configure freezes what is left again)
            gc.unfreeze()

    @property
    def session(self):
        """Give the estimator's session, or None while there is none."""
        return self.runner.session if self.runner is not None else None

    def _on_set_parameters(self, params) -> SetParametersResult:
        if self.runner is not None:
            return self.runner.set_parameters(params)
        self.p.update({q.name: q.value for q in params if q.name in self.p})
        return SetParametersResult(successful=True)

    def report(self) -> interface.NodeReport:
        """Return the run's counts as data: per input, estimates, gaps, errors."""
        if self.runner is not None:
            return self.runner.report(NODE_NAME)
        return self._report or interface.NodeReport(node=NODE_NAME)

    def summary(self) -> str:
        """Return a one-line account of the run for a log: samples per input, gaps, jumps."""
        return summary(self.report())


class EstimatorNode(_Estimator, Node):
    """Thermal estimator node: subscribes to the rig's sensors, publishes estimates."""

    def __init__(self, **kwargs) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self._declare()
        self._make_runner()
        self.runner.start()

    def destroy_node(self) -> None:
        """Stop the Foxglove view and the what-if worker, then destroy the node."""
        self.runner.close()
        super().destroy_node()


class ManagedEstimatorNode(_Estimator, LifecycleNode):
    """The estimator as a lifecycle node: configure, activate, deactivate, cleanup, shutdown."""

    def __init__(self, **kwargs) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self._declare()
        self.get_logger().info('managed estimator: unconfigured (configure loads the '
                               'configuration and the model, activate starts it)')

    def on_configure(self, state) -> TransitionCallbackReturn:
        """Load and check the configuration and the inputs file; load the compiled model."""
        try:
            self._make_runner()
        except BAD_INPUT as exc:
            self.get_logger().error(f'configure failed: {exc}')
            return TransitionCallbackReturn.FAILURE
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state) -> TransitionCallbackReturn:
        """Subscribe and publish."""
        self.runner.start()
        return super().on_activate(state)

    def on_deactivate(self, state) -> TransitionCallbackReturn:
        """Send the drive's last limits (the fallback); stop taking samples and publishing."""
        self.runner.stop('the estimator was deactivated')
        return super().on_deactivate(state)

    def on_cleanup(self, state) -> TransitionCallbackReturn:
        """Drop the estimator: a configure loads it again."""
        self._drop_runner('the estimator was cleaned up')
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state) -> TransitionCallbackReturn:
        """Stop (the drive's last limits first, when active) and drop the estimator."""
        self._drop_runner('the estimator is shutting down')
        return TransitionCallbackReturn.SUCCESS

    def destroy_node(self) -> None:
        """Drop the estimator if shutdown did not, then destroy the node."""
        self._drop_runner('the estimator is shutting down')
        super().destroy_node()


MANAGED_HELP = ('start as a managed (lifecycle) node: unconfigured until configured and '
                'activated through its lifecycle services (/<node>/change_state)')
_DESCRIPTION = ('Live thermal estimator of the wet EHA (ROS 2 node). ROS arguments follow '
                '--ros-args, e.g. --ros-args --params-file config/estimator.params.yaml '
                '-p publish_rate_Hz:=20 -p use_sim_time:=true')


def main(args: Optional[List[str]] = None) -> int:
    """Run the estimator node until Ctrl-C or shutdown; return the exit status."""
    def close(node: _Estimator) -> int:
        print(node.summary(), file=sys.stderr, flush=True)
        node.report().write(sys.stdout)
        return 0

    return run_node(args, 'wet-eha-thermal-estimator', _DESCRIPTION,
                    lambda managed: (ManagedEstimatorNode if managed else EstimatorNode)(),
                    BAD_INPUT, log_executor=True, close=close,
                    flags={'managed': MANAGED_HELP})


if __name__ == '__main__':
    sys.exit(main())
