"""The one result record of a measured scene: its fields are the columns of ``results.csv``
(the study's, after the case's own parameters), of a sweep's ``results.parquet`` and
``results.csv`` (after its swept keys), the keys of ``glshade measure --json`` and the
table of ``docs/results.md``. Declared once, here, with each column's unit and meaning.

A column's ``role`` says where it goes: ``measured`` (the metric's numbers, the same
wherever a case ran), ``law`` (the closed forms beside them, docs/physics.md) or
``timing`` (seconds spent, which differ from run to run: the study's table has them, a
sweep keeps them in its case files, not in its table).
"""

from __future__ import annotations

import functools
import math
import unicodedata
from collections.abc import Callable
from dataclasses import Field, dataclass, field, fields
from typing import Any, ClassVar

from glshade.metrics import physics
from glshade.metrics.status import STATUSES
from glshade.metrics.visibility import Visibility
from glshade.scene import Scene

ROLES = ("measured", "law", "timing")


def column(
    unit: str,
    meaning: str,
    role: str = "measured",
    *,
    low: float | None = None,
    choices: tuple[str, ...] = (),
) -> Any:
    """A record field with its unit, meaning and role (as ``docs/results.md`` prints them);
    ``low``: its least value where that is not its unit's (:data:`UNIT_RANGES`: 0 for a
    distance or a noise); ``choices``: the words a text column may hold (none: any line)."""
    return field(
        metadata={"unit": unit, "meaning": meaning, "role": role, "low": low, "choices": choices}
    )


#: The range of a number by its unit, what a stored record may hold (a file read back
#: outside it is not one glshade wrote): no image is 1e6 px across (camera.width is at
#: most 16384), no length on a part or screen 1 km, no slope π rad; a count is a count
#: of pixels or contours (a 16384² image has 2.7e8 pixels). The ends are included.
UNIT_RANGES: dict[str, tuple[float, float]] = {
    "px": (-1e6, 1e6),
    "mm": (-1e6, 1e6),
    "mm²": (0.0, 1e12),
    "µm": (-1e9, 1e9),
    "µrad": (-1e7, 1e7),
    "deg": (-360.0, 360.0),
    "fraction": (0.0, 1.0),
    "count": (0, 2**31 - 1),
    "s": (0.0, 1e7),
    "": (-1e12, 1e12),
}
#: What ``pmd_shift_law_status`` says (:func:`glshade.metrics.physics.pmd_shift_law_check`).
LAW_STATUSES = ("ok", "grazing")
#: The longest text a stored record's column may hold (a status reason joins a few
#: sentences: a few hundred characters).
MAX_TEXT = 4096


@dataclass(frozen=True)
class Column:
    """One column: its name, unit, meaning and role."""

    name: str
    unit: str
    meaning: str
    role: str


def _boolean(value: Any) -> bool:
    return value == "True" if isinstance(value, str) else bool(value)


def _optional_float(value: Any) -> float | None:
    if value is None or value == "":
        return None
    number = float(value)
    return None if math.isnan(number) else number


#: How a column's value is read back from JSON or CSV text, by its annotation.
PARSE: dict[str, Callable[[Any], Any]] = {
    "str": str,
    "float": float,
    "int": int,
    "bool": _boolean,
    "float | None": _optional_float,
}


#: The JSON values a case file may hold for a field, by the field's annotation.
_JSON_TYPES: dict[str, tuple[type, ...]] = {
    "str": (str,),
    "float": (int, float),
    "int": (int,),
    "bool": (bool,),
    "float | None": (int, float, type(None)),
}


