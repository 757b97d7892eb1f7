"""
Play a bag on the ROS graph with /clock, at a rate factor, optionally looped.

Node ``eha_player``: the messages of an MCAP bag (see
:mod:`wet_eha_thermal.bag.reader`; read as a stream, so memory stays flat)
are published as stored, CDR bytes unchanged, each on a publisher with the
QoS its recorder offered (``offered_qos_profiles`` of the channel: reliable
and transient local only when every offer was; the largest depth; reliable,
volatile, depth 100 when nothing was recorded), so the latched alerts stay
transient local.

Timing: the bag's log time runs on a scaled timeline, wall time elapsed x
rate. At each wake-up every message due (within 0.1 ms) is published in one
burst, preceded by a /clock (rosgraph_msgs/Clock) holding the log time of the
burst's last message; between bursts /clock follows the timeline at
``clock_hz`` without passing the next message. A use_sim_time node therefore
never receives a message before the clock has reached its log time, and a
Float64 (no header: stamped by the receiver with its ROS clock) gets the log
time of the last message of its burst. At rate 1 the bursts are one sample
time of a 1 kHz bag; at high rates they hold several samples, stamped alike.
/clock is published best effort, depth 1, as rosbag2 and rclpy's time source do.

Looping: each pass starts ``LOOP_GAP_NS`` of play time after the previous
one ended. By default /clock jumps back to the bag's start; consumers see time
going backwards (rclpy's ROS clock follows it: the estimator then refuses
every sample of the later passes as going backwards, their stamps being
those of the first pass again; the simulated rig re-anchors). With
``loop_offset`` pass k is
shifted by k x (bag span + gap): /clock keeps increasing, and so do the header
stamps of messages whose first field is a std_msgs/Header (rewritten in place,
zero stamps kept); stamps anywhere else inside a message keep their recorded
value.

A bag cut by a crash plays up to the last complete chunk (a warning says so);
a file that is not MCAP is one error, exit status 2. Messages stored out of
log-time order are published at once, /clock never goes back within a pass.

Run it with ``wet-eha-thermal-play BAG [--rate 2] [--loop] ...`` or
``python -m wet_eha_thermal.ros.player``; ROS arguments follow --ros-args.
"""

import argparse
import math
import signal
import struct
import sys
import time
from typing import Dict, Iterator, List, NamedTuple, Optional, Sequence, TextIO

import rclpy
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from wet_eha_thermal.bag.reader import BagError, BagInfo, iter_raw, open_bag, RawMessage
from wet_eha_thermal.ros.topics import message_class, time_msg
import yaml

NODE_NAME = 'eha_player'
PROG = 'wet-eha-thermal-play'
CLOCK_TOPIC = '/clock'
DEFAULT_DEPTH = 100          # history depth when the bag recorded no QoS, or depth 0
BATCH_WINDOW_S = 1e-4        # messages due this soon (wall time) join the current burst
MAX_BURST = 1000             # messages per burst; the rest follow at the next wake-up
MAX_SLEEP_S = 0.1            # longest sleep, so that Ctrl-C is served promptly
WAIT_POLL_S = 0.05           # subscriber check period of --wait-subscribers
LOOP_GAP_NS = 1_000_000      # play time between the end of a pass and the next one
ACK_TIMEOUT_S = 2.0          # wait at the end for reliable subscribers to acknowledge
TTY_PERIOD_S, LOG_PERIOD_S = 0.5, 5.0   # progress lines: on a terminal, in a log
_HEADER_TYPE = 'std_msgs/Header'
# CDR encapsulation (byte 1: 0 big, 1 little endian) then Header.stamp: int32 sec, uint32 nanosec
_STAMP = {0: struct.Struct('>iI'), 1: struct.Struct('<iI')}
_STAMP_AT = 4


def _policy(enum, value):
    """Return the QoS policy of a recorded value (short key or number), None if unknown."""
    try:
        if isinstance(value, str):
            return enum.get_from_short_key(value)
        return enum(value)
    except (KeyError, ValueError):
        return None


