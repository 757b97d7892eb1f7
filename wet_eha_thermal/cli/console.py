"""What the commands show on the console besides their results: progress, validity flags."""

import sys
import time
from typing import Iterable


class Progress:
    """Progress on stderr: one updating line on a terminal, a line per step otherwise."""

    def __init__(self, stream=None) -> None:
        self.stream = stream if stream is not None else sys.stderr
        self.tty = self.stream.isatty()
        self.t0 = time.monotonic()

    def __call__(self, done: int, total: int, label: str) -> None:
        """Report that ``done`` of ``total`` items are finished; ``label`` names the next."""
        pct = 100.0 * done / max(total, 1)
        bar = '#' * int(pct / 5)
        text = (f'[{bar:<20}] {done}/{total} {pct:3.0f}% {time.monotonic() - self.t0:5.1f}s '
                f'{label}')
        if self.tty:
            end = '\n' if done >= total else ''
            self.stream.write('\r' + text.ljust(100) + end)
        else:
            self.stream.write(text + '\n')
        self.stream.flush()


def print_validity(flags: Iterable) -> None:
    """Print the correlations used outside their validated range, if any."""
    flags = list(flags)
    if flags:
        print('\nCorrelations used outside their validated range:')
        for flag in flags:
            print(f'  - {flag}')
