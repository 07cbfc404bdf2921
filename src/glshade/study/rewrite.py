"""A study's report and figures again, from what its directory keeps (``study.json`` and
``results.csv``), without measuring anything: the visibility plots, the laws against the
simulation and ``report.md``. The image grids are redrawn where the case thumbnails are
still in ``cases/``; otherwise the grids already there are kept, as are the Fig. 9
overlays (they need the case's images, so only a run draws them)."""

from __future__ import annotations

from pathlib import Path

from glshade.measure.store import read_manifest
from glshade.metrics.visibility import MetricSettings
from glshade.study import findings, plots
from glshade.study.plan import OVERLAY_CASES, StudyPlan
from glshade.study.store import STRIPES, read_results_csv


def stored_plan(out_dir: Path) -> StudyPlan:
    """The plan a study directory was run with (its ``study.json``)."""
    data = read_manifest(out_dir, STRIPES, "study")
    known = set(MetricSettings.__dataclass_fields__)
    metric = MetricSettings(**{k: v for k, v in data.get("metric", {}).items() if k in known})
    return StudyPlan(
        surfaces=tuple(data["surfaces"]),
        thetas=tuple(data["thetas"]),
        sigma2s=tuple(data["sigma2s"]),
        dmaxs=tuple(data["dmaxs"]),
        size=int(data["size"]),
        metric=metric,
    )


def rewrite(out_dir: Path) -> Path:
    """Redraw what the stored rows allow and write ``report.md``; returns its path."""
    out_dir = Path(out_dir)
    plan = stored_plan(out_dir)
    rows = read_results_csv(out_dir / "results.csv")
    written = plots.write_figures(rows, out_dir, plan)
    figures = [out_dir / name for name in OVERLAY_CASES.values() if (out_dir / name).exists()]
    for surface in plan.surfaces:
        for dmax in plan.dmaxs:
            grid, plot = (out_dir / name for name in plots.figure_names(surface, dmax))
            figures += [path for path in (grid, plot) if path in written or path.exists()]
    figures += [path for path in written if path not in figures]
    return findings.write_report(rows, out_dir, plan, figures)


def stored_pmd_plan(out_dir: Path):
    """The plan a PMD study in ``out_dir`` was run with (its ``pmd_study.json``)."""
    from glshade.instruments.pmd.settings import PmdSettings
    from glshade.study.pmd_plan import PmdChain, PmdStudyPlan
    from glshade.study.pmd_store import PMD_LAYOUT

    data = read_manifest(out_dir, PMD_LAYOUT, "study")
    chain = dict(data["chain"])
    chain["periods"] = tuple(chain.get("periods") or ())
    chain["surface_periods"] = tuple(
        (surface, tuple(periods))
        for surface, periods in (chain.get("surface_periods") or {}).items()
    )
    cases = StudyPlan(
        surfaces=tuple(data["surfaces"]),
        thetas=tuple(data["thetas"]),
        sigma2s=tuple(data["sigma2s"]),
        dmaxs=tuple(data["dmaxs"]),
        size=int(data["size"]),
    )
    return PmdStudyPlan(cases, PmdChain(**chain), PmdSettings(**data["settings"]))


def rewrite_pmd(out_dir: Path) -> Path:
    """The PMD study's figures and ``pmd_report.md`` again from ``pmd_study.json``,
    ``pmd_results.csv`` and the stripe study's ``results.csv``, without measuring; returns
    the report's path."""
    from glshade.study import pmd_findings, pmd_plots, pmd_store

    out_dir = Path(out_dir)
    plan = stored_pmd_plan(out_dir)
    rows = pmd_store.read_results_csv(out_dir / pmd_store.RESULTS_NAME)
    paper = read_results_csv(out_dir / "results.csv")
    size = stored_plan(out_dir).size if (out_dir / STRIPES.manifest).exists() else None
    image = (size, size) if size else None
    figures = pmd_plots.write_pmd_figures(rows, paper, out_dir, plan, image)
    return pmd_findings.write_pmd_report(rows, paper, out_dir, plan, figures, size)