class Record:
    """What every result record shares: its columns are its own dataclass's fields (a
    subclass that adds fields, a study's row, keeps its record's columns); every field,
    a subclass's too, is typed whatever it was read from (JSON, CSV text, NumPy); a record
    reads back from a row."""

    #: Set on each record class: its own fields are the record's columns.
    record: ClassVar[bool] = False
    #: Every record says whether its numbers can be read: ``ok``, or why not (its own
    #: words), and what to change (two of its columns).
    status: str
    status_reason: str

    @classmethod
    def columns(cls) -> tuple[Column, ...]:
        """The record's columns, in order."""
        owner = next(c for c in cls.__mro__ if c.__dict__.get("record"))
        return _columns(owner)

    def __post_init__(self) -> None:
        for item in fields(self):  # type: ignore[arg-type]
            kind = item.type if isinstance(item.type, str) else item.type.__name__
            object.__setattr__(self, item.name, PARSE[kind](getattr(self, item.name)))

    @classmethod
    def from_row(cls, row: dict[str, Any]) -> Any:
        """From a case file's object or a table's row (text); other keys are ignored, a
        missing timing reads 0."""
        return cls(
            **{
                c.name: row.get(c.name, 0.0) if c.role == "timing" else row[c.name]
                for c in cls.columns()
            }
        )

    @classmethod
    def json_problem(cls, row: dict[str, Any]) -> str | None:
        """Why ``row``, read from a case file's JSON, is not this record's fields with
        the JSON types they are written as (a number where a number belongs, never a
        string or a list; a missing field), or None. Only the fields of ``cls`` that
        ``row`` must hold are checked (a missing timing reads 0)."""
        for item in fields(cls):  # type: ignore[arg-type]
            if item.name not in row:
                if item.metadata.get("role") == "timing":
                    continue
                return f"lacks {item.name} (written by an older glshade)"
            problem = _json_value_problem(item, row[item.name])
            if problem is not None:
                return problem
        return None

    @classmethod
    def field_problem(cls, name: str, value: Any) -> str | None:
        """Why ``value``, read from JSON, is not one this record's field ``name`` holds
        (its JSON type, then :func:`value_problem`), or None; a name that is no field of
        the record has no problem here."""
        item = next((f for f in fields(cls) if f.name == name), None)  # type: ignore[arg-type]
        return None if item is None else _json_value_problem(item, value)

    def problem(self) -> str | None:
        """Why this record's values (read from a table's text) are not ones glshade
        writes (:func:`value_problem`), or None."""
        for item in fields(self):  # type: ignore[arg-type]
            problem = value_problem(item, getattr(self, item.name))
            if problem is not None:
                return problem
        return None

    def row(self, roles: tuple[str, ...] = ROLES) -> dict[str, Any]:
        """The columns of these roles, in order, as plain values (None stays None)."""
        return {c.name: getattr(self, c.name) for c in self.columns() if c.role in roles}

    def outputs(self) -> dict[str, Any]:
        """What a case measured, the same wherever it ran: the measured and law columns."""
        return self.row(("measured", "law"))

    def seconds(self) -> dict[str, float]:
        return self.row(("timing",))


def _json_value_problem(item: Field, value: Any) -> str | None:
    kind = item.type if isinstance(item.type, str) else item.type.__name__
    if not isinstance(value, _JSON_TYPES[kind]) or (isinstance(value, bool) and kind != "bool"):
        return f"holds {type(value).__name__} as {item.name}, not {kind}"
    return value_problem(item, value)


#: Characters no stored text may hold: controls (line breaks, escapes), format characters
#: (bidirectional overrides), lone surrogates, line and paragraph separators.
_CONTROL_CATEGORIES = frozenset({"Cc", "Cf", "Cs", "Zl", "Zp"})


def value_problem(item: Field, value: Any) -> str | None:
    """Why ``value``, of the type a record's field ``item`` is written as, is not one it
    holds, or None: a number not finite or outside its unit's range
    (:data:`UNIT_RANGES`, from the column's own ``low``); a text that is not one of the
    column's ``choices``, is longer than :data:`MAX_TEXT` or holds a control character."""
    if isinstance(value, str):
        return text_problem(item.name, value, item.metadata.get("choices") or ())
    if value is None or isinstance(value, bool):
        return None
    low, high = UNIT_RANGES.get(item.metadata.get("unit", ""), UNIT_RANGES[""])
    if item.metadata.get("low") is not None:
        low = item.metadata["low"]
    if isinstance(value, float) and not math.isfinite(value):
        return f"holds {value!r} as {item.name}, not a finite number"
    if not low <= value <= high:  # exact for an int of any size
        return f"holds {_shown(value)} as {item.name}, outside {_end(low)} to {_end(high)}"
    return None


def text_problem(name: str, text: str, choices: tuple[str, ...] = ()) -> str | None:
    """Why ``text``, stored as ``name``, is not one line glshade writes (not one of
    ``choices`` where there are any; longer than :data:`MAX_TEXT`; a control
    character), or None."""
    if choices and text not in choices:
        return f"holds {_shown(text)} as {name}, not one of {', '.join(choices)}"
    if len(text) > MAX_TEXT:
        return f"holds {len(text)} characters as {name}, more than {MAX_TEXT}"
    odd = next((c for c in text if unicodedata.category(c) in _CONTROL_CATEGORIES), None)
    if odd is not None:
        return f"holds the control character U+{ord(odd):04X} in {name}"
    return None


def _end(bound: float) -> str:
    return str(bound) if isinstance(bound, int) else f"{bound:g}"


