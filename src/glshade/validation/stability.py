"""Stiff and extreme cases: the shader against the NumPy fp64 oracle.

Each case is a scene at the edge of what glshade is asked to do: grazing and near-normal
views, dents from a micrometre to half a millimetre deep and from 0.1 mm to 20 mm wide,
bumps, a near-singular covariance, a defect far off the axis, radii from 5 mm to 100 m,
silhouettes, a folding stripe map, an emitter seen edge-on and a tiny emitter.

Every case is rendered twice: the **centre** (a 32x32 camera at the paper's pitch, i.e.
the central crop of the paper's 1024² image, where the dent is) and the **field** (the
whole view on 48x48 pixels). :func:`check` compares both with
:func:`glshade.oracle.tracer.trace` and ``first_hit`` and returns the measured errors;
``tests/test_stability.py`` asserts on them and ``glshade accuracy`` tabulates them.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from glshade.frame import Frame
from glshade.gpu.renderer import Renderer, RootSolver
from glshade.oracle import tracer as reference
from glshade.scene import Defect, Scene, paper_scene

#: uv tolerances (mm) where no case says otherwise (the renderer's accuracy goals).
UV_TOLERANCE = {"fp32": 5e-4, "fp64": 1e-6}


@dataclass(frozen=True)
class Extreme:
    """One stiff or extreme scene of the stability matrix. ``uv_tolerance_fp32``: a
    documented limit, where fp32 cannot meet the default
    (the reason in ``note``)."""

    name: str
    group: str
    scene: Scene
    note: str = ""
    uv_tolerance_fp32: float | None = None

    def uv_tolerance(self, precision: str) -> float:
        if precision == "fp32" and self.uv_tolerance_fp32 is not None:
            return self.uv_tolerance_fp32
        return UV_TOLERANCE[precision]


def _with(scene: Scene, **tables) -> Scene:
    return replace(scene, **tables)


@dataclass(frozen=True)
class _Bases:
    """The paper's scene (45°, σ² 4 mm², dmax 5 µm) on each base surface the cases vary."""

    flat: Scene
    sphere: Scene
    cylinder: Scene


def _bases() -> _Bases:
    """The flat, spherical and cylindrical paper scenes every case starts from."""
    return _Bases(
        flat=paper_scene("flat", 45.0, 4.0, 0.005),
        sphere=paper_scene("sphere", 45.0, 4.0, 0.005),
        cylinder=paper_scene("cylinder", 45.0, 4.0, 0.005),
    )


def _view_cases(bases: _Bases) -> list[Extreme]:
    """Near-grazing and near-normal views of the flat base, and a grazing sphere."""
    out = [
        Extreme(f"flat theta {theta:g}", "view", bases.flat.updated(camera={"theta_deg": theta}))
        for theta in (0.5, 1.0, 2.0, 89.0, 89.9)
    ]
    out.append(Extreme("sphere theta 1", "view", bases.sphere.updated(camera={"theta_deg": 1.0})))
    return out


#: ``(sigma2, dmax)`` of the dents from narrow to wide and from shallow to deep.
_DENT_SHAPES = (
    (0.01, 0.005),
    (0.01, 0.5),
    (400.0, 0.005),
    (400.0, 0.5),
    (4.0, 1e-6),
    (4.0, 0.5),
    (1.0, 0.02),
)


