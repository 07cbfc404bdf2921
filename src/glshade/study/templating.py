"""The studies' reports as Jinja2 templates: the one environment that loads them from
``glshade/study/templates`` (shipped in the wheel) with the filters and tests
of :mod:`glshade.study.formats`. The analysis modules never import this one: they compute
numbers, the templates word them.
"""

from __future__ import annotations

import functools
from typing import Any

from jinja2 import Environment, PackageLoader, StrictUndefined

from glshade.study.formats import FILTERS, TESTS


@functools.cache
def environment() -> Environment:
    """The reports' environment: Markdown, not HTML (no autoescaping: stored text is
    escaped by the ``md`` filter where it enters), every variable required."""
    env = Environment(
        loader=PackageLoader("glshade.study", "templates"),
        autoescape=False,
        undefined=StrictUndefined,
        keep_trailing_newline=True,
        trim_blocks=True,
        lstrip_blocks=True,
    )
    env.filters.update(FILTERS)
    env.tests.update(TESTS)
    return env


def render(name: str, **context: Any) -> str:
    """The template ``name`` rendered with ``context``."""
    return environment().get_template(name).render(**context)


def render_lines(name: str, **context: Any) -> list[str]:
    """The template ``name`` rendered, as the lines it writes (each without its break)."""
    return render(name, **context).removesuffix("\n").split("\n")


def macro(name: str, macro_name: str) -> Any:
    """A macro of the template ``name``, to call from Python (returns its text)."""
    return getattr(environment().get_template(name).module, macro_name)
