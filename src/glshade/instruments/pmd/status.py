"""Whether a PMD case's numbers can be read (its ``status`` and why), and which columns a
status makes unreadable."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from glshade.instruments.pmd.capture import Decoding, interior
from glshade.metrics.status import (
    STATUSES,
    Status,
    combined,
    coverage_edge,
    no_dent,
    touches_edge,
)
from glshade.oracle.lobe import finish_share
from glshade.scene import Scene

if TYPE_CHECKING:
    from glshade.instruments.pmd.baseline import Noise, PmdBaseline
    from glshade.instruments.pmd.model import StationModel
    from glshade.instruments.pmd.shots import Shot


#: Where the finish's lobe keeps less than this share of the finest fringe (its closed
#: form), an unresolved case names the finish as the cause.
FINISH_CAUSE_SHARE = 0.5
#: The share of the dent's seen region that may be invalid (modulation too low) before
#: its numbers cannot be read.
INVALID_SHARE = 0.25


# --------------------------------------------------------------------------- status
def assess_pmd(
    scene: Scene,
    model: StationModel,
    baseline: PmdBaseline,
    shot: Shot,
    region: np.ndarray,
    failed: np.ndarray,
    exact_mm: float,
    noise: Noise,
    noisy: bool,
) -> Status:
    """Whether a PMD case's numbers can be read: ``outside`` (the dent moves no seen
    pixel), ``edge`` (its region touches the image's border or the edge of what sees the
    screen, or a height map's holes or edge), ``unresolved`` (more than
    :data:`INVALID_SHARE` of its region is not valid: the fringes are averaged out),
    ``saturated``/``underexposed`` (the recorded frames), ``noise`` (the shift the dent
    makes, ``exact_mm`` from the traced maps, is not above the largest shift noise alone
    makes, so the decoded shift is noise's, where a sensor records (``noisy``); or the
    unwrapping fails in the dent's region). A scene without a dent is ``outside``
    whatever else holds (:func:`~glshade.metrics.status.no_dent`, as the stripe metric
    says it)."""
    absent = no_dent(scene)
    if absent is not None:
        return absent
    if not region.any():
        return Status(
            "outside",
            "the dent is not seen: no pixel that sees the screen moves (move the dent, "
            "defect.x0/z0, or the camera)",
        )
    found = [
        _pmd_edge(scene, region, shot),
        _pmd_resolution(scene, model, region, shot.decoding),
    ]
    if model.sensor is not None:
        found.append(_pmd_exposure(baseline))
    floor = noise.floor
    if noisy and not exact_mm > floor:
        hint = ""
        if noise.std > 2.0 * noise.predicted:
            hint = (
                f" (the noise is {noise.std / noise.predicted:.3g} times its prediction: the "
                f"{model.coding.periods[0]:g} mm fringes alias or nearly fail to unwrap "
                "there; a longer emitter.periods[0] or a smaller period ratio helps)"
            )
        found.append(
            Status(
                "noise",
                f"the dent shifts the screen points by {exact_mm:.3g} mm, not above the "
                f"{floor:.3g} mm two noisy decodes of the defect-free scene differ by near it"
                + hint,
            )
        )
    in_region = int((failed & region).sum())
    if in_region:
        found.append(
            Status(
                "noise",
                f"{in_region} pixels of the dent's region fail to unwrap (noise or a "
                "period ratio too large for it)",
            )
        )
    return combined(found)


def _pmd_edge(scene: Scene, region: np.ndarray, shot: Shot) -> Status:
    covered = coverage_edge(scene)
    if covered is not None:
        return covered
    seen = interior(np.all(np.isfinite(shot.uv), axis=-1))  # its edge pixels straddle it
    where = touches_edge(region, seen)
    return Status("edge", f"the dent's region touches {where}") if where else Status()


def _pmd_resolution(
    scene: Scene, model: StationModel, region: np.ndarray, decoding: Decoding
) -> Status:
    count = int(region.sum())
    if not count:
        return Status()
    share = float((region & ~decoding.valid).sum() / count)
    if share <= INVALID_SHARE:
        return Status()
    finest = model.coding.periods[0]
    said = f"{share:.0%} of the dent's region has a modulation below {decoding.threshold:.3g}: "
    finish = finish_share(scene, region, finest, model.axes)
    if finish is not None and finish.share < FINISH_CAUSE_SHARE:
        return Status(
            "unresolved",
            said + finish.phrase(finest) + " (a longer emitter.periods[0], a smoother finish "
            "or a screen nearer the part resolves them)",
        )
    return Status(
        "unresolved",
        said + f"the pixels average the {finest:g} mm fringes out there (a longer "
        "emitter.periods[0], a sharper focus or a finer camera resolves them)",
    )


def _pmd_exposure(baseline: PmdBaseline) -> Status:
    """``saturated``/``underexposed`` from the brightest fringe's noise-free signal,
    ``gain`` × radiance: the share of the range above the black level it fills (the full
    well fills that range), so the black level is left out by construction."""
    signal = baseline.capture.white * baseline.capture.gain
    signal = signal * baseline.model.coding.brightest()
    seen = np.isfinite(signal) & (baseline.capture.white > 0)
    values = signal[seen]
    if not values.size:
        return Status()
    clipped = float((values >= 1.0).mean())
    if clipped > 0.01:
        return Status(
            "saturated",
            f"{clipped:.1%} of the seen pixels clip at full scale on the brightest fringe; "
            'lower camera.exposure or set it to "auto"',
        )
    peak = float(np.percentile(values, 99.5))
    if peak < 0.1:
        return Status(
            "underexposed",
            f"the fringes peak at {peak:.1%} of the range above the black level; raise "
            'camera.exposure or set it to "auto"',
        )
    return Status()


assert "unresolved" in STATUSES  # the statuses are the paper metric's, in its order


#: The numbers of the dent itself: a status other than ok makes them unreadable (the
#: station's own numbers, its noise, decoding error and valid share, stay readable).
DENT_COLUMNS = (
    "pmd_shift_mm",
    "pmd_snr",
    "pmd_slope_urad",
    "pmd_depth_um",
    "pmd_sigma_mm",
)


def pmd_concerns(status: str, column: str) -> bool:
    """True when ``status`` makes ``column`` of a PMD record unreadable."""
    return status != "ok" and column in DENT_COLUMNS
