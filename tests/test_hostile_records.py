"""Stored results are re-validated on read. A case file's checksum is an integrity check,
not a signature: one who recomputes it can write anything. So every field a study, a PMD
study or a sweep reads back is checked against its column's declared type, range and
words; a file that fails is measured again with one warning line, exactly as one with a
bad checksum, and never reaches the table or the report. Text that does pass (a status
reason with ``<`` or ``|``) is escaped where it enters a Markdown report.

The records are real: the shipped study's rows (``docs/paper_study``), written as case
files by glshade's own writers, then forged; the end-to-end runs are 32² (about 2 s each).
"""

from __future__ import annotations

import csv
import io
import json
import shutil
from pathlib import Path

import pytest

from glshade.app.cli import main
from glshade.errors import GlshadeError
from glshade.instruments.record import Measurement, PmdMeasurement
from glshade.measure.case_files import Rejected, case_file_bytes
from glshade.study import pmd_store, store
from glshade.study.escape import markdown_text
from glshade.sweep import store as sweep_store

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "docs" / "paper_study"
CASE = "flat_theta45_sigma2_4_dmax5um"

#: The reproductions: (study kind, field, forged value, the warning's reason).
STATUSES = "ok, outside, edge, unresolved, saturated, underexposed, noise"
FORGED = [
    ("pmd", "status", "bogus", f"holds 'bogus' as status, not one of {STATUSES}"),
    ("pmd", "pmd_shift_mm", float("inf"), "holds inf as pmd_shift_mm, not a finite number"),
    ("pmd", "valid_fraction", 1e308, "holds 1e+308 as valid_fraction, outside 0 to 1"),
    (
        "pmd",
        "status_reason",
        "edge\n<script>alert(1)</script> | [x](http://e)",
        "holds the control character U+000A in status_reason",
    ),
    (
        "pmd",
        "unwrap_failures",
        2**63,
        "holds 9223372036854775808 as unwrap_failures, outside 0 to 2147483647",
    ),
    ("paper", "visibility_px", 1e308, "holds 1e+308 as visibility_px, outside 0 to 1e+06"),
    ("paper", "deflection_px", float("nan"), "holds nan as deflection_px, not a finite number"),
    ("paper", "islands", -1, "holds -1 as islands, outside 0 to 2147483647"),
    ("paper", "status_reason", "x" * 5000,
     "holds 5000 characters as status_reason, more than 4096"),
    ("paper", "status_reason", "a\u202eb",
     "holds the control character U+202E in status_reason"),
    ("pmd", "pmd_shift_law_status", "fine",
     "holds 'fine' as pmd_shift_law_status, not one of ok, grazing"),
]  # fmt: skip


IDS = [f"{kind}-{name}-{index}" for index, (kind, name, _, _) in enumerate(FORGED)]


def shipped_row(kind: str):
    """The shipped study's row of :data:`CASE`: a real record of each kind."""
    if kind == "pmd":
        rows = pmd_store.read_results_csv(STUDY / "pmd_results.csv")
    else:
        rows = store.read_results_csv(STUDY / "results.csv")
    return next(row for row in rows if store.case_key(*row.case) == CASE)


def measured_table(path: Path) -> list[dict[str, str]]:
    """A study's table without its timings (seconds differ from run to run)."""
    rows = list(csv.DictReader(io.StringIO(path.read_text(), newline="")))
    return [{k: v for k, v in row.items() if not k.endswith("_s")} for row in rows]


def forge(path: Path, change) -> None:
    """Rewrite the case file at ``path`` with ``change(content)`` applied and its
    checksum recomputed: what one who knows the format can do."""
    content = json.loads(path.read_text())
    content.pop("checksum")
    case_id = content.pop("case_id")
    change(content)
    path.write_bytes(case_file_bytes(case_id, content))


def one_warning(rejected: Rejected, name: str, reason: str) -> None:
    assert rejected.line() == (
        f"1 case file could not be trusted and is measured again: {name}.json {reason}"
    )