def _shown(value: Any) -> str:
    """``value`` in a message: its repr (escaped: one line), at most 40 characters."""
    text = repr(value)
    return text if len(text) <= 40 else f"{text[:37]}..."


@functools.cache
def _columns(owner: type) -> tuple[Column, ...]:
    return tuple(
        Column(f.name, f.metadata["unit"], f.metadata["meaning"], f.metadata["role"])
        for f in fields(owner)
    )


@dataclass(frozen=True)
class Measurement(Record):
    """What was measured of one scene's defect, every length in pixels of its image."""

    record = True

    visibility_px: float = column(
        "px",
        "the paper's metric: the largest distance between corresponding stripe contours over "
        "the phase sweep, whole pixels of the image",
        low=0.0,
    )
    visibility_continuous_px: float = column(
        "px",
        "the limit of the paper's metric for a vanishing phase step and pixel size, by the "
        "same contour rules (sub-pixel)",
        low=0.0,
    )
    deflection_px: float = column(
        "px",
        "how far the dent moves the emitter map: the largest distance between a row r and the "
        "row r0 where v0(r0) = v1(r), in a kept column; equals the continuous visibility where "
        "nothing folds",
        low=0.0,
    )
    folded: bool = column(
        "",
        "True where the dent's emitter map runs against the defect-free one along some kept "
        "column (the stripe map folds)",
    )
    islands: int = column(
        "count",
        "the most stripe pieces the dent cuts off (touching neither a cut column nor the "
        "border; beyond those the defect-free image has) at any phase; never measured",
    )
    best_phase_mm: float = column("mm", "stripe phase at which visibility_px was reached")
    unpaired_contours: int = column(
        "count",
        "stripes reaching a cut column or the border that found no partner at the best phase "
        "(0 in a healthy comparison)",
    )
    offset_dx_px: int = column(
        "px", "registration offset applied to the defect image, columns (0 for rendered pairs)"
    )
    offset_dy_px: int = column(
        "px", "registration offset applied to the defect image, rows (0 for rendered pairs)"
    )
    unresolved_fraction: float = column(
        "fraction",
        "share of the kept pixels left out because the defect-free stripes span fewer than "
        "4 px per period there (aliasing)",
    )
    noise_floor_px: float | None = column(
        "px",
        "with a sensor: the paper's metric between two noisy exposures of the defect-free "
        "scene, the contour jitter noise alone makes (empty without a sensor)",
        low=0.0,
    )
    status: str = column(
        "",
        "whether the numbers can be read: ok, or why not (outside, edge, unresolved, "
        "saturated, underexposed, noise; docs/study.md, 'Whether a number can be trusted')",
        choices=STATUSES,
    )
    status_reason: str = column(
        "", "why the numbers cannot be read, and what to change (empty when status is ok)"
    )
    stripe_contrast: float | None = column(
        "",
        "Michelson contrast of the defect-free stripes over the resolved kept pixels (0.5th to "
        "99.5th percentile) relative to the emitter's own: 1 for a sharp mirror; below 0.5 "
        "warned about, with its causes",
        low=0.0,
    )
    fold_ratio: float | None = column(
        "",
        "closed form 2 κ Dc De / ((Dc + De) sin θ), κ the largest tangential curvature of base "
        "plus dent; the map folds where it exceeds 1 (docs/physics.md)",
        "law",
    )
    deflection_law_px: float | None = column(
        "px", "closed form of deflection_px (docs/physics.md)", "law"
    )
    visibility_law_px: float | None = column(
        "px",
        "closed form of visibility_continuous_px: the deflection, capped by a fold at "
        "b sqrt(2 ln(F/m)) (docs/physics.md)",
        "law",
    )
    magnification: float | None = column(
        "",
        "closed form of how much a convex base in the plane of incidence magnifies the "
        "emitter (1 on the flat plate; docs/physics.md)",
        "law",
    )
    trace_s: float = column("s", "time to trace the dent's emitter map (GL)", "timing")
    shade_s: float = column("s", "time to binarise the defect image at every phase", "timing")
    contours_s: float = column(
        "s", "time of the contour analysis over the phase sweep (OpenCV)", "timing"
    )
    continuous_s: float = column("s", "time of the deflection and the continuous limit", "timing")

    @classmethod
    def of(cls, scene: Scene, result: Visibility, trace_s: float = 0.0) -> Measurement:
        """The record of ``result``, the metric's measurement of ``scene``: its numbers
        rounded as tables show them, the closed forms beside them, the seconds spent."""
        law = physics.laws(scene)
        spent = result.seconds
        return cls(
            visibility_px=result.visibility_px,
            visibility_continuous_px=round(result.visibility_continuous_px, 4),
            deflection_px=round(result.deflection_px, 4),
            folded=result.folded,
            islands=result.islands,
            best_phase_mm=result.best_phase_mm,
            unpaired_contours=result.unpaired_contours,
            offset_dx_px=int(result.offset_px[0]),
            offset_dy_px=int(result.offset_px[1]),
            unresolved_fraction=round(result.unresolved_fraction, 5),
            noise_floor_px=result.noise_floor_px,
            status=result.status,
            status_reason=result.status_reason,
            stripe_contrast=_finite(result.stripe_contrast, 4),
            fold_ratio=_finite(law.fold_ratio, 5),
            deflection_law_px=_finite(law.deflection_px, 4),
            visibility_law_px=_finite(law.visibility_px, 4),
            magnification=_finite(law.magnification, 5),
            trace_s=round(trace_s, 4),
            shade_s=round(spent.shade, 4),
            contours_s=round(spent.contours, 4),
            continuous_s=round(spent.continuous, 4),
        )


