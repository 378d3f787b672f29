"""compare's tables are built once as data (tracker.app.report_tables) and written twice: as Markdown (table.md)
and as HTML (report.html); both show the same cells, and the page colours the cells the data marks."""
from html.parser import HTMLParser
from pathlib import Path
from types import SimpleNamespace

import pytest

from tracker.app.report import PRIMARY, markdown, write_report
from tracker.app.report_html import tables_html
from tracker.app.report_tables import BEST, BETTER, UNMARKED, WORSE, Cell, Code, Report, Table, cell_marks


class _Tables(HTMLParser):
    """The tables of a piece of HTML: per table, its header texts and its body rows of (class, text) cells."""

    def __init__(self, page: str):
        super().__init__()
        self.tables: list[dict] = []
        self._cell: list[str] | None = None
        self.feed(page)

    def handle_starttag(self, tag, attrs):
        if tag == "table":
            self.tables.append({"header": [], "rows": []})
        elif tag == "tr" and self.tables and self.tables[-1]["header"]:  # a body row (the header comes first)
            self.tables[-1]["rows"].append([])
        elif tag in ("th", "td"):
            self._cell = [tag, dict(attrs).get("class", ""), ""]

    def handle_data(self, data):
        if self._cell is not None:
            self._cell[2] += data

    def handle_endtag(self, tag):
        if tag in ("th", "td") and self._cell is not None:
            kind, css, text = self._cell
            if kind == "th":
                self.tables[-1]["header"].append(text)
            else:
                self.tables[-1]["rows"][-1].append((css, text))
            self._cell = None


def _markdown_tables(text: str) -> list[list[list[str]]]:
    """The tables of ``table.md``'s text: per table, its lines (header first) as lists of cell texts."""
    tables, previous = [], ""
    for line in text.splitlines():
        if line.startswith("|") and not line.startswith("|---"):
            if not previous.startswith("|"):
                tables.append([])
            tables[-1].append(line[2:-2].split(" | "))
        previous = line
    return tables


def _sample() -> Report:
    errors = Table("mpjpe_abs: error (mm)", ("prior", "walk", "kick", "s/frame"), (
        (Cell("zv"), Cell("30.0 ± 1.0", mean=30.04), Cell("n/a"), Cell("0.100")),
        (Cell("crbm & <b>"), Cell("30.0 ± 2.0", mean=29.96), Cell("50.0 ± 1.0", mean=50.0), Cell("0.200")),
        (Cell("gpdm"), Cell("41.5 ± 0.5", mean=41.5), Cell("49.9 ± 3.0", mean=49.9), Cell("0.300"))))
    pck = Table("pck_abs: 3DPCK (%)", ("prior", "walk", "s/frame"), (
        (Cell("zv"), Cell("90.0 ± 1.0", mean=90.0), Cell("0.100")),
        (Cell("crbm & <b>"), Cell("95.0 ± 1.0", mean=95.0), Cell("0.200"))), higher_is_better=True)
    paired = Table("Paired difference to zv", ("prior", "compared with", "walk", "kick"), (
        (Cell("crbm & <b>"), Cell("zv"), Cell("-4.0 [-6.0, -2.0]", interval=(-6.0, -2.0)), Cell("+1.0")),
        (Cell("gpdm"), Cell("zv"), Cell("+3.0 [+1.0, +5.0]", interval=(1.0, 5.0)),
         Cell("-0.0 [-3.0, -0.0]", interval=(-3.0, -0.04)))))
    note = ("As ", Code("compare-trc"), " prints it.")
    spread = Table("spread (mm)", ("prior", "walk"), ((Cell("zv"), Cell("12.3")), (Cell("gpdm"), Cell("n/a"))),
                   notes=(note,))
    return Report("tiny", ((Code("exp.toml"), ": 2 seed(s)"),), (errors, pck, paired, spread))


def test_marks_rank_the_means_as_shown_and_paired_intervals_that_exclude_zero():
    errors, pck, paired, spread = _sample().tables
    # 30.04 and 29.96 both read 30.0: both best; n/a and times are not ranked; one ranked cell is not marked.
    assert cell_marks(errors) == [["", BEST, "", ""], ["", BEST, "", ""], ["", "", BEST, ""]]
    assert cell_marks(pck) == [["", "", ""], ["", BEST, ""]]  # the highest is the best
    # below zero better, above worse; an interval that reads -0.0 at its top does not exclude zero
    assert cell_marks(paired) == [["", "", BETTER, UNMARKED], ["", "", WORSE, UNMARKED]]
    assert cell_marks(spread) == [["", ""], ["", ""]]


