"""
Output files written whole or not at all, and the figures and tables of the reports.

Each file is written under a ``.partial`` name and renamed when complete: a
reader, or a run that follows an interrupted one, never finds half a file
under the real name.
"""

from contextlib import contextmanager
from pathlib import Path
from typing import Iterable, Iterator, List, Sequence

#: Resolution of every figure (dots per inch).
FIGURE_DPI = 110


def partial(path: Path) -> Path:
    """Return the name ``path`` is written under until it is complete."""
    return path.with_name(path.name + '.partial')


@contextmanager
def atomic(path: Path) -> Iterator[Path]:
    """Yield the partial name to write ``path`` under; rename it to ``path`` when done."""
    tmp = partial(path)
    tmp.unlink(missing_ok=True)         # left by an interrupted run
    yield tmp
    tmp.replace(path)


def write_text(path: Path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically; return the path."""
    with atomic(path) as tmp:
        tmp.write_text(text)
    return path


def pyplot():
    """
    Return ``matplotlib.pyplot`` on the file-only Agg backend (the one set-up of every plot).

    Imported on first use: matplotlib costs a second of start-up that a
    command without plots should not pay; Agg needs no display (servers, CI).
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path: Path) -> Path:
    """Lay out a matplotlib figure, save it as the PNG ``path`` atomically, close it."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    with atomic(path) as tmp:
        fig.savefig(tmp, dpi=FIGURE_DPI, format='png')   # the format: not in the partial name
    plt.close(fig)
    return path


def markdown_table(header: Sequence[str], rows: Iterable[Sequence[object]]) -> List[str]:
    """Return the lines of a Markdown table: the header, its rule, one line per row."""
    def line(cells: Sequence[object]) -> str:
        return '| ' + ' | '.join(str(cell) for cell in cells) + ' |'

    return [line(header), line(['---'] * len(header))] + [line(row) for row in rows]
