"""The station that took a SOFAST (Sandia OpenCSP) measurement, read from its own files
(docs/twin.md): the camera (OpenCV intrinsics and distortion), the screen's calibrated
shape (screen fractions -> screen coordinates), the camera-screen pose, and the facet's
definition. Lengths are converted from the files' metres to mm on reading.

OpenCSP's conventions, kept: a pose ``r_cam_screen`` (a rotation vector) and
``v_cam_screen_cam`` mean that a point ``p_screen`` in screen coordinates is
``R(r_cam_screen)^-1 p_screen + v_cam_screen_cam`` in camera coordinates (OpenCV's camera
frame: x right, y down, z forward); a camera pixel's ray is ``cv2.undistortPoints`` of
its integer (column, row) index, as OpenCSP's ``Camera.vector_from_pixel``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from glshade.errors import GlshadeError

M_TO_MM = 1000.0

#: The station's files, as OpenCSP names them, looked for beside a measurement.
STATION_FILES = {
    "camera": "camera_sofast_downsampled.h5",
    "display": "display_distorted_2d.h5",
    "orientation": "spatial_orientation.h5",
    "facet": "Facet_NSTTF.json",
    "calibration": "image_calibration.h5",
}


@dataclass(frozen=True)
class SofastCamera:
    """OpenCV's camera model: ``matrix`` K (3 x 3, pixels), ``distortion`` (k1, k2, p1,
    p2, k3), ``size`` (width, height) in pixels."""

    matrix: NDArray[np.float64]
    distortion: NDArray[np.float64]
    size: tuple[int, int]
    name: str = ""

    def rays(self, columns: NDArray[Any], rows: NDArray[Any]) -> NDArray[np.float64]:
        """Unit rays (N, 3) in camera coordinates of the pixels at integer ``columns``,
        ``rows`` (pixel centres, OpenCV's convention), distortion undone."""
        import cv2

        pixels = np.stack([columns, rows], axis=-1).astype(np.float64).reshape(-1, 1, 2)
        ideal = cv2.undistortPoints(pixels, self.matrix, self.distortion)[:, 0, :]
        rays = np.concatenate([ideal, np.ones((ideal.shape[0], 1))], axis=1)
        return rays / np.linalg.norm(rays, axis=1, keepdims=True)

    def project(
        self, points: NDArray[np.float64], rvec: NDArray[np.float64], tvec: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """Pixels (N, 2) of object ``points`` (N, 3) posed by OpenCV's ``rvec``, ``tvec``."""
        import cv2

        out, _ = cv2.projectPoints(
            np.asarray(points, np.float64).reshape(-1, 1, 3),
            np.asarray(rvec, np.float64),
            np.asarray(tvec, np.float64),
            self.matrix,
            self.distortion,
        )
        return np.asarray(out[:, 0, :], np.float64)


@dataclass(frozen=True)
class SofastDisplay:
    """The screen's calibrated shape ('distorted2D'): ``fractions`` (2, M) screen
    fractions (x, y) and ``points_mm`` (2, M) where they lie on the flat screen, in
    screen coordinates (mm). Between them it interpolates linearly on their Delaunay
    triangles, as OpenCSP's ``DisplayShape`` does; outside them a point is NaN."""

    fractions: NDArray[np.float64]
    points_mm: NDArray[np.float64]
    model: str = "distorted2D"
    name: str = ""
    _interpolator: Any = field(default=None, compare=False, repr=False)

    def screen_mm(self, x: NDArray[Any], y: NDArray[Any]) -> NDArray[np.float64]:
        """Screen points (N, 3) in mm, screen coordinates (z = 0 on the flat screen), of
        screen fractions ``x``, ``y`` (N,)."""
        interp = self._interpolator
        if interp is None:
            from scipy.interpolate import LinearNDInterpolator

            interp = LinearNDInterpolator(self.fractions.T, self.points_mm.T)
            object.__setattr__(self, "_interpolator", interp)
        xy = np.asarray(interp(np.ravel(x), np.ravel(y)), np.float64).reshape(-1, 2)
        return np.concatenate([xy, np.zeros((xy.shape[0], 1))], axis=1)

    def affine(self) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
        """The best affine map fraction -> screen mm, ``(matrix (2, 2), offset (2,),
        rms mm)``: the flat, rectangular screen nearest this one, and how far the
        calibrated shape departs from it."""
        design = np.concatenate([self.fractions.T, np.ones((self.fractions.shape[1], 1))], 1)
        coef, *_ = np.linalg.lstsq(design, self.points_mm.T, rcond=None)
        rms = float(np.sqrt(np.mean((design @ coef - self.points_mm.T) ** 2)))
        return coef[:2].T, coef[2], rms


@dataclass(frozen=True)
class SofastFacet:
    """A facet's definition: ``corners_mm`` (4, 3) and ``centroid_mm`` (3,) in facet
    coordinates (z along the facet's normal)."""

    corners_mm: NDArray[np.float64]
    centroid_mm: NDArray[np.float64]


@dataclass(frozen=True)
class SofastStation:
    """A SOFAST station: camera, display shape, the camera-screen pose (OpenCSP's
    ``r_cam_screen`` rotation vector and ``v_cam_screen_cam`` in mm) and the facet."""

    camera: SofastCamera
    display: SofastDisplay
    r_cam_screen: NDArray[np.float64]
    v_cam_screen_cam_mm: NDArray[np.float64]
    facet: SofastFacet
    sources: tuple[str, ...] = ()

    def screen_to_camera(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(R, t)``: a screen point p (mm) is ``R p + t`` in camera coordinates."""
        from glshade.poses import rodrigues

        return rodrigues(self.r_cam_screen).T, np.asarray(self.v_cam_screen_cam_mm, np.float64)


def _text(value: object) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def _group(path: Path, name: str) -> Any:
    import h5py

    try:
        h5 = h5py.File(path, "r")
    except OSError as exc:
        raise GlshadeError(f"{path}: not a readable HDF5 file ({exc})") from None
    if name not in h5:
        h5.close()
        raise GlshadeError(f"{path}: no '{name}' group (an OpenCSP {name} file expected)")
    return h5


def _read(path: Path, group: str, keys: tuple[str, ...]) -> dict[str, Any]:
    h5 = _group(path, group)
    try:
        missing = [k for k in keys if f"{group}/{k}" not in h5]
        if missing:
            raise GlshadeError(f"{path}: {group} lacks {', '.join(missing)}")
        return {k: h5[f"{group}/{k}"][()] for k in keys}
    finally:
        h5.close()


def read_sofast_camera(path: str | Path) -> SofastCamera:
    """An OpenCSP ``Camera`` HDF5 file."""
    values = _read(
        Path(path), "Camera", ("intrinsic_mat", "distortion_coef", "image_shape_xy", "name")
    )
    size = tuple(int(v) for v in np.ravel(values["image_shape_xy"]))
    return SofastCamera(
        matrix=np.asarray(values["intrinsic_mat"], np.float64).reshape(3, 3),
        distortion=np.asarray(values["distortion_coef"], np.float64).ravel(),
        size=(size[0], size[1]),
        name=_text(values["name"]),
    )


def read_sofast_display(path: str | Path) -> SofastDisplay:
    """An OpenCSP ``DisplayShape`` HDF5 file of the 'distorted2D' model (metres -> mm)."""
    path = Path(path)
    h5 = _group(path, "DisplayShape")
    try:
        model = _text(h5["DisplayShape/screen_model"][()])
        if model != "distorted2D":
            raise GlshadeError(f"{path}: screen model '{model}'; glshade reads 'distorted2D'")
        return SofastDisplay(
            fractions=np.asarray(h5["DisplayShape/xy_screen_fraction"][()], np.float64),
            points_mm=M_TO_MM * np.asarray(h5["DisplayShape/xy_screen_coords"][()], np.float64),
            model=model,
            name=_text(h5["DisplayShape/name"][()]) if "DisplayShape/name" in h5 else "",
        )
    finally:
        h5.close()


def read_sofast_orientation(path: str | Path) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """An OpenCSP ``SpatialOrientation`` file: ``(r_cam_screen, v_cam_screen_cam mm)``."""
    values = _read(Path(path), "SpatialOrientation", ("r_cam_screen", "v_cam_screen_cam"))
    rvec = np.asarray(values["r_cam_screen"], np.float64).ravel()
    return rvec, M_TO_MM * np.asarray(values["v_cam_screen_cam"], np.float64).ravel()


def read_sofast_facet(path: str | Path) -> SofastFacet:
    """An OpenCSP facet definition (JSON: ``v_facet_corners``, ``v_centroid_facet``)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
        corners = np.array([data["v_facet_corners"][k] for k in "xyz"], np.float64).T
        centroid = np.array([data["v_centroid_facet"][k] for k in "xyz"], np.float64).ravel()
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise GlshadeError(f"{path}: not an OpenCSP facet definition ({exc})") from None
    return SofastFacet(corners_mm=M_TO_MM * corners, centroid_mm=M_TO_MM * centroid)


def station_paths(folder: str | Path) -> dict[str, Path]:
    """The station's files in ``folder`` under OpenCSP's names (:data:`STATION_FILES`)."""
    return {key: Path(folder) / name for key, name in STATION_FILES.items()}


def read_sofast_station(
    camera: str | Path, display: str | Path, orientation: str | Path, facet: str | Path
) -> SofastStation:
    """The station from its four files."""
    rvec, tvec = read_sofast_orientation(orientation)
    return SofastStation(
        camera=read_sofast_camera(camera),
        display=read_sofast_display(display),
        r_cam_screen=rvec,
        v_cam_screen_cam_mm=tvec,
        facet=read_sofast_facet(facet),
        sources=tuple(str(p) for p in (camera, display, orientation, facet)),
    )
