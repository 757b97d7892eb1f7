"""
Command-line entry point: ``wet-eha-thermal <command> ...``.

One module per command, each with ``HELP`` (its line in the command list),
``DESCRIPTION`` (its ``--help`` text), ``add_arguments(parser)`` and
``run(args)`` returning the exit status; ``play`` hands its arguments to the
player's own parser (``OWN_PARSER``, ``main(argv)``). To add a command, write
its module and add its name to :data:`COMMANDS`. A module imports what its
command calls inside ``add_arguments`` and ``run``: only the command that runs
pays for its imports, and its options' defaults are read from what it calls.

Every command reports bad input as one line on stderr (``error: ...``) and
exits with status 2, without a traceback; nothing runs after a bad config.
"""

import importlib
import sys
from typing import List, Optional

from .arguments import BadArgument, Parser
from ..config import ConfigError
from ..model.duty import DutyError

#: The commands, in the order ``--help`` lists them: each is the module ``cli/<name>.py``.
COMMANDS = ('maps', 'sensitivity', 'simulate', 'live', 'layout', 'replay', 'calibrate', 'whatif',
            'play')


def command(name: str):
    """Return the module of the command ``name``."""
    return importlib.import_module(f'{__name__}.{name}')


def build_parser(only: Optional[str] = None) -> Parser:
    """Return the parser of all commands; with ``only``, only that one's options are added."""
    parser = Parser(prog='wet-eha-thermal',
                    description='Thermal digital twin of a wet electro-hydrostatic actuator.')
    sub = parser.add_subparsers(dest='command', required=True)
    for name in COMMANDS:
        module = command(name)
        own = getattr(module, 'OWN_PARSER', False)
        p = sub.add_parser(name, help=module.HELP, description=module.DESCRIPTION,
                           add_help=not own)
        if not own and only in (None, name):
            module.add_arguments(p)
            p.set_defaults(run=module.run)
    return parser


def main(argv: Optional[List[str]] = None) -> int:
    """Run the command line; return the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    name = argv[0] if argv and argv[0] in COMMANDS else ''
    if name and getattr(command(name), 'OWN_PARSER', False):
        return command(name).main(argv[1:])
    try:
        args = build_parser(only=name).parse_args(argv)
        args.argv = argv
        return args.run(args)
    except (BadArgument, ConfigError, DutyError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print('interrupted', file=sys.stderr)
        return 130
