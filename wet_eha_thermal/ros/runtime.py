"""
Executors, spinning, clocks, readiness and parameter helpers for the nodes of this package.

Measured with the ROS 2 Jazzy wheels (rclpy 7.1.6): ``EventsExecutor.spin()``
never runs a callback and ignores Ctrl-C, so :func:`spin` turns the executor
in slices of 0.1 s instead (``spin_until_future_complete`` with a timeout,
which runs every callback due in the slice without returning to Python in
between); the MultiThreadedExecutor loses most messages of a 1 kHz
subscription and is not offered.
"""

import argparse
import gc
import json
import signal
import sys
import time
from types import MappingProxyType
from typing import Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Type

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future
from rclpy.utilities import remove_ros_args
from std_msgs.msg import String
from wet_eha_thermal import interface
from wet_eha_thermal.config import Config
from wet_eha_thermal.ros.topics import FROM_NAMESPACE, latched_qos, PREFIX_DOC, resolve_prefix

EXECUTORS = ('events', 'single')
#: What a node's ``qos`` parameter may name (:func:`~.topics.input_qos`).
QOS_KINDS = ('sensor_data', 'reliable')


class FastClock:
    """
    A node's ROS clock in nanoseconds, cheap enough to read for every sample.

    Without sim time the ROS clock is the system clock, and ``time.time_ns()``
    reads it in 0.06 us where rclpy's ``Clock.now()`` takes 3.6 us (measured
    here). Under ``use_sim_time`` it reads the ROS clock (0 before the first
    /clock). Whether sim time is on is looked up twice a second, on the
    steady clock, so that switching ``use_sim_time`` at run time takes effect.
    """

    def __init__(self, node: Node) -> None:
        self._clock = node.get_clock()
        self.sim = self._clock.ros_time_is_active
        node.create_timer(0.5, self._look, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def _look(self) -> None:
        self.sim = self._clock.ros_time_is_active

    def now_ns(self) -> int:
        """Return the ROS clock (ns)."""
        return self._clock.now().nanoseconds if self.sim else time.time_ns()


class Readiness:
    """
    Say on the ready topic (latched JSON) when this node is ready for the rig's duty.

    Constructed once the node's slow start is over (model compiled and warmed);
    it then waits, on a steady 10 Hz timer, until its ``subscriptions`` have
    matched their publishers: every one of them with ``require_all``, else
    every one whose topic has a publisher in the graph (at least one). The
    simulated rig starts its duty only after the nodes it waits for said so
    (``wait_for``), so that no sample is published before anyone listens.
    ``extra``: more keys of the ready message (what the node serves, say);
    ``also``: subscriptions that must have matched a publisher in any case.
    """

    def __init__(self, node: Node, topic: str, subscriptions: Sequence,
                 hardware_id: str, require_all: bool, extra: Optional[dict] = None,
                 also: Sequence = ()) -> None:
        self.node = node
        self.subscriptions = list(subscriptions)
        self.also = list(also)
        self.require_all = require_all
        self.hardware_id = hardware_id
        self.extra = dict(extra or {})
        self.ready = False
        self.publisher = node.create_publisher(String, topic, latched_qos())
        self._timer = node.create_timer(0.1, self.check,
                                        clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.check()

    def check(self) -> bool:
        """Publish the ready message once the subscriptions are matched; return whether ready."""
        if self.ready:
            return True
        subs = self.subscriptions if self.require_all else [
            s for s in self.subscriptions if self.node.count_publishers(s.topic_name) > 0]
        needed = subs + self.also
        if not subs or any(s.get_publisher_count() == 0 for s in needed):
            return False
        self.ready = True
        self._timer.cancel()
        self.publisher.publish(String(data=json.dumps({
            **self.extra, 'node': self.node.get_name(), 'ready': True,
            'hardware_id': self.hardware_id,
            'matched_topics': sorted(s.topic_name for s in needed)})))
        self.node.get_logger().info(f'ready: {len(subs)} input topics matched'
                                    + (f', and {len(self.also)} more' if self.also else ''))
        return True


def prepare_model_step(node: Node, cfg: Config, estimator: bool = False) -> None:
    """
    Compile the model's kernels (or load them from numba's cache), saying so in the log.

    ``estimator``: also the estimator core's (the estimator node's first samples).
    """
    # imported here: the recorder and the player use this module and need no model
    from wet_eha_thermal.estimator.warmup import compile_estimator
    from wet_eha_thermal.model.warmup import compile_model
    node.get_logger().info('loading the compiled model step (after an install or a change of '
                           'the model code it compiles once, in about a minute)')
    seconds = (compile_estimator if estimator else compile_model)(cfg)
    node.get_logger().info(f'model step ready in {seconds:.1f} s')


def make_executor(kind: str):
    """Return an executor: 'events' (rclpy.experimental.EventsExecutor) or 'single'."""
    if kind not in EXECUTORS:
        raise ValueError(f'executor {kind!r}: expected one of {", ".join(EXECUTORS)}')
    if kind == 'events':
        from rclpy.experimental import EventsExecutor
        return EventsExecutor()
    return SingleThreadedExecutor()


def spin(executor, node: Node, started: Optional[Callable[[], None]] = None) -> None:
    """
    Spin ``executor`` until SIGINT (Ctrl-C), SIGTERM or a shutdown of the context.

    The executor turns in slices of 0.1 s (see the module docstring). The
    signals only set a flag, so that no KeyboardInterrupt lands inside a
    callback. The flag alone is not enough: an EventsExecutor slice ends at
    its timeout only once its queue is empty, which on a busy machine (inputs
    at 1 kHz, callbacks outlasting their timers' periods) may be never. So a
    steady 10 Hz timer of ``node`` completes the future the slice waits on,
    which ends it after the callback running. Not the handler itself: it may
    interrupt the main thread inside that future's lock, which each slice
    takes, and deadlock. ``started()`` runs once the handlers are in place
    (a node logs that it spins there, so that a Ctrl-C sent on that line is
    caught).
    """
    signals = []
    stopped = Future()

    def on_signal(signum, frame) -> None:
        signals.append(signum)

    def end_slice() -> None:
        if signals and not stopped.done():
            stopped.set_result(signals[0])

    timer = node.create_timer(0.1, end_slice, clock=Clock(clock_type=ClockType.STEADY_TIME))
    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        if started is not None:
            started()
        while rclpy.ok() and not signals:
            executor.spin_until_future_complete(stopped, timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)
        node.destroy_timer(timer)


def accept_whole_numbers(node: Node, defaults: Mapping[str, object]) -> None:
    """
    Read an integer override of a double parameter (``-p rate_Hz:=500``) as a double.

    YAML types ``500`` as an integer, and declaring a double parameter with
    it fails. rclpy keeps the command-line overrides in the node's private
    ``_parameter_overrides``; call this before declaring the parameters.
    """
    overrides = getattr(node, '_parameter_overrides', None)
    if not isinstance(overrides, dict):
        return
    for name, default in defaults.items():
        given = overrides.get(name)
        if isinstance(default, float) and given is not None \
                and given.type_ == Parameter.Type.INTEGER:
            overrides[name] = Parameter(name, Parameter.Type.DOUBLE, float(given.value))


def descriptor(text: str, low=None, high=None, read_only: bool = True) -> ParameterDescriptor:
    """
    Return a parameter's descriptor: the one way the nodes build them.

    ``low``/``high`` (ints or floats) give its range. The type is left unset:
    rclpy takes it from the declared default (or the declared type).
    """
    d = ParameterDescriptor(description=text, read_only=read_only)
    if isinstance(low, int):
        d.integer_range = [IntegerRange(from_value=low, to_value=high, step=1)]
    elif low is not None:
        d.floating_point_range = [FloatingPointRange(from_value=float(low),
                                                     to_value=float(high), step=0.0)]
    return d


def shared_parameters(*names: str) -> Dict[str, Tuple[object, ParameterDescriptor]]:
    """
    Return the declarations (name -> (default, descriptor)) of the parameters the nodes share.

    One declaration, one range and one check (:func:`declare_parameters`)
    for ``qos``, ``qos_depth``, ``topic_prefix``, ``hardware_id`` and
    ``executor``, whichever node declares them; ``names`` picks those a node has.
    """
    shared = {
        'qos': ('sensor_data', descriptor(
            "QoS of the sensor topics: 'sensor_data' (best effort) or 'reliable'")),
        'qos_depth': (1000, descriptor('history depth of the sensor subscriptions', 1, 100000)),
        'topic_prefix': (FROM_NAMESPACE, descriptor(PREFIX_DOC)),
        'hardware_id': (FROM_NAMESPACE, descriptor(
            "hardware_id of the diagnostic statuses and the ready messages; '' = "
            f"{interface.HARDWARE_ID} followed by the node's namespace "
            f"({interface.hardware_id('/left')} under /left, {interface.HARDWARE_ID} at the "
            'root)')),
        'executor': ('events', descriptor(
            "executor used by main(): 'events' (rclpy.experimental.EventsExecutor) or 'single' "
            '(SingleThreadedExecutor); the --executor option overrides it')),
    }
    return {name: shared[name] for name in names}


def declare_parameters(node: Node, parameters: Mapping[str, Tuple[object, ParameterDescriptor]]
                       ) -> Dict[str, object]:
    """
    Declare ``parameters`` (name -> (default, descriptor)) on ``node``; return their values.

    The shared ones (:func:`shared_parameters`) are checked here: ValueError
    names the parameter, its value and what is allowed; ``topic_prefix``
    comes back resolved (:func:`~wet_eha_thermal.ros.topics.resolve_prefix`),
    and an empty ``hardware_id`` as the namespace's
    (:func:`~wet_eha_thermal.interface.hardware_id`).
    """
    accept_whole_numbers(node, {name: default for name, (default, _) in parameters.items()})
    values = {name: node.declare_parameter(name, default, desc).value
              for name, (default, desc) in parameters.items()}
    allowed = {'qos': QOS_KINDS, 'executor': EXECUTORS}
    for name, kinds in allowed.items():
        if name in values and values[name] not in kinds:
            raise ValueError(f'parameter {name} = {values[name]!r}: expected one of '
                             f'{", ".join(kinds)}')
    if 'topic_prefix' in values:       # the prefix itself: '' is the node's namespace
        values['topic_prefix'] = resolve_prefix(node, values['topic_prefix'])
    if values.get('hardware_id') == FROM_NAMESPACE:
        values['hardware_id'] = interface.hardware_id(node.get_namespace())
    return values


def parse_node_options(argv: List[str], prog: str, description: str,
                       flags: Mapping[str, str] = MappingProxyType({})) -> argparse.Namespace:
    """
    Parse a node's own options from ``argv`` (with the program name), ROS arguments removed.

    ``--executor``, None meaning the node's ``executor`` parameter, and the
    node's own on/off ``flags`` (name of ``--name``: its help).
    """
    parser = argparse.ArgumentParser(prog=prog, description=description)
    parser.add_argument('--executor', choices=EXECUTORS, default=None,
                        help="'events' (rclpy.experimental.EventsExecutor) or 'single' "
                             '(SingleThreadedExecutor); default: the executor parameter, '
                             'which defaults to events')
    for name, text in flags.items():
        parser.add_argument(f'--{name}', action='store_true', help=text)
    return parser.parse_args(remove_ros_args(argv)[1:])


def run_node(args: Optional[List[str]], prog: str, description: str,
             make_node: Callable[[], Node], bad_input: Tuple[Type[BaseException], ...], *,
             error_prefix: Optional[str] = None, log_executor: bool = False,
             after_spin: Optional[Callable[[Node, object], None]] = None,
             close: Optional[Callable[[Node], int]] = None,
             flags: Mapping[str, str] = MappingProxyType({})) -> int:
    """
    Run one node of this package as a program until Ctrl-C, SIGTERM or shutdown.

    ``args`` is the command line with the program name (None: ``sys.argv``).
    An exception of ``bad_input`` while making the node (a bad parameter,
    configuration or file) is one line on stderr, ``<error_prefix>: <reason>``
    (default prefix: ``prog``), and exit status 2. The executor is
    ``--executor``, else the node's ``executor`` parameter, else events.
    ``after_spin(node, executor)`` runs once spinning stopped (a recorder
    drains); ``close(node)`` runs before the node is destroyed and returns
    the exit status (default 0). ``flags``: the node's own on/off options
    (name of ``--name``: help), given to ``make_node`` by name.
    """
    argv = list(sys.argv if args is None else args)
    opts = parse_node_options(argv, prog, description, flags)
    rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    node = None
    status = 0
    try:
        try:
            node = make_node(**{name: getattr(opts, name) for name in flags})
        except bad_input as exc:
            print(f'{error_prefix or prog}: {exc}', file=sys.stderr)
            return 2
        kind = opts.executor or (node.get_parameter('executor').value
                                 if node.has_parameter('executor') else 'events')
        # what the start loaded (modules, compiled kernels) stays for good: out of the
        # collector's full passes, which would otherwise stall a callback now and then
        gc.freeze()
        executor = make_executor(kind)
        try:
            # inside: a Ctrl-C while the node is added still shuts the executor down
            executor.add_node(node)
            spin(executor, node, started=(
                lambda: node.get_logger().info(f'spinning with the {kind} executor'))
                if log_executor else None)
            if after_spin is not None:
                after_spin(node, executor)
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        finally:
            executor.shutdown()
    except KeyboardInterrupt:
        pass
    finally:
        if node is not None:
            if close is not None:
                status = close(node)
            node.destroy_node()
        rclpy.try_shutdown()
    return status
