"""Read AIST++ camera calibrations: ``cameras/<setting>.json`` and ``cameras/mapping.txt``.

A setting file is a JSON list of 9 cameras, each with ``name`` (c01…c09), ``size`` [width,
height] in pixels, ``matrix`` (3×3 intrinsics, pixels), ``distortions`` (OpenCV k1, k2, p1, p2,
k3), ``rotation`` (Rodrigues vector, radians, world → camera) and ``translation`` (world →
camera, **centimetres**, the unit of ``keypoints3d``). ``mapping.txt`` has one
``<seq> <setting>`` pair per line.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

from dancedata.errors import InputError

N_DISTORTIONS = 5  # OpenCV order: k1, k2, p1, p2, k3


@dataclass(frozen=True)
class AistCamera:
    """One calibrated camera of a setting, in AIST++ units (translation in cm)."""

    name: str
    width: int
    height: int
    matrix: tuple[tuple[float, ...], ...]  # 3×3, pixels
    distortions: tuple[float, ...]  # k1, k2, p1, p2, k3
    rotation: tuple[float, ...]  # 3: Rodrigues, radians, world → camera
    translation_cm: tuple[float, ...]  # 3: world → camera, cm


def _numbers(value: object, n: int, what: str, path: Path) -> tuple[float, ...]:
    if not isinstance(value, list) or len(value) != n:
        raise InputError(f"{what} must be a list of {n} numbers", path)
    out = []
    for item in value:
        if isinstance(item, bool) or not isinstance(item, int | float) or not math.isfinite(item):
            raise InputError(f"{what} holds {item!r}, expected a finite number", path)
        out.append(float(item))
    return tuple(out)


def _camera(entry: object, index: int, path: Path) -> AistCamera:
    if not isinstance(entry, dict):
        raise InputError(f"camera {index} is not a JSON object", path)
    missing = [
        k
        for k in ("name", "size", "matrix", "distortions", "rotation", "translation")
        if k not in entry
    ]
    label = f"camera {entry['name']}" if "name" in entry else f"camera {index + 1} (no name)"
    if missing:
        raise InputError(f"{label} lacks {missing}", path)
    name = str(entry["name"])
    width, height = _numbers(entry["size"], 2, f"{label} size", path)
    if not isinstance(entry["matrix"], list) or len(entry["matrix"]) != 3:
        raise InputError(f"{label} matrix must be 3×3", path)
    matrix = tuple(_numbers(row, 3, f"{label} matrix row", path) for row in entry["matrix"])
    if matrix[2] != (0.0, 0.0, 1.0) or matrix[1][0] != 0.0:
        raise InputError(f"{label} matrix is not an intrinsic matrix (last row 0 0 1)", path)
    distortions = entry["distortions"]
    if isinstance(distortions, list) and len(distortions) == 4:
        distortions = [*distortions, 0.0]
    return AistCamera(
        name=name,
        width=int(width),
        height=int(height),
        matrix=matrix,
        distortions=_numbers(distortions, N_DISTORTIONS, f"{label} distortions", path),
        rotation=_numbers(entry["rotation"], 3, f"{label} rotation", path),
        translation_cm=_numbers(entry["translation"], 3, f"{label} translation", path),
    )


def read_camera_setting(path: str | Path) -> list[AistCamera]:
    """The cameras of one setting file, in file order (c01…c09)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path) from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"not a JSON camera file ({exc})", path) from None
    if not isinstance(data, list) or not data:
        raise InputError("expected a JSON list of cameras", path)
    cameras = [_camera(entry, i, path) for i, entry in enumerate(data)]
    names = [c.name for c in cameras]
    if len(set(names)) != len(names):
        raise InputError(f"camera names repeat: {names}", path)
    return cameras


def read_camera_mapping(path: str | Path) -> dict[str, str]:
    """``{seq_id: setting}`` from ``mapping.txt`` (blank lines ignored, fields stripped)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path) from None
    except UnicodeDecodeError:
        raise InputError("camera mapping is not UTF-8 text", path) from None
    mapping: dict[str, str] = {}
    for number, line in enumerate(text.splitlines(), start=1):
        fields = line.split()
        if not fields:
            continue
        if len(fields) != 2:
            raise InputError(f"line {number}: expected '<seq> <setting>', found {line!r}", path)
        mapping[fields[0]] = fields[1]
    return mapping