def recorded_qos(offered_qos_profiles: str) -> QoSProfile:
    """
    Return the QoS to publish a topic with, from its recorded ``offered_qos_profiles``.

    rosbag2's rule: reliable (transient local) only when every recorded
    publisher offered it, else best effort (volatile); the largest depth.
    Nothing usable recorded: reliable, volatile, depth ``DEFAULT_DEPTH``.
    """
    try:
        offers = yaml.safe_load(offered_qos_profiles or '[]')
    except yaml.YAMLError:
        offers = None
    if not isinstance(offers, list):
        offers = []
    offers = [o for o in offers if isinstance(o, dict)]
    reliability = [_policy(ReliabilityPolicy, o.get('reliability')) for o in offers]
    durability = [_policy(DurabilityPolicy, o.get('durability')) for o in offers]
    depths = [o['depth'] for o in offers if isinstance(o.get('depth'), int) and o['depth'] > 0]
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=max(depths, default=DEFAULT_DEPTH),
        reliability=(ReliabilityPolicy.BEST_EFFORT
                     if ReliabilityPolicy.BEST_EFFORT in reliability
                     else ReliabilityPolicy.RELIABLE),
        durability=(DurabilityPolicy.TRANSIENT_LOCAL
                    if durability and all(d == DurabilityPolicy.TRANSIENT_LOCAL
                                          for d in durability)
                    else DurabilityPolicy.VOLATILE))


def shift_header_stamp(data: bytes, shift_ns: int) -> bytes:
    """Return CDR ``data`` of a message starting with a std_msgs/Header, its stamp shifted."""
    layout = _STAMP.get(data[1]) if len(data) >= _STAMP_AT + 8 else None
    if layout is None:
        return data
    sec, nanosec = layout.unpack_from(data, _STAMP_AT)
    if sec == 0 and nanosec == 0:
        return data                   # zero means 'use the clock': keep it
    sec, nanosec = divmod(sec * 1_000_000_000 + nanosec + shift_ns, 1_000_000_000)
    return data[:_STAMP_AT] + layout.pack(sec, nanosec) + data[_STAMP_AT + 8:]


class _Output(NamedTuple):
    """Where the messages of one bag topic go."""

    publisher: object
    header_first: bool    # the message starts with a std_msgs/Header (stamp can be shifted)


