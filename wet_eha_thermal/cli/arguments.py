"""
What the commands share on their command lines: the parser, validators and option groups.

A validator is an argparse ``type``: it converts the text and raises
:class:`argparse.ArgumentTypeError` naming the value and what is allowed;
:class:`Parser` reports that as one line, ``error: --option value: ...``.
Checks that need two options or the configuration stay with the command and
raise :class:`BadArgument`.
"""

import argparse
import contextlib
import inspect
import math
from pathlib import Path
import re
from typing import Any, Callable


class BadArgument(ValueError):
    """A command-line value that is out of range; the message names the option and value."""


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one :class:`BadArgument` line, not usage and exit."""

    def error(self, message: str):
        """Raise :class:`BadArgument`: ``argument --x: v: what`` becomes ``--x v: what``."""
        # argparse says 'argument --x: '; the commands' own checks say '--x value: ', so
        # every error of a command reads the same
        message = re.sub(r'^argument ([^:]+): ', r'\1 ', message)
        raise BadArgument(f'{message} (see {self.prog} --help)')


def default(callee: Callable, name: str) -> Any:
    """Return the default of parameter ``name`` of ``callee`` (a function or a dataclass)."""
    return inspect.signature(callee).parameters[name].default


def _number(text: str, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text}: not a number; {what}') from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f'{text}: {what}')
    return value


def positive(unit: str) -> Callable[[str], float]:
    """Return a validator of a finite number > 0 of ``unit`` (``'seconds'``, ``'Hz'``)."""
    def positive_number(text: str) -> float:
        value = _number(text, f'must be a number of {unit} > 0')
        if value <= 0.0:
            raise argparse.ArgumentTypeError(f'{text}: must be a number of {unit} > 0')
        return value
    return positive_number


def at_least(low: float, what: str, number=float) -> Callable[[str], float]:
    """Return a validator of a number (``number`` int or float) >= ``low``; ``what`` says why."""
    def bounded(text: str):
        try:
            value = number(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'{text}: not a number; must be at least '
                                             f'{low:g}{what}') from None
        if not (math.isfinite(value) and value >= low):
            raise argparse.ArgumentTypeError(f'{text}: must be at least {low:g}{what}')
        return value
    return bounded


def in_range(low: float, high: float, unit: str) -> Callable[[str], float]:
    """Return a validator of a number in ``low..high`` ``unit``."""
    def ranged(text: str) -> float:
        value = _number(text, f'must be {low:g}..{high:g} {unit}')
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f'{text}: must be {low:g}..{high:g} {unit}')
        return value
    return ranged


def stage(text: str) -> int:
    """Return a reference stage number (a key of :data:`~..model.duty.STAGES`)."""
    from ..model.duty import STAGES

    valid = ', '.join(str(k) for k in STAGES)
    try:
        number = int(text)
    except ValueError:
        number = None
    if number not in STAGES:
        raise argparse.ArgumentTypeError(f'{text}: unknown stage; valid stages: {valid}')
    return number


def existing(text: str) -> Path:
    """Return the path of a file or folder that exists."""
    path = Path(text)
    if not path.exists():
        raise argparse.ArgumentTypeError(f'{text}: not found')
    return path


def existing_file(text: str) -> Path:
    """Return the path of a file that exists."""
    path = existing(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f'{text}: is a folder, not a file')
    return path


def out_folder(text: str) -> Path:
    """Return the path of an output folder: absent (made later) or a folder."""
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f'{text}: exists and is not a folder')
    return path


def add_out(p: argparse.ArgumentParser, command: str) -> None:
    """Add ``--out``: the output folder, ``out/<command>`` by default."""
    p.add_argument('--out', type=out_folder, default=Path('out') / command,
                   help='output folder (default: %(default)s)')


def add_config(p: argparse.ArgumentParser, default_text: str = 'the reference rig') -> None:
    """Add ``--config``: a YAML configuration (load_config reports a missing or bad one)."""
    p.add_argument('--config', type=Path, default=None,
                   help=f'YAML configuration (default: {default_text})')


def add_duty_arguments(p: argparse.ArgumentParser, required: bool, default_stage: int = None):
    """Add the --stage | --duty choice, and return the group (others may join it)."""
    which = p.add_mutually_exclusive_group(required=required)
    which.add_argument('--stage', type=stage, default=None,
                       help='reference stage number (1-6)'
                       + ('' if default_stage is None else f'; default {default_stage}'))
    which.add_argument('--duty', type=existing_file, metavar='FILE.csv',
                       help='duty table: time_s, flow_L_min, load_MPa (repeats periodically)')
    return which


def add_dask_arguments(group, what: str) -> None:
    """Add --workers N | --scheduler ADDRESS: where ``what`` run on Dask."""
    group.add_argument('--workers', type=at_least(1, '', int), default=None, metavar='N',
                       help=f'run the {what} on a local Dask cluster of N processes (default '
                            'for a campaign: one per CPU)')
    group.add_argument('--scheduler', default=None, metavar='ADDRESS',
                       help=f'run the {what} on the Dask cluster of this scheduler, e.g. '
                            'tcp://host:8786 (its workers must see the same paths)')


@contextlib.contextmanager
def dask(args: argparse.Namespace):
    """Yield the Dask client of --scheduler, else of a local cluster of --workers processes."""
    from ..offline.campaign import ClusterError, dask_client

    try:
        with dask_client(args.scheduler, args.workers) as client:
            yield client
    except ClusterError as exc:
        raise BadArgument(str(exc)) from None
