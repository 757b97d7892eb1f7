"""``wet-eha-thermal live``: the live digital twin, the estimator on the simulated rig."""

import argparse
from pathlib import Path

from .arguments import add_duty_arguments, at_least, BadArgument, default, in_range, positive
from ..config import load_config

HELP = 'the live digital twin: estimator on the simulated rig'
DESCRIPTION = ('Run the live digital twin: the simulated rig (ROS 2 node eha_sim_rig) publishes '
               'the sensor topics of a stage or a duty file, the estimator '
               '(eha_thermal_estimator) follows them, and a status line shows the estimated '
               'temperatures, margin, time to limit, alerts and stale inputs. Ends after '
               '--duration or on Ctrl-C with a summary. The recorder (eha_recorder) writes the '
               'run to a rosbag2 bag of MCAP files. The nodes run on a private ROS domain (from '
               'the process id, or $WET_EHA_LIVE_DOMAIN_ID).')
#: Sensor sample rates the rig can publish at (Hz).
RATE_RANGE_HZ = (50.0, 10000.0)


def foxglove_address(text: str):
    """Return ``(host, port)`` of ``--foxglove`` HOST:PORT; a port is needed (live prints it)."""
    from ..live_view import parse_address

    try:
        host, port = parse_address(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    if port == 0:       # live prints the address to open: it must know it
        raise argparse.ArgumentTypeError(f'{text}: give a port, 1..65535')
    return host, port


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the options of ``live``; the defaults are those of :class:`.LiveOptions`."""
    from ..live_view import address_text
    from ..ros.live_children import LiveOptions

    add_duty_arguments(p, required=False, default_stage=default(LiveOptions, 'stage'))
    p.add_argument('--duration', type=positive('seconds'),
                   default=default(LiveOptions, 'duration_s'),
                   help='how long to run, s (default: %(default)g)')
    p.add_argument('--rate-Hz', type=in_range(*RATE_RANGE_HZ, 'Hz'),
                   default=default(LiveOptions, 'rate_Hz'),
                   help='sensor sample rate of the rig, Hz (default: %(default)g)')
    p.add_argument('--config', type=Path, default=None,
                   help='YAML configuration of rig and estimator (default: the reference rig)')
    p.add_argument('--no-noise', action='store_true', help='publish noise-free sensor values')
    p.add_argument('--executor', choices=('events', 'single'),
                   default=default(LiveOptions, 'executor'),
                   help='rclpy executor of both nodes (default: %(default)s)')
    p.add_argument('--record', type=Path, default=None, metavar='PATH',
                   help='recording of the run: a rosbag2 bag directory, as ros2 bag record -o '
                        'makes, or one MCAP file when PATH ends in .mcap; never overwritten '
                        '(default: runs/live_<UTC time>)')
    p.add_argument('--no-record', action='store_true', help='do not record the run')
    p.add_argument('--max-bag-size', type=at_least(0, ' bytes (0: no size split)', int),
                   default=default(LiveOptions, 'max_bag_size_B'), metavar='BYTES',
                   help='start a new file of the recording after this many bytes, as ros2 bag '
                        'record -b; 0: no size split (default: %(default)d, 1 GiB)')
    p.add_argument('--max-bag-duration', type=at_least(0, ' s (0: no time split)'),
                   default=default(LiveOptions, 'max_bag_duration_s'), metavar='SECONDS',
                   help='start a new file of the recording after this much time, as ros2 bag '
                        'record -d; 0: no time split (default: %(default)g s). Each closed '
                        'file is complete: a crash or a full disk cannot take the run whole')
    p.add_argument('--foxglove', type=foxglove_address,
                   default=address_text(*default(LiveOptions, 'foxglove')), metavar='HOST:PORT',
                   help='where the estimator serves the Foxglove view (estimates with their '
                        'bands, margins, alerts, inputs, thermocouples; open it with '
                        'layouts/live.json); live prints the address to open; one taken is '
                        'one warning and the run goes on without it (default: %(default)s)')
    p.add_argument('--no-foxglove', action='store_true', help='no Foxglove view')
    p.add_argument('--closed-loop', action='store_true',
                   help="the rig's simulated drive honours the current limit the estimator "
                        'publishes (the load yields where the duty asks for more); the status '
                        'line and the summary show when it binds')
    p.add_argument('--rig-as-built', type=at_least(0, ' (a seed; 0: the rig is the configuration)',
                                                   int),
                   default=default(LiveOptions, 'as_built_seed'), metavar='SEED',
                   help="the rig's truth is the configuration with its uncertain parameters "
                        'drawn with SEED (docs/live.md); 0: the configuration itself '
                        '(default: %(default)d)')


def run(args: argparse.Namespace) -> int:
    """Check the configuration and the duty, then run the twin."""
    from ..model.duty import load_duty_csv, stage_duty
    from ..ros.live_children import LiveOptions

    # check the configuration and the duty here, so that a mistake is one line, not two
    # children failing
    cfg = load_config(args.config)
    act = cfg.hydraulics.actuator
    if args.duty is not None:
        load_duty_csv(args.duty, act.area_m2, act.half_stroke_m)
    stage = None if args.duty is not None else (args.stage or default(LiveOptions, 'stage'))
    if stage is not None:
        stage_duty(cfg, stage)
    from ..ros import live, live_monitor

    try:
        domain = live_monitor.domain_from_env()
    except ValueError as exc:
        raise BadArgument(str(exc)) from None
    opts = LiveOptions(stage=stage, duty=args.duty, duration_s=args.duration,
                       rate_Hz=args.rate_Hz, config=args.config, noise=not args.no_noise,
                       executor=args.executor, record=not args.no_record,
                       record_path=args.record, max_bag_size_B=args.max_bag_size,
                       max_bag_duration_s=args.max_bag_duration,
                       foxglove=None if args.no_foxglove else args.foxglove,
                       closed_loop=args.closed_loop, as_built_seed=args.rig_as_built)
    return live.run(opts, domain=domain)
