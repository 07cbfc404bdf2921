"""The paper's study, measured by any instrument that has a study: ``glshade paper
--method NAME``.

A study is the paper's plan of cases (the surfaces, Table 1's θ × σ² × dmax and the image
size: :class:`~glshade.study.plan.StudyPlan`) measured by one instrument, with that
instrument's run, figures and report. Each instrument's study is a :class:`StudyKind`
registered under the instrument's name through the ``glshade.studies`` entry-point group
(glshade's own: the stripe metric's and phase measuring's), so ``glshade paper`` never
branches on an instrument's name: ``--method``'s choices, each study's own flags, the
refusal of one study's flag given to another and the run all come from here. A plug-in
instrument without a study is measured, swept, optimised and snapshot-tested like the
others; ``glshade paper --method`` does not offer it.
"""

from __future__ import annotations

import argparse
import functools
import warnings
from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, Any, ClassVar

from glshade.components.plugin_guard import PluginRefused, run_plugin_code
from glshade.errors import GlshadeError, GlshadeWarning

if TYPE_CHECKING:
    from glshade.study.plan import StudyPlan

ENTRY_POINT_GROUP = "glshade.studies"
#: glshade's own studies: instrument name -> ``module:class``.
BUILTIN_STUDIES = {
    "paper": "glshade.app.commands.paper_stripes:StripeStudy",
    "pmd": "glshade.app.commands.paper_pmd:PmdStudy",
}


class StudyKind(ABC):
    """One instrument's study of the paper's cases: its own flags on ``glshade paper``,
    the checks that refuse bad input before ``--out`` is touched, and the run (cases,
    figures, report) with ``--out`` locked."""

    #: The instrument's registered name (``--method NAME``).
    name: ClassVar[str]
    #: What the study writes, in a few words (``--method``'s help).
    writes: ClassVar[str]

    def add_flags(self, parser: argparse.ArgumentParser) -> None:
        """Add this study's own flags to ``glshade paper`` (none by default)."""
        return None

    def flags_given(self, args: argparse.Namespace) -> list[str]:
        """This study's own flags the command line set (refused by the other studies)."""
        return []

    def plan_settings(self, args: argparse.Namespace) -> Any:
        """The stripe metric's settings the plan's cases carry
        (:attr:`~glshade.study.plan.StudyPlan.metric`): its defaults unless the study
        is the stripe metric's own."""
        from glshade.instruments.registry import instrument
        from glshade.study.plan import PLAN_METHOD

        return instrument(PLAN_METHOD).settings_type()

    def sweep_file(self, plan: StudyPlan, prepared: Any) -> dict[str, Any]:
        """The study's cases as a sweep file (docs/sweeps.md): its grid, size and
        ``[measure]`` table, so ``glshade sweep`` measures the same scenes with the same
        settings (``glshade paper --as-sweep FILE``)."""
        raise GlshadeError(f"--as-sweep: the {self.name} study has no sweep form")

    @abstractmethod
    def prepared(self, args: argparse.Namespace, plan: StudyPlan, workers: str) -> Any:
        """Everything checked before ``--out`` is touched (bad input is one line): what
        :meth:`run` takes. ``workers`` is ``--workers`` as typed (``auto`` or N);
        ``args.workers`` holds the worker processes it resolved to."""

    @abstractmethod
    def run(self, args: argparse.Namespace, plan: StudyPlan, prepared: Any) -> int:
        """Run (or resume) the study into ``args.out`` (locked) and write its report."""


@functools.cache
def study_kinds() -> dict[str, StudyKind]:
    """The studies by instrument name, glshade's own first; a plug-in's that does not load,
    that is not a :class:`StudyKind`, or whose instrument is not registered, is left out
    with one warning."""
    from glshade.instruments.registry import method_names

    found = {name: _kind(value) for name, value in BUILTIN_STUDIES.items()}
    for name, value in _plugin_points():
        try:
            if name in found or name not in method_names():
                raise PluginRefused(f"no instrument {name!r} without a study of its own")
            found[name] = run_plugin_code(functools.partial(_kind, value))
        except PluginRefused as exc:
            warnings.warn(f"study plug-in {name} ({value}) left out: {exc}", GlshadeWarning, 2)
    return found


def study_kind(name: str) -> StudyKind:
    """The study of instrument ``name`` (one line listing the studies otherwise)."""
    kinds = study_kinds()
    if name not in kinds:
        raise GlshadeError(f"--method: must be one of {', '.join(kinds)}, got {name!r}")
    return kinds[name]


def refuse_other_flags(args: argparse.Namespace, chosen: StudyKind) -> None:
    """Refuse, in one line, a flag of another study given to ``chosen``."""
    from glshade.instruments.registry import instrument

    for other in study_kinds().values():
        if other is chosen:
            continue
        for flag in other.flags_given(args):
            raise GlshadeError(
                f"{flag}: belongs to {instrument(other.name).title} (--method {other.name}), "
                f"not to --method {chosen.name}"
            )


def measure_table_of(method: str, settings: Any) -> dict[str, Any]:
    """A sweep file's ``[measure]`` table of instrument ``method``'s ``settings``: the
    method and every setting that is set (an unset one keeps its documented fallback)."""
    from dataclasses import asdict

    values = {key: value for key, value in asdict(settings).items() if value is not None}
    return {"method": method, **values}


def _plugin_points() -> list[tuple[str, str]]:
    from importlib.metadata import entry_points

    try:
        points = entry_points(group=ENTRY_POINT_GROUP)
    except Exception:  # an installed package's metadata that cannot be read
        return []
    own = set(BUILTIN_STUDIES.values())
    return sorted((p.name, p.value) for p in points if p.value not in own)


def _kind(value: str) -> StudyKind:
    import importlib

    module_name, _, attribute = value.partition(":")
    loaded: Any = getattr(importlib.import_module(module_name.strip()), attribute.strip())
    kind = loaded() if isinstance(loaded, type) else loaded
    if not isinstance(kind, StudyKind):
        raise PluginRefused(f"{value} is not a glshade.app.studies.StudyKind")
    return kind