@dataclass(frozen=True)
class PmdMeasurement(Record):
    """What a phase-measuring deflectometry station measures of one scene's dent: lengths
    on the screen in mm, slopes in µrad, heights in µm (docs/pmd.md). The row of
    ``glshade measure --method pmd``, of a PMD sweep and of the PMD study."""

    record = True

    pmd_shift_mm: float | None = column(
        "mm",
        "the largest distance between the decoded screen points with and without the dent, "
        "near the dent, over the pixels valid in both and off the edge of that region "
        "(unwrapping failures left out)",
        low=0.0,
    )
    pmd_shift_exact_mm: float | None = column(
        "mm",
        "the same shift of the exact (traced) screen points: what a noise-free station "
        "would decode; the status compares it with pmd_noise_floor_mm",
        low=0.0,
    )
    pmd_noise_mm: float | None = column(
        "mm",
        "the decoded coordinate's noise: the standard deviation of the difference of two "
        "decodes of the defect-free scene recorded twice (two noises), over sqrt 2, over the "
        "pixels near the dent valid in both, off that region's edge and unwrapped right in "
        "both (0 without a sensor)",
        low=0.0,
    )
    pmd_noise_predicted_mm: float | None = column(
        "mm",
        "periods[0] / 2π · sqrt(2 / N) · σ_I / B, σ_I the sensor's noise at each pixel's mean "
        "level above the black level and B its modulation, pooled as a root mean square over "
        "the same pixels (0 without a sensor)",
        low=0.0,
    )
    pmd_noise_floor_mm: float | None = column(
        "mm",
        "the largest difference between the two noisy decodes of the defect-free scene over "
        "the same pixels: the shift noise alone makes (0 without a sensor)",
        low=0.0,
    )
    pmd_snr: float | None = column(
        "",
        "pmd_shift_mm / pmd_noise_mm; empty without a sensor (noise-free: unbounded)",
        low=0.0,
    )
    pmd_slope_urad: float | None = column(
        "µrad",
        "the largest measured slope deviation (normals against the nominal surface's) in the "
        "dent's region",
        low=0.0,
    )
    pmd_depth_um: float | None = column(
        "µm",
        "the depth of the Gaussian fitted to the heights integrated from the slopes (positive "
        "for a dent), to compare with dmax; empty where the fit fails or lands where no dent "
        "of these heights can be (beyond twice their range, or off the grid)",
    )
    pmd_sigma_mm: float | None = column(
        "mm",
        "the σ of that Gaussian, to compare with sqrt(sigma2)",
        low=0.0,
    )
    decode_rms_mm: float | None = column(
        "mm",
        "root mean square of the decoded minus the exact screen points over the valid pixels "
        "of the defect-free scene",
        low=0.0,
    )
    unwrap_failures: int = column(
        "count",
        "valid pixels of the dent's scene decoded more than half the finest period from the "
        "exact map (the unwrapping chose another fringe)",
    )
    valid_fraction: float = column(
        "fraction",
        "valid pixels (modulation above the threshold) over the pixels that see the "
        "screen, the dent's scene",
    )
    modulation: float | None = column(
        "",
        "the finest fringe's modulation share B / (b1 W) of the noise-free radiance (b1 the "
        "displayed fringe's fundamental over the displayed white, W the pixel's own response "
        "to the white), its median over the dent's region, else over the pixels that see the "
        "screen: 1 for a sharp mirror, less where the finish, the lens or the pixels average "
        "the fringes out",
        low=0.0,
    )
    status: str = column(
        "",
        "whether the numbers can be read: ok, or why not (docs/pmd.md, 'Status: whether a "
        "number can be trusted')",
        choices=STATUSES,
    )
    status_reason: str = column(
        "", "why the numbers cannot be read, and what to change (empty when status is ok)"
    )
    pmd_shift_law_mm: float | None = column(
        "mm",
        "closed form of pmd_shift_mm: 2 α_max (De + σ cos θ) · G, α_max the dent's steepest "
        "slope along the coded directions, G the curved base's factor along the plane of "
        "incidence (docs/physics.md, section 7)",
        "law",
    )
    pmd_shift_law_status: str = column(
        "",
        "whether pmd_shift_law_mm holds: ok, or grazing where the base's horizon falls inside "
        "the dent's window (docs/physics.md, section 7)",
        "law",
        choices=LAW_STATUSES,
    )
    pmd_shift_law_reason: str = column(
        "", "why pmd_shift_law_mm does not hold (empty when it does)", "law"
    )
    render_s: float = column("s", "time to render both sequences (GL)", "timing")
    decode_s: float = column("s", "time to record and decode the dent's sequence", "timing")
    heights_s: float = column("s", "time of the slopes, heights and dent fit", "timing")

    @classmethod
    def of(cls, scene: Scene, result: Any, baseline_seconds: float = 0.0) -> PmdMeasurement:
        """The record of ``result`` (a :class:`glshade.instruments.pmd.station.PmdResult`)."""
        spent = result.seconds
        law = physics.pmd_shift_law_check(scene)
        return cls(
            pmd_shift_mm=_finite(result.pmd_shift_mm, 6),
            pmd_shift_exact_mm=_finite(result.pmd_shift_exact_mm, 6),
            pmd_noise_mm=_finite(result.pmd_noise_mm, 7),
            pmd_noise_predicted_mm=_finite(result.pmd_noise_predicted_mm, 7),
            pmd_noise_floor_mm=_finite(result.pmd_noise_floor_mm, 6),
            pmd_snr=_finite(result.pmd_snr, 3),
            pmd_slope_urad=_finite(result.pmd_slope_urad, 2),
            pmd_depth_um=_finite(result.pmd_depth_um, 4),
            pmd_sigma_mm=_finite(result.pmd_sigma_mm, 4),
            decode_rms_mm=_finite(result.decode_rms_mm, 7),
            unwrap_failures=result.unwrap_failures,
            valid_fraction=round(result.valid_fraction, 5),
            modulation=_finite(result.modulation, 4),
            status=result.status,
            status_reason=result.status_reason,
            pmd_shift_law_mm=_finite(physics.pmd_shift_mm(scene), 6),
            pmd_shift_law_status=law.status,
            pmd_shift_law_reason=law.reason,
            render_s=round(spent.get("render", 0.0) + baseline_seconds, 4),
            decode_s=round(spent.get("decode", 0.0), 4),
            heights_s=round(spent.get("heights", 0.0), 4),
        )