class PlayerNode(Node):
    """
    Publish a bag's messages on their topics and /clock, paced on a scaled timeline.

    Drive it with :meth:`step` from one thread (the one of every other ROS
    call of the process): it publishes what is due and says when to call
    again. Play position 0 is the bag's first log time, reached ``delay_s``
    of wall time after construction or after :meth:`start_after` (the
    subscribers need time to discover the publishers); until then /clock
    holds the start time.
    """

    def __init__(self, info: BagInfo, *, rate: float = 1.0, loop: bool = False,
                 loop_offset: bool = False, topics: Optional[Sequence[str]] = None,
                 remap: Optional[Dict[str, str]] = None, clock_hz: float = 100.0,
                 delay_s: float = 0.5, **kwargs) -> None:
        if not (rate > 0 and math.isfinite(rate)):
            raise ValueError(f'rate {rate}: expected a positive number')
        if not (clock_hz >= 0 and math.isfinite(clock_hz)):
            raise ValueError(f'clock_hz {clock_hz}: expected 0 (no /clock) or more')
        unknown = sorted(set(topics or ()) - set(info.topics))
        if unknown:
            raise ValueError(f'topics not in the bag: {", ".join(unknown)} (it has '
                             f'{", ".join(sorted(info.topics)) or "none"})')
        super().__init__(NODE_NAME, start_parameter_services=False, **kwargs)
        self.info = info
        self.rate = rate
        self.loop = loop
        self.loop_offset = loop_offset
        self.clock_period_s = 1.0 / clock_hz if clock_hz > 0 else None
        self.start_ns = info.start_time_ns
        self.span_ns = info.end_time_ns - info.start_time_ns
        self.skipped: Dict[str, str] = {}     # topic -> why it is not played
        self.outputs: Dict[str, _Output] = {}
        remap = remap or {}
        for topic in topics or sorted(info.topics):
            entry = info.topics[topic]
            try:
                cls = message_class(entry.type_name)
            except (ImportError, AttributeError, ValueError) as exc:
                self.skipped[topic] = f'type {entry.type_name!r} not available ({exc})'
                continue
            first_field = next(iter(cls.get_fields_and_field_types().values()), None)
            self.outputs[topic] = _Output(
                self.create_publisher(cls, remap.get(topic, topic),
                                      recorded_qos(entry.offered_qos_profiles)),
                first_field == _HEADER_TYPE)
        for topic, why in self.skipped.items():
            self.get_logger().warning(f'not playing {topic}: {why}')
        self.clock_pub = None
        if self.clock_period_s is not None:
            self.clock_pub = self.create_publisher(
                Clock, CLOCK_TOPIC,
                QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
        self._clock = Clock()
        self.published = 0               # messages, /clock not counted
        self.passes = 0                  # passes begun (1 during the first)
        self.position_ns = 0             # play position of the last message published
        self.anchor_s = time.monotonic() + delay_s   # wall time of play position 0
        self._messages: Optional[Iterator[RawMessage]] = None
        self._next: Optional[RawMessage] = None
        self._clock_floor_ns = 0         # /clock published last in this pass
        self._clock_wall_s = -math.inf   # when /clock was published last
        self._begin_pass()

    # ------------------------------------------------------------ timeline
    def _pass_offset_ns(self) -> int:
        """Return the play position of the bag's start in the current pass."""
        return (self.passes - 1) * (self.span_ns + LOOP_GAP_NS)

    def _clock_shift_ns(self) -> int:
        """Return what is added to the log times of this pass on /clock and in headers."""
        return self._pass_offset_ns() if self.loop_offset else 0

    def _position_ns(self, msg: RawMessage) -> int:
        return msg.log_time_ns - self.start_ns + self._pass_offset_ns()

    def _due_s(self, msg: RawMessage) -> float:
        return self.anchor_s + self._position_ns(msg) * 1e-9 / self.rate

    def _begin_pass(self) -> bool:
        """Start reading the bag from its beginning; return whether it has a message."""
        self.close_bag()
        self.passes += 1
        self._messages = iter_raw(self.info.path, self.outputs)
        self._next = next(self._messages, None)
        self._clock_floor_ns = self.start_ns + self._clock_shift_ns()
        return self._next is not None

    def subscribed(self) -> bool:
        """Tell whether every played topic has a matched subscription."""
        return all(out.publisher.get_subscription_count() > 0 for out in self.outputs.values())

    def start_after(self, now_s: float, delay_s: float) -> None:
        """Reach play position 0 ``delay_s`` after wall time ``now_s`` (call before any step)."""
        self.anchor_s = now_s + delay_s

    def close_bag(self) -> None:
        """Close the bag file (done at the end of the play); playing again is not possible."""
        if self._messages is not None:
            self._messages.close()
            self._messages = None
        self._next = None

    # ------------------------------------------------------------- playing
    def _publish_clock(self, clock_ns: int, now_s: float) -> None:
        if self.clock_pub is None:
            return
        self._clock_floor_ns = max(self._clock_floor_ns, clock_ns)
        self._clock.clock = time_msg(self._clock_floor_ns)
        self.clock_pub.publish(self._clock)
        self._clock_wall_s = now_s

    def step(self, now_s: float) -> Optional[float]:
        """
        Publish what is due at wall time ``now_s`` (time.monotonic() s); return when to call again.

        Returns None when the play is over (end of the bag, not looping).
        """
        burst: List[RawMessage] = []
        while (self._next is not None and len(burst) < MAX_BURST
               and self._due_s(self._next) <= now_s + BATCH_WINDOW_S):
            burst.append(self._next)
            self._next = next(self._messages, None)
        if burst:
            shift_ns = self._clock_shift_ns()
            self._publish_clock(max(m.log_time_ns for m in burst) + shift_ns, now_s)
            for msg in burst:
                out = self.outputs[msg.topic]
                data = msg.data
                if shift_ns and out.header_first:
                    data = shift_header_stamp(data, shift_ns)
                out.publisher.publish(data)
                self.position_ns = max(self.position_ns, self._position_ns(msg))
            self.published += len(burst)
        if self._next is None:
            if not self.loop or not self._begin_pass():
                return None
        elif (self.clock_period_s is not None
              and now_s - self._clock_wall_s >= self.clock_period_s):
            timeline_ns = round((now_s - self.anchor_s) * self.rate * 1e9)
            limit_ns = self._position_ns(self._next)
            self._publish_clock(self.start_ns + self._clock_shift_ns() - self._pass_offset_ns()
                                + min(timeline_ns, limit_ns), now_s)
        wake_s = self._due_s(self._next)
        if self.clock_period_s is not None:
            wake_s = min(wake_s, self._clock_wall_s + self.clock_period_s)
        return wake_s

    def wait_for_acks(self, timeout_s: float = ACK_TIMEOUT_S) -> bool:
        """Wait until reliable subscribers acknowledged everything published, at most timeout_s."""
        end_s = time.monotonic() + timeout_s
        acked = True
        for out in self.outputs.values():
            left_s = max(end_s - time.monotonic(), 0.0)
            acked = out.publisher.wait_for_all_acked(
                Duration(nanoseconds=round(left_s * 1e9))) and acked
        return acked

    def progress(self, now_s: float) -> str:
        """Return a one-line progress report: time played / total, rate achieved."""
        played_s = self.position_ns * 1e-9
        total_s = self.span_ns * 1e-9
        in_pass_s = played_s - self._pass_offset_ns() * 1e-9
        wall_s = now_s - self.anchor_s
        rate = f'{played_s / wall_s:.2f}x' if wall_s > 0.05 else '-'
        line = (f'{max(in_pass_s, 0.0):.1f} / {total_s:.1f} s '
                f'({100.0 * max(in_pass_s, 0.0) / total_s if total_s else 100.0:.0f} %), '
                f'rate {rate} (asked {self.rate:g}x), {self.published} messages')
        if self.loop:
            line += f', pass {self.passes}'
        return line

    def destroy_node(self) -> None:
        """Close the bag and destroy the node."""
        self.close_bag()
        super().destroy_node()


class _Progress:
    """Print the progress line on a stream: in place on a terminal, now and then in a log."""

    def __init__(self, stream: TextIO, quiet: bool) -> None:
        self.stream = stream
        self.quiet = quiet
        self.tty = stream.isatty()
        self.period_s = TTY_PERIOD_S if self.tty else LOG_PERIOD_S
        self.next_s = time.monotonic() + self.period_s
        self.width = 0

    def update(self, node: PlayerNode, now_s: float) -> None:
        if self.quiet or now_s < self.next_s:
            return
        self.next_s = now_s + self.period_s
        line = node.progress(now_s)
        if self.tty:
            self.width = max(self.width, len(line))
            self.stream.write('\r' + line.ljust(self.width))
        else:
            self.stream.write(line + '\n')
        self.stream.flush()

    def finish(self, node: PlayerNode, how: str) -> None:
        if self.quiet:
            return
        if self.tty and self.width:
            self.stream.write('\r' + ' ' * self.width + '\r')
        self.stream.write(f'{how}: {node.progress(time.monotonic())}\n')
        self.stream.flush()


def _remap(text: str):
    old, sep, new = text.partition(':=')
    if not (sep and old and new):
        raise argparse.ArgumentTypeError(f'{text!r}: expected OLD:=NEW')
    return old, new


def _positive(text: str) -> float:
    value = float(text)
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f'{text}: expected a positive number')
    return value


