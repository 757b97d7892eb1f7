"""``wet-eha-thermal whatif``: what a duty does from the live state, a bag's last, or cold."""

import argparse
import json
from pathlib import Path
import time

from .arguments import add_out, BadArgument, default, existing, existing_file, positive, stage
from ..config import load_config

HELP = 'what a duty does from where the actuator is now'
DESCRIPTION = ('Run a duty from the state of a running estimator (asked over ROS, on this '
               'ROS_DOMAIN_ID), from the last state of a recorded bag (--bag, replayed first) '
               'or cold (--cold); print the peaks and when each limit is reached; write '
               'whatif.csv and whatif.png.')
#: Time to run the duty by default (s).
DURATION_S = 3600.0


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the options of ``whatif``; the defaults are those of the what-if and its client."""
    from ..offline.simulation import simulate
    from ..offline.whatif import DEFAULT_DT_S
    from ..ros.whatif_client import ask

    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument('--stage', type=stage, default=None, help='reference stage number (1-6)')
    which.add_argument('--duty', type=existing_file, metavar='FILE.csv',
                       help='duty table: time_s, flow_L_min, load_MPa (repeats periodically)')
    which.add_argument('--samples', type=existing_file, metavar='FILE.csv',
                       help='sensor table: time_s, current_A, speed_rad_s, p_a_Pa, p_b_Pa, '
                            'p_acc_Pa[, position_m], SI units (repeats periodically)')
    start = p.add_mutually_exclusive_group()
    start.add_argument('--bag', type=existing, default=None, metavar='PATH',
                       help='start from the last state of this bag (an MCAP file or a bag '
                            'directory), replayed through the estimator')
    start.add_argument('--cold', action='store_true',
                       help='start cold: every temperature at the ambient')
    # range checks of the duration, ambient and step are the request's (parse_request)
    p.add_argument('--duration', type=float, default=DURATION_S,
                   help='time to run the duty, s (default: %(default)g)')
    p.add_argument('--ambient-C', type=float, default=None,
                   help="ambient temperature, degC (default: the estimator's; cold: "
                        f"{default(simulate, 'ambient_C'):g})")
    p.add_argument('--dt', type=float, default=None,
                   help=f'thermal model step, s (default: {DEFAULT_DT_S:g})')
    p.add_argument('--config', type=Path, default=None,
                   help='YAML configuration for --bag and --cold (default: stored in the bag, '
                        'else the reference rig)')
    p.add_argument('--topic-prefix', default=default(ask, 'prefix'),
                   help="the estimator's topic_prefix (default: %(default)s)")
    p.add_argument('--timeout', type=positive('seconds'), default=default(ask, 'timeout_s'),
                   help="how long to wait for the estimator's answer, s (default: %(default)g)")
    add_out(p, 'whatif')


def request_of(args: argparse.Namespace, cfg) -> dict:
    """Return the request of the command line (the duty's files read and checked)."""
    from ..model.duty import load_duty_csv
    from ..offline.whatif import read_samples_csv, RequestError
    from ..units import L_MIN, MPA

    request = {'id': f'cli-{time.time_ns()}', 'duration_s': args.duration}
    if args.ambient_C is not None:
        request['ambient_C'] = args.ambient_C
    if args.dt is not None:
        request['dt_s'] = args.dt
    if args.stage is not None:
        request['stage'] = args.stage
    elif args.duty is not None:
        act = cfg.hydraulics.actuator
        t, q, dp = load_duty_csv(args.duty, act.area_m2, act.half_stroke_m).rows()
        request['table'] = {'time_s': t.tolist(), 'flow_L_min': (q / L_MIN).tolist(),
                            'load_MPa': (dp / MPA).tolist()}
    else:
        try:
            request['samples'] = read_samples_csv(args.samples)
        except RequestError as exc:
            raise BadArgument(f'--samples {exc}') from None
    return request


def _ask_live(args: argparse.Namespace) -> str:
    """Return the answer of the running estimator on ``--topic-prefix``."""
    from ..ros.whatif_client import ask, NoAnswer

    request = request_of(args, load_config(args.config))
    print(f'asking the estimator on {args.topic_prefix}/whatif/request ...', flush=True)
    try:
        return ask(json.dumps(request), request['id'], args.topic_prefix, args.timeout)
    except NoAnswer as exc:
        raise BadArgument(str(exc)) from None


def _run_cold(args: argparse.Namespace) -> str:
    """Return the answer from every temperature at the ambient."""
    from ..offline.simulation import simulate
    from ..offline.whatif import model_outputs
    from ..offline.whatif_worker import run_request

    cfg = load_config(args.config)
    return run_request(json.dumps(request_of(args, cfg)), cfg, model_outputs(cfg), None,
                       default(simulate, 'ambient_C'), 'cold', None)


def _run_from_bag(args: argparse.Namespace) -> str:
    """Return the answer from the last state of ``--bag``, replayed through the estimator."""
    import pickle

    from ..estimator.session import EstimatorSession
    from ..offline import replay as rp
    from ..offline.whatif_worker import run_request

    try:
        plan = rp.ReplayOptions(config_path=args.config).plan(args.bag)
        session = EstimatorSession(plan.cfg)
        print(f'replaying {args.bag} for its last state ...', flush=True)
        rp.replay(plan, session=session)
    except (rp.ReplayError, rp.BagError) as exc:
        raise BadArgument(str(exc)) from None
    return run_request(json.dumps(request_of(args, plan.cfg)), plan.cfg,
                       session.model.quantities.names, pickle.dumps(session.model),
                       session.ambient_C, f'the last state of {args.bag}', session.t_model)


def run(args: argparse.Namespace) -> int:
    """Ask or run the what-if, print the answer and write its files; 2 if it was refused."""
    from ..offline.whatif import format_answer, write_answer

    if args.cold:
        text = _run_cold(args)
    elif args.bag is not None:
        text = _run_from_bag(args)
    else:
        text = _ask_live(args)
    answer = json.loads(text)
    print(format_answer(answer))
    if not answer['ok']:
        return 2
    out = args.out
    try:
        files = write_answer(answer, out)
    except OSError as exc:
        raise BadArgument(f'--out {out}: cannot write the results: {exc.strerror or exc}') \
            from None
    print('wrote ' + ', '.join(str(f) for f in files))
    return 0