def _finite(value: float, digits: int) -> float | None:
    """A closed form rounded as tables show it; None where it is not finite (JSON has no
    NaN)."""
    return round(value, digits) if math.isfinite(value) else None


COLUMNS: tuple[Column, ...] = Measurement.columns()
COLUMN_NAMES: tuple[str, ...] = tuple(c.name for c in COLUMNS)
TIMINGS: tuple[str, ...] = tuple(c.name for c in COLUMNS if c.role == "timing")
OUTPUT_NAMES: tuple[str, ...] = tuple(c.name for c in COLUMNS if c.role != "timing")


PMD_COLUMNS: tuple[Column, ...] = PmdMeasurement.columns()
PMD_COLUMN_NAMES: tuple[str, ...] = tuple(c.name for c in PMD_COLUMNS)
PMD_TIMINGS: tuple[str, ...] = tuple(c.name for c in PMD_COLUMNS if c.role == "timing")
PMD_OUTPUT_NAMES: tuple[str, ...] = tuple(c.name for c in PMD_COLUMNS if c.role != "timing")


def columns_markdown(columns: tuple[Column, ...] = COLUMNS) -> str:
    """A table of columns, as ``docs/results.md`` and ``docs/sweeps.md`` print it."""
    lines = ["| column | unit | meaning |", "|---|---|---|"]
    lines += [f"| `{c.name}` | {c.unit or '—'} | {c.meaning} |" for c in columns]
    return "\n".join(lines)