# --------------------------------------------------------------------------- each store
@pytest.mark.parametrize(("kind", "name", "value", "reason"), FORGED, ids=IDS)
def test_a_forged_study_case_file_is_rejected_with_its_reason(tmp_path, kind, name, value, reason):
    row = shipped_row(kind)
    layout = pmd_store.PMD_LAYOUT if kind == "pmd" else store.STRIPES
    (tmp_path / layout.cases).mkdir()
    store.write_case(tmp_path, row, None, layout)
    path = tmp_path / layout.cases / f"{CASE}.json"
    finished = pmd_store.finished if kind == "pmd" else store.finished
    assert finished(tmp_path, [CASE]) == {CASE: row}  # the honest file reads back as it was

    forge(path, lambda content: content.update({name: value}))
    rejected = Rejected()
    assert finished(tmp_path, [CASE], rejected) == {}
    one_warning(rejected, CASE, reason)


@pytest.mark.parametrize(("kind", "name", "value", "reason"), FORGED, ids=IDS)
def test_a_forged_sweep_case_file_is_rejected_with_its_reason(tmp_path, kind, name, value, reason):
    record_class = PmdMeasurement if kind == "pmd" else Measurement
    record = record_class.from_row(dict(shipped_row(kind)))
    (tmp_path / "cases").mkdir()
    sweep_store.write_case(tmp_path, "0123456789abcdef", record)
    assert sweep_store.finished(tmp_path, ["0123456789abcdef"], kind) == {
        "0123456789abcdef": record
    }

    path = tmp_path / "cases" / "0123456789abcdef.json"
    forge(path, lambda content: content["outputs"].update({name: value}))
    rejected = Rejected()
    assert sweep_store.finished(tmp_path, ["0123456789abcdef"], kind, rejected) == {}
    one_warning(rejected, "0123456789abcdef", reason)


def test_a_forged_timing_and_case_point_are_rejected_too(tmp_path):
    row = shipped_row("paper")
    (tmp_path / "cases").mkdir()
    path = tmp_path / "cases" / f"{CASE}.json"
    for name, value, reason in (
        ("trace_s", -1.0, "holds -1.0 as trace_s, outside 0 to 1e+07"),
        ("theta_deg", float("-inf"), "holds -inf as theta_deg, not a finite number"),
        ("surface", "flat\x1b[2J", "holds the control character U+001B in surface"),
    ):
        store.write_case(tmp_path, row, None)
        forge(path, lambda content: content.update({name: value}))  # noqa: B023
        rejected = Rejected()
        assert store.finished(tmp_path, [CASE], rejected) == {}
        one_warning(rejected, CASE, reason)


def test_every_row_of_the_shipped_study_passes_the_check():
    """The check refuses nothing glshade writes: the whole paper study, both instruments
    (432 real records, every status and law status they reached)."""
    paper = store.read_results_csv(STUDY / "results.csv")
    pmd = pmd_store.read_results_csv(STUDY / "pmd_results.csv")
    assert len(paper) == len(pmd) == 216
    assert {r.status for r in paper} == {"ok", "unresolved"}
    assert {r.pmd_shift_law_status for r in pmd} == {"ok", "grazing"}
    for row in [*paper, *pmd]:
        assert type(row).json_problem(json.loads(json.dumps(dict(row)))) is None