def test_markdown_writer_pins_table_md():
    assert markdown(_sample()) == """# tiny

`exp.toml`: 2 seed(s)

## mpjpe_abs: error (mm)

| prior | walk | kick | s/frame |
|---|---|---|---|
| zv | 30.0 ± 1.0 | n/a | 0.100 |
| crbm & <b> | 30.0 ± 2.0 | 50.0 ± 1.0 | 0.200 |
| gpdm | 41.5 ± 0.5 | 49.9 ± 3.0 | 0.300 |

## pck_abs: 3DPCK (%)

| prior | walk | s/frame |
|---|---|---|
| zv | 90.0 ± 1.0 | 0.100 |
| crbm & <b> | 95.0 ± 1.0 | 0.200 |

## Paired difference to zv

| prior | compared with | walk | kick |
|---|---|---|---|
| crbm & <b> | zv | -4.0 [-6.0, -2.0] | +1.0 |
| gpdm | zv | +3.0 [+1.0, +5.0] | -0.0 [-3.0, -0.0] |

## spread (mm)

As `compare-trc` prints it.

| prior | walk |
|---|---|
| zv | 12.3 |
| gpdm | n/a |
"""


def _same_in_both(report: Report, text: str) -> None:
    """Every table of ``report`` shows the same header and cells in the Markdown ``text`` and in the HTML that
    :func:`tables_html` writes, the HTML's cell classes being the data's marks."""
    taken: set[str] = set()
    intro, body, links = tables_html(report, taken)
    assert [title for _, title in links] == [t.title for t in report.tables] and len(taken) == len(links)
    html_tables, md_tables = _Tables(body).tables, _markdown_tables(text)
    assert len(html_tables) == len(md_tables) == len(report.tables)
    for table, shown, md in zip(report.tables, html_tables, md_tables):
        assert shown["header"] == md[0] == list(table.header)
        assert [[t for _, t in row] for row in shown["rows"]] == md[1:] == [[c.text for c in r] for r in table.rows]
        assert [[css for css, _ in row] for row in shown["rows"]] == cell_marks(table)


def test_the_html_writer_shows_the_markdown_writers_cells_with_the_datas_marks():
    report = _sample()
    _same_in_both(report, markdown(report))
    intro, body, _ = tables_html(report, set())
    assert intro == "<p><code>exp.toml</code>: 2 seed(s)</p>\n"
    assert '<p class="note">As <code>compare-trc</code> prints it.</p>' in body
    assert "<td>crbm &amp; &lt;b&gt;</td>" in body  # a label is text, escaped
    assert '<td class="best">30.0 ± 1.0</td>' in body and '<td class="worse">+3.0 [+1.0, +5.0]</td>' in body


def _result(sequence: str, row: str, seed: int, error: float, views=(0, 1)) -> dict:
    """A run's ``result.json`` content as the report reads it."""
    return {"metrics": {PRIMARY: {"per_frame": [error - 1.0, error, error + 1.0]},
                        "pck_abs": {"per_frame": [100.0 - error, 100.0 - error, 100.0 - error]}},
            "tracked_frames": [2, 3, 4], "seconds_per_frame": 0.1, "wall_seconds": 1.0,
            "run": {"sequence": sequence, "row": row, "seed_index": seed, "key": f"{sequence}{row}{seed}{views}",
                    "views": list(views)}}


@pytest.mark.parametrize("paired", ["baseline", "all"])
def test_write_report_writes_its_tables_data_as_table_md(tmp_path: Path, paired: str):
    priors = [SimpleNamespace(label=label, replicate_of=None) for label in ("zv", "crbm", "gpdm")]
    exp = SimpleNamespace(path=tmp_path / "exp.toml", description="", seeds=2, seed=7, priors=priors,
                          paired=paired, baseline="zv")
    results = [_result(seq, row + name, i, base + shift + 3.0 * i + 10.0 * k)
               for seq, base in (("walk", 30.0), ("kick", 60.0))
               for name, views, shift in (("", (0, 1), 0.0), (", views 0", (0,), 20.0))
               for k, row in enumerate(("zv", "crbm", "gpdm")) for i in range(2)]
    meta = {"runs": len(results), "ran_now": 0, "jobs": 1, "backend": "joblib", "wall_seconds_now": 0.0,
            "version": "0"}
    summary = write_report(exp, results, tmp_path, meta)
    report = summary["report"]
    text = (tmp_path / "table.md").read_text(encoding="utf-8")
    assert text == summary["table"] and text.startswith(markdown(report)) and summary["tables"] == markdown(report)
    _same_in_both(report, text)
    marks = {t.title.split(":")[0]: cell_marks(t) for t in report.tables}
    assert marks[PRIMARY][0][1:3] == [BEST, BEST] and marks["pck_abs"][0][1:3] == [BEST, BEST]  # zv: lowest error
    paired_marks = [m for title, m in marks.items() if title.startswith("Paired")][0]
    assert {mark for row in paired_marks for mark in row[2:]} == {WORSE}  # every other row is worse by 10 or 20
