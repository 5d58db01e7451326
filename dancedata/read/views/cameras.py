"""The AIST++ cameras of a sequence: its ``camera_setting`` looked up in the cameras table.

The table's rows become a :class:`dancedata.read.cameras.CameraSet` (OpenCV parameters, translation
in metres); projection itself is :mod:`dancedata.compute.camera`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from dancedata.errors import StoreError
from dancedata.read.cameras import CameraSet, camera_set

if TYPE_CHECKING:
    from dancedata.read.sequence_reader import _SequenceReader


def sequence_cameras(store: _SequenceReader, seq_id: str) -> CameraSet:
    """The calibrated cameras of the sequence's AIST++ setting, in the view order of
    ``motion/keypoints2d``; StoreError when the sequence or the store has none."""
    setting = store.sequence(seq_id).get("camera_setting")
    if not setting or not store.has_table("cameras"):
        raise StoreError(f"sequence {seq_id} has no cameras in this store", store.path)
    return camera_set(store.table("cameras").to_pylist(), setting)
