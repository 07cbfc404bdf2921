"""Components whose declarations are malformed, one per entry point (each attribute a
list of components, as a module's ``COMPONENTS`` is)."""

from __future__ import annotations

from glshade.components.base import SurfaceComponent


class NamedByAList(SurfaceComponent):
    name = ["wavy"]  # type: ignore[assignment]


class ParamsRaise(SurfaceComponent):
    name = "wavy"

    @property
    def params(self):  # type: ignore[override]
        raise RuntimeError("no table today")


class RankedByWord(SurfaceComponent):
    name = "wavy"
    rank = "high"  # type: ignore[assignment]


class ParamsOfText(SurfaceComponent):
    name = "wavy"
    params = ("surface.amplitude",)  # type: ignore[assignment]


class NamedLikeAPath(SurfaceComponent):
    name = "../wavy"


class Sphere(SurfaceComponent):
    name = "sphere"  # glshade's own


class Good(SurfaceComponent):
    name = "rippled"


named_by_a_list = [NamedByAList]
params_raise = [ParamsRaise]
ranked_by_word = [RankedByWord]
params_of_text = [ParamsOfText]
named_like_a_path = [NamedLikeAPath]
#: a valid component beside one that takes a built-in's name: the plug-in goes whole
takes_a_builtin_name = [Good, Sphere]