def _dent_cases(flat: Scene) -> list[Extreme]:
    """Dents and bumps of extreme width and depth on the flat base, a bump a grazing ray
    can skim over and a steep dent that folds the stripe map."""
    out = [
        Extreme(
            f"flat sigma2 {sigma2:g} dmax {dmax:g}",
            "dent",
            flat.updated(defect={"sigma2": sigma2, "dmax": dmax}),
        )
        for sigma2, dmax in _DENT_SHAPES
    ]
    out.append(
        Extreme(
            "flat bump dmax -0.5 sigma2 1",
            "dent",
            flat.updated(defect={"sigma2": 1.0, "dmax": -0.5}),
        )
    )
    out.append(
        Extreme("flat bump dmax -1e-6", "dent", flat.updated(defect={"sigma2": 4.0, "dmax": -1e-6}))
    )
    out.append(
        Extreme(
            "grazing steep bump",
            "dent",
            flat.updated(camera={"theta_deg": 2.0}, defect={"sigma2": 0.25, "dmax": -0.05}),
            "the ray can skim over the bump's top",
        )
    )
    out.append(
        Extreme(
            "folding: steep dent at 5 deg",
            "dent",
            flat.updated(camera={"theta_deg": 5.0}, defect={"sigma2": 0.05, "dmax": 0.02}),
        )
    )
    return out


def _covariance_cases(bases: _Bases) -> list[Extreme]:
    """A near-singular covariance and defects far off the axis."""
    near_singular = Defect(dmax=0.005, sigma_x2=1.0, sigma_z2=1.0, sigma_xz=1.0 - 1e-6)
    return [
        Extreme(
            "covariance condition 1e6",
            "covariance",
            _with(bases.flat, defect=near_singular),
            "a ridge 1.4 µm wide with slope 3.5: 1e-7 mm of fp32 position error tilts the normal "
            "by "
            "2.5e-4 rad; use fp64",
            uv_tolerance_fp32=2e-2,
        ),
        Extreme(
            "defect far off axis",
            "covariance",
            bases.flat.updated(defect={"x0": 12.0, "z0": -9.0}),
            "the centre view shows only the defect's far tail",
        ),
        Extreme(
            "sphere, defect far off axis",
            "covariance",
            bases.sphere.updated(defect={"x0": 10.0, "z0": 8.0}),
        ),
    ]


def _radius_cases(bases: _Bases) -> list[Extreme]:
    """Convex and concave spheres and cylinders from 5 mm to 100 m, and a cylinder whose
    axis lies in the plane of incidence."""
    out = []
    for radius in (5.0, -5.0, 1e5, -1e5):
        out.append(
            Extreme(
                f"sphere R {radius:g}", "radius", bases.sphere.updated(surface={"radius": radius})
            )
        )
        out.append(
            Extreme(
                f"cylinder R {radius:g}",
                "radius",
                bases.cylinder.updated(surface={"radius": radius}),
            )
        )
    out.append(
        Extreme(
            "cylinder x-axis R 5 at 15 deg",
            "radius",
            bases.cylinder.updated(
                surface={"radius": 5.0, "axis": "x"}, camera={"theta_deg": 15.0}
            ),
        )
    )
    return out


def _silhouette_cases(sphere: Scene) -> list[Extreme]:
    """Rays that graze a sphere's silhouette, and a concave bowl."""
    return [
        Extreme(
            "sphere R 20 at 5 deg (silhouette)",
            "silhouette",
            sphere.updated(surface={"radius": 20.0}, camera={"theta_deg": 5.0}),
            "rays graze the silhouette: the hit moves ~1/cos(incidence) per unit of ray error",
            uv_tolerance_fp32=2e-3,
        ),
        Extreme(
            "concave bowl R -20 at 30 deg",
            "silhouette",
            sphere.updated(surface={"radius": -20.0}, camera={"theta_deg": 30.0}),
        ),
    ]


def _emitter_cases(bases: _Bases) -> list[Extreme]:
    """A tiny emitter, and one the reflected rays see edge-on."""
    return [
        Extreme(
            "tiny emitter 0.5 mm", "emitter", bases.flat.updated(emitter={"half_size": [0.5, 0.5]})
        ),
        Extreme(
            "emitter edge-on (sphere R 5 at 85 deg)",
            "emitter",
            bases.sphere.updated(surface={"radius": 5.0}, camera={"theta_deg": 85.0}),
            "reflected rays sweep past the emitter's plane",
        ),
    ]


