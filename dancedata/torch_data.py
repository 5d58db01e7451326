"""PyTorch access to the measures of a store (torch is optional and imported on use).

    from dancedata.torch_data import MeasureDataset
    ds = MeasureDataset("data/stores/aist-demo", split="train")
    item = ds[0]   # {"motion": (T, 225) tensor, "audio": (T, 35) tensor, "genre": (G,), ...}

Measures differ in length when tempi differ; use ``batch_size=1`` or a padding ``collate_fn``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from dancedata.loader import DanceStore, MeasureWindow


def _torch() -> Any:
    try:
        import torch
    except ImportError:
        raise ImportError(
            "dancedata.torch_data needs PyTorch: pip install torch (or dancedata[stems])"
        ) from None
    return torch


class MeasureDataset:
    """A map-style dataset (``torch.utils.data.Dataset`` protocol) of measure windows."""

    def __init__(
        self,
        store: str | Path | DanceStore,
        split: str | None = None,
        scheme: str = "crossmodal",
        motion: str | None = "fact_motion_225",
        audio: str | None = "fact_audio_35",
        version: str | None = None,
    ) -> None:
        self._torch = _torch()
        self.store = store if isinstance(store, DanceStore) else DanceStore(store, version)
        self.windows: list[MeasureWindow] = list(
            self.store.iter_measures(split=split, scheme=scheme, motion=motion, audio=audio)
        )

    def __len__(self) -> int:
        return len(self.windows)

    def __getitem__(self, index: int) -> dict[str, Any]:
        window = self.windows[index]
        torch = self._torch
        item: dict[str, Any] = {
            "seq_id": window.seq_id,
            "measure": window.measure,
            "genre": torch.from_numpy(window.genre_onehot),
        }
        if window.motion is not None:
            item["motion"] = torch.from_numpy(window.motion.copy())
        if window.audio is not None:
            item["audio"] = torch.from_numpy(window.audio.copy())
        return item
