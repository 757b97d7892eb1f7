"""``wet-eha-thermal layout``: a Foxglove layout for an actuator in a namespace."""

import argparse
from pathlib import Path

from .arguments import BadArgument

HELP = 'write the Foxglove layout (live view or recording) for an actuator in a namespace'
DESCRIPTION = ("Write the shipped Foxglove layout layouts/live.json (the estimator's live "
               'view) or layouts/replay.json (a recording) for the nodes of one actuator: its '
               "topics under the namespace (or --topic-prefix), the nodes' diagnostic statuses "
               'named with it. Import the file in Foxglove (Layout, Import from file).')


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the options of ``layout``: which layout, the namespace, the prefix, the file."""
    from ..layouts import NAMES
    p.add_argument('which', choices=NAMES, help='live: the Foxglove view; replay: a recording')
    p.add_argument('--namespace', default='/',
                   help="the actuator's namespace, as -r __ns:= gave it (default: the root, "
                        'whose topics are /eha)')
    p.add_argument('--topic-prefix', default=None,
                   help="the nodes' topic_prefix parameter when it was set (default: the "
                        "namespace's prefix)")
    p.add_argument('-o', '--output', type=Path, default=None,
                   help='layout file to write (default: <which>_<namespace>.json here)')


def run(args: argparse.Namespace) -> int:
    """Write the layout; print where."""
    from ..interface import namespace_prefix
    from ..layouts import write_layout
    from ..launch_plan import namespace_of

    try:
        namespace = '/' if args.namespace.strip('/') == '' else namespace_of(
            args.namespace, '--namespace')
    except ValueError as exc:
        raise BadArgument(str(exc)) from None
    prefix = args.topic_prefix
    if prefix is not None and not prefix.startswith('/'):
        raise BadArgument(f'--topic-prefix {prefix}: must start with /')
    name = namespace.strip('/').replace('/', '_') or 'root'
    path = write_layout(args.which, args.output or Path(f'{args.which}_{name}.json'),
                        namespace, prefix)
    print(f'wrote {path}: topics under {prefix or namespace_prefix(namespace)}, statuses of '
          f'the nodes in {namespace}')
    return 0
