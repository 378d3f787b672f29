"""The tables of ``compare``'s report as plain data, built once (:func:`tracker.app.report.write_report`) and
rendered by two writers: :func:`tracker.app.report.markdown` (``table.md``) and
:func:`tracker.app.report_html.tables_html` (``report.html``).

A :class:`Report` holds a title, an introduction and its :class:`Table` s; a table holds its title, the notes
above it, its header and its rows of :class:`Cell` s. A cell keeps the text it shows and the numbers behind it:
the mean a column of ``mean ± std`` cells is ranked by, or a paired difference's interval, which
:func:`cell_marks` turns into the marks the page colours (best of a column, better or worse than the compared
row). Text that is shown as code (a file name, a command) is a :class:`Code` part of a :data:`Text`.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Code:
    """A piece of text shown as code (a file or command name): ``text`` in backticks in Markdown, in
    ``<code>`` in HTML."""

    text: str


#: A line of text: plain parts (``str``) and :class:`Code` parts, in order.
Text = tuple[str | Code, ...]

#: The marks :func:`cell_marks` gives a cell: the best mean of its column, a paired difference whose interval lies
#: below zero (better than the compared row) or above zero (worse), or none.
BEST, BETTER, WORSE, UNMARKED = "best", "better", "worse", ""


@dataclass(frozen=True)
class Cell:
    """One cell of a table: the ``text`` shown, with ``digits`` decimals, and the numbers behind it.

    ``mean``: a mean over runs (or over models) that ranks the cell among the other cells of its column that have
    one (the best of them marked); ``interval``: the (low, high) bootstrap interval of a paired difference, which
    marks the cell better or worse where it excludes zero. Both are compared as the text shows them (rounded to
    ``digits``), so that cells that read the same are marked the same. A label, a count, a time or n/a has
    neither."""

    text: str
    mean: float | None = None
    interval: tuple[float, float] | None = None
    digits: int = 1

    def shown(self, value: float) -> float:
        """``value`` rounded as this cell's text shows it."""
        return float(f"{value:.{self.digits}f}")


@dataclass(frozen=True)
class Table:
    """One table under its own heading: ``title``, the ``notes`` (paragraphs) between the heading and the table,
    the column ``header`` and the ``rows`` (each as many cells as the header; the first column names the row and
    is never marked). ``higher_is_better``: which end of a column's means is the best (3DPCK: the highest; an
    error: the lowest)."""

    title: str
    header: tuple[str, ...]
    rows: tuple[tuple[Cell, ...], ...]
    notes: tuple[Text, ...] = ()
    higher_is_better: bool = False


@dataclass(frozen=True)
class Report:
    """An experiment's tables: the ``title`` (the description, or the experiment file's name), the
    ``intro`` (paragraphs before the first table) and the ``tables`` in the order shown."""

    title: str
    intro: tuple[Text, ...]
    tables: tuple[Table, ...]


def cell_marks(table: Table) -> list[list[str]]:
    """The mark of every body cell of ``table`` (:data:`BEST`, :data:`BETTER`, :data:`WORSE` or
    :data:`UNMARKED`), row by row: in each column but the first, the best ``mean`` where at least two cells have
    one (every cell that shows it, on a tie); a cell with an ``interval`` and no ``mean`` is better where its
    interval lies wholly below zero and worse where wholly above."""
    marks = [[UNMARKED for _ in row] for row in table.rows]
    for c in range(1, len(table.header)):
        column = [(i, row[c]) for i, row in enumerate(table.rows) if c < len(row)]
        means = {i: cell.shown(cell.mean) for i, cell in column if cell.mean is not None}
        if len(means) > 1:
            best = (max if table.higher_is_better else min)(means.values())
            for i, value in means.items():
                if value == best:
                    marks[i][c] = BEST
        for i, cell in column:
            if cell.interval is not None and cell.mean is None:
                lo, hi = (cell.shown(v) for v in cell.interval)
                marks[i][c] = BETTER if hi < 0 else WORSE if lo > 0 else UNMARKED
    return marks
