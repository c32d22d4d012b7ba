"""
Console output drawn by rich: aligned tables, and a progress bar redrawn in place.

Tables are plain text (no colour, no box-drawing characters): columns two spaces apart under
a header and a rule of ``-``, trailing spaces dropped, as they read in a terminal, a CI log or a
file alike. A :class:`ProgressBar` draws on a terminal only; elsewhere it draws nothing and
its lines are printed as plain lines.
"""

from collections.abc import Iterable, Sequence
import io
from typing import TextIO

from rich.box import Box
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn
from rich.table import Table

#: A table's frame: a rule of '-' under the header, nothing else.
_HEADER_RULE = Box('    \n    \n----\n    \n    \n    \n    \n    \n', ascii=True)
#: Characters a table line may take: wide enough that no cell is wrapped or cut.
_TABLE_WIDTH = 10_000


def text_table(header: Sequence[str], rows: Iterable[Sequence[str]],
               right: Sequence[int] = ()) -> str:
    """Return ``rows`` under ``header`` as aligned plain text; columns ``right`` right-aligned."""
    table = Table(*header, box=_HEADER_RULE, show_edge=False, pad_edge=False,
                  padding=(0, 1), collapse_padding=True, show_header=bool(header))
    for column in right:
        table.columns[column].justify = 'right'
    for row in rows:
        table.add_row(*row)
    text = io.StringIO()
    Console(file=text, width=_TABLE_WIDTH, color_system=None, force_terminal=False,
            highlight=False, markup=False, emoji=False).print(table)
    return '\n'.join(line.rstrip() for line in text.getvalue().splitlines())


class ProgressBar:
    """
    One progress bar on ``stream`` (a terminal, and ``draw``; else none is drawn), lines above.

    :meth:`update` sets the share done (0 to 1) and the text after the bar; :meth:`write_line`
    prints a line above it (on any stream); :meth:`close` removes the bar.
    """

    def __init__(self, stream: TextIO, draw: bool = True) -> None:
        self.console = Console(file=stream, highlight=False, markup=False, emoji=False)
        self.live = draw and self.console.is_terminal
        # Redrawn when told (no thread), and sys.stdout and sys.stderr left as they are.
        self.progress = Progress(BarColumn(), TextColumn('{task.fields[status]}'),
                                 console=self.console, transient=True, auto_refresh=False,
                                 redirect_stdout=False, redirect_stderr=False)
        self.task = self.progress.add_task('', total=1.0, status='', visible=self.live)
        if self.live:
            self.progress.start()

    def update(self, share: float, status: str) -> None:
        """Show ``share`` (0 to 1) of the work done, ``status`` after the bar."""
        if self.live:
            self.progress.update(self.task, completed=min(max(share, 0.0), 1.0), status=status)
            self.progress.refresh()

    def write_line(self, line: str) -> None:
        """Print ``line`` above the bar, as it is (no markup)."""
        self.console.print(line, soft_wrap=True)

    def close(self) -> None:
        """Remove the bar (the lines printed stay)."""
        if self.live:
            self.progress.stop()
            self.live = False