def _not_negative(text: str) -> float:
    value = float(text)
    if not (value >= 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f'{text}: expected 0 or a positive number')
    return value


def build_parser() -> argparse.ArgumentParser:
    """Return the parser of the player's options (the ROS arguments taken out before)."""
    parser = argparse.ArgumentParser(
        prog=PROG,
        description='Play a bag (MCAP) on the ROS graph with /clock, so that nodes with '
                    'use_sim_time run on its time. ROS arguments follow --ros-args.')
    parser.add_argument('bag', help='an .mcap file, or a rosbag2 bag directory (its files as '
                        'one run)')
    parser.add_argument('--rate', type=_positive, default=1.0,
                        help='play time per wall time (default: %(default)s)')
    parser.add_argument('--loop', action='store_true',
                        help='play again from the start at the end, until Ctrl-C; /clock '
                             'jumps back to the start (see --loop-offset)')
    parser.add_argument('--loop-offset', action='store_true',
                        help='with --loop: shift each pass by the bag span, so /clock and '
                             'leading header stamps keep increasing')
    parser.add_argument('--topics', nargs='+', metavar='TOPIC',
                        help='play these topics only (default: every topic)')
    parser.add_argument('--remap', nargs='+', type=_remap, default=[], metavar='OLD:=NEW',
                        help='publish topic OLD of the bag on NEW')
    parser.add_argument('--clock-hz', type=_not_negative, default=100.0,
                        help='/clock rate between bursts; 0: no /clock (default: %(default)s)')
    parser.add_argument('--delay', type=_not_negative, default=0.5, metavar='SECONDS',
                        help='wall time between creating the publishers and the first '
                             'message, for discovery; /clock holds the start meanwhile '
                             '(default: %(default)s)')
    parser.add_argument('--wait-subscribers', action='store_true',
                        help='before the delay, wait until every played topic has a '
                             'subscriber (scripts and tests: no message lost to discovery)')
    parser.add_argument('--quiet', action='store_true', help='no progress line')
    return parser


