"""Which AIST++ camera files an ingest needs, and the cameras table built from them.

``cameras/mapping.txt`` names each sequence's setting; ``cameras/<setting>.json`` holds its 9
calibrated cameras. Only the settings of the ingested sequences are read and stored. A
sequence the mapping does not name, or whose setting file is absent, has no cameras
(``camera_setting`` null): a missing annotation kind, reported by ``info``, not an error.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dancedata.errors import InputError
from dancedata.io.aist_cameras import AistCamera, read_camera_mapping, read_camera_setting
from dancedata.io.aist_keypoints import N_VIEWS
from dancedata.read.cameras import cameras_table

MAPPING_FILE = "mapping.txt"


@dataclass
class CameraInputs:
    """The mapping file, each selected sequence's setting, and the settings read."""

    mapping_file: Path | None = None
    setting_of: dict[str, str] = field(default_factory=dict)  # seq_id → setting, when read
    setting_files: dict[str, Path] = field(default_factory=dict)  # setting → json
    settings: dict[str, list[AistCamera]] = field(default_factory=dict)
    skipped: list[dict[str, str]] = field(default_factory=list)

    def files(self) -> list[Path]:
        found = [] if self.mapping_file is None else [self.mapping_file]
        return found + [self.setting_files[s] for s in sorted(self.setting_files)]


def _read_setting(path: Path) -> list[AistCamera]:
    cameras = read_camera_setting(path)
    if len(cameras) != N_VIEWS:
        raise InputError(f"expected {N_VIEWS} cameras, found {len(cameras)}", path)
    return cameras


def find_camera_inputs(raw: Path, seq_ids: list[str], on_error: str = "fail") -> CameraInputs:
    """Read the camera files under ``raw/cameras`` that ``seq_ids`` use (nothing when there is
    no mapping). Each setting must hold the 9 AIST++ views, in c01…c09 order as keypoints2d;
    a bad setting file is an InputError, or with ``on_error="skip"`` recorded in ``skipped``
    and its sequences left without cameras."""
    mapping_file = raw / "cameras" / MAPPING_FILE
    if not mapping_file.is_file():
        return CameraInputs()
    mapping = read_camera_mapping(mapping_file)
    inputs = CameraInputs(mapping_file=mapping_file)
    bad: set[str] = set()
    for seq_id in seq_ids:
        setting = mapping.get(seq_id)
        if setting is None or setting in bad:
            continue
        path = raw / "cameras" / f"{setting}.json"
        if setting not in inputs.settings:
            if not path.is_file():
                continue
            try:
                inputs.settings[setting] = _read_setting(path)
            except InputError as exc:
                if on_error != "skip":
                    raise
                inputs.skipped.append({"path": str(path), "error": exc.problem})
                bad.add(setting)
                continue
            inputs.setting_files[setting] = path
        inputs.setting_of[seq_id] = setting
    return inputs


def cameras_table_rows(
    inputs: CameraInputs, used: set[str], checksums: dict[str, str]
) -> list[dict[str, Any]]:
    """Cameras-table rows of the ``used`` settings, in setting order (the rows themselves are
    :func:`dancedata.read.cameras.cameras_table`'s)."""
    return cameras_table({s: inputs.settings[s] for s in used}, inputs.setting_files, checksums)
