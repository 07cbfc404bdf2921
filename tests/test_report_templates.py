"""The studies' reports are their numbers worded by templates: the stored reports in
``docs/paper_study`` come back byte for byte from the stored tables (``results.csv``,
``pmd_results.csv``, ``finding3.csv``), and each verdict's words are the template's.
(``test_report_layers.py``: the analysis never loads Jinja.)"""

from __future__ import annotations

import re
import shutil
from pathlib import Path
from types import SimpleNamespace

import pytest

from glshade.study import finding3, findings, pmd_findings, pmd_store, store
from glshade.study.rewrite import rewrite, stored_plan, stored_pmd_plan

STUDY = Path(__file__).resolve().parents[1] / "docs" / "paper_study"


def _figures(text: str, out: Path) -> list[Path]:
    """The figures a stored report shows, in its order (``![stem](name)`` lines)."""
    return [out / name for name in re.findall(r"^!\[[^\]]*\]\(([^)]+)\)$", text, re.M)]


def test_the_stored_study_report_comes_back_byte_for_byte(tmp_path):
    stored = (STUDY / "report.md").read_text(encoding="utf-8")
    shutil.copy(STUDY / "finding3.csv", tmp_path)  # the report quotes it
    stages = ("trace", "shade", "contours", "continuous numbers", "I/O", "figures")
    found = re.search(
        r"^" + r", ".join(rf"{re.escape(s)} ([\d.]+) s" for s in stages), stored, re.M
    )
    assert found, "the stored report states its run's timings"
    timings = SimpleNamespace(
        **dict(
            zip(
                ("trace", "shade", "contours", "continuous", "io", "figures"),
                map(float, found.groups()),
                strict=True,
            )
        )
    )
    rows = store.read_results_csv(STUDY / "results.csv")
    path = findings.write_report(
        rows, tmp_path, stored_plan(STUDY), _figures(stored, tmp_path), timings
    )
    assert path.read_bytes() == (STUDY / "report.md").read_bytes()


def test_the_stored_pmd_report_comes_back_byte_for_byte(tmp_path):
    stored = (STUDY / "pmd_report.md").read_text(encoding="utf-8")
    found = re.search(r"This run spent (\d+) s measuring \((\d+) cases\)", stored)
    assert found, "the stored report states what its run spent"
    path = pmd_findings.write_pmd_report(
        pmd_store.read_results_csv(STUDY / "pmd_results.csv"),
        store.read_results_csv(STUDY / "results.csv"),
        tmp_path,
        stored_pmd_plan(STUDY),
        _figures(stored, tmp_path),
        stored_plan(STUDY).size,
        float(found[1]),
        int(found[2]),
    )
    assert path.read_bytes() == (STUDY / "pmd_report.md").read_bytes()


def test_the_stored_finding3_report_comes_back_byte_for_byte(tmp_path):
    stored = (STUDY / "finding3.md").read_text(encoding="utf-8")
    size = int(re.search(r"(\d+)² pixels", stored)[1])
    rows = finding3.read_rows(STUDY / "finding3.csv")
    present = {r["variant"] for r in rows}
    variants = [v for v in finding3.VARIANTS if v.key in present]
    path = finding3.write_report(rows, variants, size, tmp_path / "finding3.md")
    assert path.read_bytes() == (STUDY / "finding3.md").read_bytes()
    section = "\n".join(finding3.report_section(STUDY)) + "\n"
    assert section in (STUDY / "report.md").read_text(encoding="utf-8")


@pytest.mark.slow
def test_a_rewrite_of_the_stored_study_is_its_report_but_the_run_time(tmp_path):
    """``rewrite`` (the figures redrawn, nothing measured) writes the stored report but
    its last section, the run's timings, which only a run knows."""
    out = tmp_path / "study"
    shutil.copytree(STUDY, out)
    again = rewrite(out).read_text(encoding="utf-8")
    stored = (STUDY / "report.md").read_text(encoding="utf-8")
    assert "## Run time of this run" not in again
    head, _, tail = stored.partition("\n## Run time of this run\n")
    assert again == head and tail.count("\n") == 2


def test_every_verdict_is_worded_by_the_template():
    """The headline a verdict states is its template's wording of its numbers, and the
    numbers hold no words of the report."""
    rows = store.read_results_csv(STUDY / "results.csv")
    stated = findings.evaluate(rows)
    assert stated and len({v.finding for v in stated}) == 5
    for v in stated:
        assert v.text.startswith(v.verdict + ": ") and v.evidence
        assert "**" not in v.text + v.evidence and "|" not in v.text + v.evidence
        assert v.numbers.verdict == v.verdict