# --------------------------------------------------------------------------- tables
def edited_table(source: Path, target: Path, row: int, **values: str) -> None:
    """``source`` copied to ``target`` with cells of data row ``row`` (1 = the first)
    replaced, as CSV writes them."""
    records = list(csv.DictReader(io.StringIO(source.read_text(), newline="")))
    records[row - 1].update(values)
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(records[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(records)
    target.write_text(buffer.getvalue())


@pytest.mark.parametrize(
    ("values", "reason"),
    [
        ({"status": "bogus"}, f"holds 'bogus' as status, not one of {STATUSES}"),
        ({"visibility_px": "inf"}, "holds inf as visibility_px, not a finite number"),
        ({"islands": "9" * 30}, "holds 999999999999999999999999999999 as islands, outside"),
        ({"islands": "two"}, "holds a value that is not its column's type"),
        ({"status_reason": "a\nb"}, "holds the control character U+000A in status_reason"),
    ],
)
def test_a_forged_results_table_is_one_line(tmp_path, values, reason):
    """``results.csv`` has no checksum; the PMD study and ``--rewrite`` read it: each row
    is checked as a case file is, and a bad one is one line naming it."""
    edited_table(STUDY / "results.csv", tmp_path / "results.csv", 3, **values)
    with pytest.raises(GlshadeError) as caught:
        store.read_results_csv(tmp_path / "results.csv")
    text = str(caught.value)
    assert "\n" not in text
    assert text.startswith(f"results table {tmp_path / 'results.csv'}: row 3 {reason}")
    assert text.endswith(
        "rerun the study that wrote it, with this --out, to rebuild it from its case files"
    )


def test_a_table_without_a_column_is_one_line(tmp_path):
    lines = (STUDY / "results.csv").read_text().splitlines()
    header = lines[0].split(",")
    at = header.index("status")
    kept = [
        ",".join(c for i, c in enumerate(next(csv.reader([line]))) if i != at) for line in lines
    ]
    (tmp_path / "results.csv").write_text("\n".join(kept) + "\n")
    with pytest.raises(GlshadeError, match=r"row 1 lacks the column 'status'; rerun"):
        store.read_results_csv(tmp_path / "results.csv")


# --------------------------------------------------------------------------- reports
HOSTILE = "dent <img src=x onerror=alert(1)> | [click](http://evil) `code` & \\| more"
ESCAPED = (
    "dent &lt;img src=x onerror=alert(1)&gt; \\| \\[click\\](http://evil) \\`code\\` &amp; "
    "\\\\\\| more"
)


def test_markdown_text_escapes_markup_and_keeps_words():
    assert markdown_text(HOSTILE) == ESCAPED
    assert markdown_text("one\ntwo\r\nthree\u2028four\x1b[31m") == "one two  three four \\[31m"
    assert markdown_text('the 10 mm stripes span 3.3 px (emitter.period = "auto")') == (
        'the 10 mm stripes span 3.3 px (emitter.period = "auto")'
    )


def test_a_stored_reason_with_markup_is_escaped_in_both_reports(tmp_path):
    """A reason that is valid text but holds markup (no control character: it passes the
    check) enters ``report.md`` and ``pmd_report.md`` escaped, never verbatim."""
    from glshade.study import findings, pmd_findings
    from glshade.study.rewrite import stored_plan, stored_pmd_plan

    for name in ("study.json", "pmd_study.json"):
        shutil.copy(STUDY / name, tmp_path / name)
    edited_table(STUDY / "results.csv", tmp_path / "results.csv", 1,
                 status="saturated", status_reason=HOSTILE)  # fmt: skip
    edited_table(STUDY / "pmd_results.csv", tmp_path / "pmd_results.csv", 1,
                 status="saturated", status_reason=HOSTILE)  # fmt: skip
    paper = store.read_results_csv(tmp_path / "results.csv")
    pmd = pmd_store.read_results_csv(tmp_path / "pmd_results.csv")
    assert paper[0].status_reason == pmd[0].status_reason == HOSTILE

    report = findings.write_report(paper, tmp_path, stored_plan(tmp_path), []).read_text()
    pmd_report = pmd_findings.write_pmd_report(
        pmd, paper, tmp_path, stored_pmd_plan(tmp_path), [], 1024
    ).read_text()
    for text in (report, pmd_report):
        assert HOSTILE not in text and "<img" not in text and "[click]" not in text
    assert f"image saturated (1; {ESCAPED})" in report
    assert pmd_report.count(f"image saturated (1; {ESCAPED})") == 2  # PMD's and the stripes'


# --------------------------------------------------------------------------- runs
PMD_SWEEP = 'base = "pmd_station.toml"\nsize = 32\n[grid]\n"camera.theta_deg" = [45]\n'


@pytest.fixture(scope="module")
def measured_sweep(tmp_path_factory, _session_renderer):
    """A one-case PMD sweep at 32², measured once: (its folder, its table, the case id)."""
    folder = tmp_path_factory.mktemp("sweep")
    shutil.copy(ROOT / "examples" / "pmd_station.toml", folder)
    (folder / "s.toml").write_text(PMD_SWEEP)
    assert (
        main(["sweep", str(folder / "s.toml"), "--out", str(folder / "out"), "--no-progress"]) == 0
    )
    (case,) = (folder / "out" / "cases").glob("*.json")
    return folder, (folder / "out" / "results.csv").read_text(), case.stem


@pytest.mark.parametrize(
    ("kind", "name", "value", "reason"),
    [f for f in FORGED if f[0] == "pmd"],
    ids=[i for f, i in zip(FORGED, IDS, strict=True) if f[0] == "pmd"],
)
def test_a_forged_sweep_case_is_measured_again_with_one_warning(
    measured_sweep, tmp_path, capsys, kind, name, value, reason
):
    """Each reproduction, forged with its checksum recomputed, in a PMD sweep: the rerun
    says one line, measures the case again and writes the table it wrote the first time
    (``unwrap_failures = 2**63`` ended every rerun in an OverflowError)."""
    source, table, case_id = measured_sweep
    shutil.copytree(source, tmp_path / "run")
    out = tmp_path / "run" / "out"
    forge(out / "cases" / f"{case_id}.json", lambda c: c["outputs"].update({name: value}))
    capsys.readouterr()
    code = main(["sweep", str(tmp_path / "run" / "s.toml"), "--out", str(out), "--no-progress"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert captured.err.splitlines() == [
        "glshade: warning: 1 case file could not be trusted and is measured again: "
        f"{case_id}.json {reason}"
    ]
    assert "(1 measured, 0 already done)" in captured.out
    assert (out / "results.csv").read_text() == table
    assert case_id in sweep_store.finished(out, [case_id], "pmd")  # written anew, trusted


def test_a_forged_pmd_study_case_never_reaches_the_report(tmp_path, capsys, _session_renderer):
    """The PMD study, its report included: a reason with a line break and HTML, forged
    with its checksum recomputed, is measured again and appears nowhere."""
    argv = ["paper", "--method", "pmd", "--surfaces", "flat", "--thetas", "45", "--sigma2s",
            "4", "--dmaxs", "5um", "--size", "32", "--workers", "0", "--no-progress",
            "--out", str(tmp_path / "study")]  # fmt: skip
    assert main(argv) == 0
    table = measured_table(tmp_path / "study" / "pmd_results.csv")
    path = tmp_path / "study" / "pmd_cases" / f"{CASE}.json"
    forged = "edge\n<script>alert(1)</script>"
    forge(path, lambda content: content.update(status="edge", status_reason=forged))
    capsys.readouterr()
    assert main(argv) == 0
    captured = capsys.readouterr()
    assert captured.err.splitlines() == [
        "glshade: warning: 1 case file could not be trusted and is measured again: "
        f"{CASE}.json holds the control character U+000A in status_reason"
    ]
    assert "1 PMD cases computed, 0 resumed" in captured.out
    assert measured_table(tmp_path / "study" / "pmd_results.csv") == table
    for name in ("pmd_results.csv", "pmd_report.md", "report.md", "results.csv"):
        assert "<script>" not in (tmp_path / "study" / name).read_text()


@pytest.mark.parametrize(
    "column, forged, said",
    [
        ("status", "bogus", "unknown status 'bogus'"),
        ("variant", "<b>x</b>", "unknown variant"),
        ("status_reason", "two\nlines <script>", "not one line of text"),
        ("visibility_px", "Infinity", "is not a finite number"),
        ("theta_deg", "forty", "is not a number"),
    ],
)
def test_a_forged_finding3_row_is_one_line_before_the_report(tmp_path, column, forged, said):
    """``finding3.csv`` enters the study's report: the shipped table reads back whole, a
    row with a forged field is refused naming the row, never copied into Markdown."""
    from glshade.study.finding3 import read_rows, report_section

    shipped = ROOT / "docs" / "paper_study" / "finding3.csv"
    rows = list(csv.DictReader(io.StringIO(shipped.read_text())))
    assert len(read_rows(shipped)) == len(rows) > 0
    rows[3][column] = forged
    text = io.StringIO()
    writer = csv.DictWriter(text, list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
    (tmp_path / "finding3.csv").write_text(text.getvalue())
    with pytest.raises(GlshadeError, match=rf"finding3.csv: row 5: .*{said}"):
        report_section(tmp_path)
