"""The ``cameras`` table, built and read back in one place: one row per (setting, camera).

Parsed setting files (:mod:`dancedata.io.aist_cameras`) become rows here
(:func:`cameras_table`), and rows become a :class:`CameraSet` of OpenCV parameters
(:func:`camera_set`); the projection math is :mod:`dancedata.compute.camera`.

Row layout (scalar columns, so any Parquet reader can use them):

    setting, camera (c01…), view (index on the views axis of motion/keypoints2d),
    width, height (pixels), fx, fy, cx, cy, skew (pixels),
    rx, ry, rz (Rodrigues vector, radians, world → camera),
    tx_m, ty_m, tz_m (world → camera translation, **metres**),
    k1, k2, p1, p2, k3 (OpenCV distortion coefficients), path, sha256 (the setting file)

AIST++ gives the translation in centimetres, like its keypoints3d; the store divides it by 100
so that cameras and ``motion/keypoints3d`` share one unit (projection is unchanged by a common
scale: x_c = R X + t scales as a whole). A sequence names its setting in the sequences column
``camera_setting``.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.compute.camera import projection_matrix, rodrigues_to_rotmat
from dancedata.io.aist_cameras import AistCamera

CM_PER_M = 100.0
DISTORTION_COLUMNS: tuple[str, ...] = ("k1", "k2", "p1", "p2", "k3")


def camera_rows(
    setting: str, cameras: list[AistCamera], path: str, sha256: str | None
) -> list[dict[str, Any]]:
    """Cameras-table rows of one setting, translation converted from cm to metres."""
    rows = []
    for view, cam in enumerate(cameras):
        k = cam.matrix
        rows.append(
            {
                "setting": setting,
                "camera": cam.name,
                "view": view,
                "width": cam.width,
                "height": cam.height,
                "fx": k[0][0],
                "fy": k[1][1],
                "cx": k[0][2],
                "cy": k[1][2],
                "skew": k[0][1],
                "rx": cam.rotation[0],
                "ry": cam.rotation[1],
                "rz": cam.rotation[2],
                "tx_m": cam.translation_cm[0] / CM_PER_M,
                "ty_m": cam.translation_cm[1] / CM_PER_M,
                "tz_m": cam.translation_cm[2] / CM_PER_M,
                **dict(zip(DISTORTION_COLUMNS, cam.distortions, strict=True)),
                "path": path,
                "sha256": sha256,
            }
        )
    return rows


def cameras_table(
    settings: Mapping[str, list[AistCamera]],
    files: Mapping[str, str | Path],
    checksums: Mapping[str, str],
) -> list[dict[str, Any]]:
    """Cameras-table rows of every setting in ``settings`` (setting → its cameras in file
    order), settings in sorted order; ``files`` maps each setting to its JSON file (recorded as
    ``path``), ``checksums`` that path (as str) to its sha256."""
    rows: list[dict[str, Any]] = []
    for setting in sorted(settings):
        path = str(files[setting])
        rows += camera_rows(setting, settings[setting], path, checksums.get(path))
    return rows


@dataclass(frozen=True)
class CameraSet:
    """The calibrated cameras of one setting, in view order, as OpenCV wants them.

    ``cv2.projectPoints(X_m, rvec[i], tvec_m[i], intrinsics[i], distortions[i])`` projects
    world points in metres into view i; ``projection`` is the undistorted P = K [R | t]."""

    setting: str
    names: list[str]
    sizes: np.ndarray  # (C, 2) int64 width, height in pixels
    intrinsics: np.ndarray  # (C, 3, 3) pixels
    rvec: np.ndarray  # (C, 3) Rodrigues, radians
    rotmat: np.ndarray  # (C, 3, 3)
    tvec_m: np.ndarray  # (C, 3) metres
    distortions: np.ndarray  # (C, 5) k1, k2, p1, p2, k3

    @property
    def projection(self) -> np.ndarray:
        """(C, 3, 4) P = K [R | t] for world points in metres."""
        return projection_matrix(self.intrinsics, self.rotmat, self.tvec_m)


def camera_set(rows: Iterable[dict[str, Any]], setting: str) -> CameraSet:
    """The :class:`CameraSet` of ``setting`` from cameras-table rows (any order)."""
    mine = sorted((r for r in rows if r["setting"] == setting), key=lambda r: r["view"])
    if not mine:
        raise KeyError(setting)
    intrinsics = np.zeros((len(mine), 3, 3))
    intrinsics[:, 0, 0] = [r["fx"] for r in mine]
    intrinsics[:, 0, 1] = [r["skew"] for r in mine]
    intrinsics[:, 0, 2] = [r["cx"] for r in mine]
    intrinsics[:, 1, 1] = [r["fy"] for r in mine]
    intrinsics[:, 1, 2] = [r["cy"] for r in mine]
    intrinsics[:, 2, 2] = 1.0
    rvec = np.array([[r["rx"], r["ry"], r["rz"]] for r in mine], dtype=np.float64)
    return CameraSet(
        setting=setting,
        names=[r["camera"] for r in mine],
        sizes=np.array([[r["width"], r["height"]] for r in mine], dtype=np.int64),
        intrinsics=intrinsics,
        rvec=rvec,
        rotmat=rodrigues_to_rotmat(rvec),
        tvec_m=np.array([[r["tx_m"], r["ty_m"], r["tz_m"]] for r in mine], dtype=np.float64),
        distortions=np.array([[r[c] for c in DISTORTION_COLUMNS] for r in mine], np.float64),
    )