def split_ros_args(argv: Sequence[str]):
    """
    Return (the player's arguments, the ROS arguments) of ``argv``.

    The ROS arguments are the ``--ros-args ... [--]`` sections. rclpy's
    remove_ros_args is not used: it also takes any ``OLD:=NEW`` (rcl's
    deprecated remap syntax), which would swallow the values of --remap.
    """
    ours: List[str] = []
    ros: List[str] = []
    inside = False
    for arg in argv:
        if arg == '--ros-args':
            inside = True
        elif inside and arg == '--':
            inside = False
            continue
        (ros if inside else ours).append(arg)
    return ours, ros


def _describe(info: BagInfo) -> str:
    return (f'{info.path}: {info.message_count} messages on {len(info.topics)} topics, '
            f'{(info.end_time_ns - info.start_time_ns) * 1e-9:.3f} s')


def _open(opts: argparse.Namespace) -> Optional[BagInfo]:
    """Return the bag to play, having said what it holds; None (said why) when it cannot play."""
    try:
        info = open_bag(opts.bag)
    except BagError as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return None
    if info.message_count == 0:
        print(f'{PROG}: error: {info.path}: no message to play', file=sys.stderr)
        return None
    if info.truncated:
        print(f'{PROG}: warning: the bag is cut ({info.problem}); playing what precedes '
              f'the cut: {_describe(info)}', file=sys.stderr)
    elif not opts.quiet:
        print(f'{PROG}: {_describe(info)}', file=sys.stderr)
    return info


def _play(node: PlayerNode, opts: argparse.Namespace, stop: List[int]) -> None:
    """Play until the bag's end, a signal (in ``stop``) or rclpy's shutdown."""
    if opts.wait_subscribers:
        if not opts.quiet:
            print(f'{PROG}: waiting for a subscriber on every topic', file=sys.stderr)
        while not (stop or node.subscribed()) and rclpy.ok():
            time.sleep(WAIT_POLL_S)
        node.start_after(time.monotonic(), opts.delay)
    progress = _Progress(sys.stderr, opts.quiet)
    wake_s = node.step(time.monotonic())
    while wake_s is not None and not stop and rclpy.ok():
        now_s = time.monotonic()
        if wake_s > now_s:
            time.sleep(min(wake_s - now_s, MAX_SLEEP_S))
            now_s = time.monotonic()
        if now_s >= wake_s:
            wake_s = node.step(now_s)
        progress.update(node, now_s)
    node.close_bag()
    if wake_s is None and not node.wait_for_acks():
        print(f'{PROG}: warning: not every reliable subscriber acknowledged the last '
              'messages', file=sys.stderr)
    progress.finish(node, 'stopped' if wake_s is not None else 'done')


def main(argv: Optional[List[str]] = None) -> int:
    """Play a bag until its end (exit 0), Ctrl-C or SIGTERM; 2 for a bad bag or option."""
    ours, ros_args = split_ros_args(sys.argv[1:] if argv is None else argv)
    opts = build_parser().parse_args(ours)
    if opts.loop_offset and not opts.loop:
        print(f'{PROG}: error: --loop-offset needs --loop', file=sys.stderr)
        return 2
    info = _open(opts)
    if info is None:
        return 2

    stop: List[int] = []

    def on_signal(signum, frame) -> None:
        stop.append(signum)

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    rclpy.init(args=[PROG] + ros_args, signal_handler_options=SignalHandlerOptions.NO)
    node = None
    try:
        try:
            node = PlayerNode(info, rate=opts.rate, loop=opts.loop,
                              loop_offset=opts.loop_offset, topics=opts.topics,
                              remap=dict(opts.remap), clock_hz=opts.clock_hz,
                              delay_s=opts.delay)
        except ValueError as exc:
            print(f'{PROG}: error: {exc}', file=sys.stderr)
            return 2
        if not node.outputs:
            print(f'{PROG}: error: no topic of the bag can be published', file=sys.stderr)
            return 2
        _play(node, opts, stop)
        return 0
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        for s, handler in old.items():
            signal.signal(s, handler)


if __name__ == '__main__':
    sys.exit(main())