def cases() -> list[Extreme]:
    """The stability matrix: every stiff or extreme case, grouped by what it stresses."""
    bases = _bases()
    return [
        *_view_cases(bases),
        *_dent_cases(bases.flat),
        *_covariance_cases(bases),
        *_radius_cases(bases),
        *_silhouette_cases(bases.sphere),
        *_emitter_cases(bases),
    ]


def views(scene: Scene) -> dict[str, Scene]:
    """The centre crop of the paper's camera and the whole field at 48x48."""
    cam = scene.camera
    centre = replace(scene, camera=replace(cam, width=32, height=32))
    return {"centre": centre, "field": scene.with_size(48)}


@dataclass(frozen=True)
class Check:
    """Measured agreement of one view of one case at one precision."""

    case: str
    view: str
    precision: str
    pixels: int
    emitter_pixels: int
    nonfinite: int  # NaN/Inf inside the mask, or in the image anywhere
    mask_mismatch: int  # pixels whose emitter hit disagrees with the oracle
    surface_mismatch: int  # pixels whose surface hit disagrees with the oracle
    distance_error: float  # max |distance - oracle t| / t where both reach the emitter
    distance_error_all: float  # the same over every pixel where both hit the surface
    uv_error_mm: float  # max over pixels both reach the emitter
    image_error: float
    max_iterations: int
    iteration_histogram: tuple[int, ...]


OUTPUTS = ("image", "uv", "mask", "distance", "iterations")


def check(
    renderer: Renderer, case: Extreme, view: str, precision: str, scene: Scene | None = None
) -> Check:
    scene = (scene or views(case.scene)[view]).updated(render={"precision": precision})
    frame: Frame = renderer.render(scene, OUTPUTS)
    expected = reference.trace(scene, ("image", "uv", "mask"))
    origin, directions = reference.pixel_rays(scene.camera)
    t, _, _, hit = reference.first_hit(scene, origin, directions.reshape(-1, 3))
    mask, image, uv = frame.output("mask"), frame.output("image"), frame.output("uv")
    distance = frame.output("distance")
    want_mask, want_image, want_uv = (expected.output(name) for name in ("mask", "image", "uv"))
    t = t.reshape(mask.shape)
    hit = hit.reshape(mask.shape)

    nonfinite = int((~np.isfinite(image)).sum() + (~np.isfinite(uv[mask])).sum())
    gpu_hit = np.isfinite(distance)
    both_hit = gpu_hit & hit
    both = mask & want_mask
    iterations = frame.output("iterations").astype(int)
    return Check(
        case=case.name,
        view=view,
        precision=precision,
        pixels=mask.size,
        emitter_pixels=int(both.sum()),
        nonfinite=nonfinite,
        mask_mismatch=int((mask != want_mask).sum()),
        surface_mismatch=int((gpu_hit != hit).sum()),
        distance_error=_relative(distance, t, both_hit & both),
        distance_error_all=_relative(distance, t, both_hit),
        uv_error_mm=float(np.abs(uv[both] - want_uv[both]).max()) if both.any() else 0.0,
        image_error=float(np.abs(image[both] - want_image[both]).max()) if both.any() else 0.0,
        max_iterations=int(iterations.max()),
        iteration_histogram=tuple(np.bincount(iterations.ravel()).tolist()),
    )


def _relative(actual: np.ndarray, expected: np.ndarray, where: np.ndarray) -> float:
    if not where.any():
        return 0.0
    return float((np.abs(actual[where] - expected[where]) / expected[where]).max())


#: The renderer's default root solver (what :func:`iteration_cap` bounds unless told).
_DEFAULT_SOLVER = RootSolver()


def iteration_cap(solver: RootSolver = _DEFAULT_SOLVER) -> int:
    """Most evaluations of g per ray: the start, the march, the bracket end, Newton."""
    return 2 + solver.march_steps + solver.newton_iterations
