"""The in-between transformer of docs/EXPERIMENTS.md §3.3 (thesis 000 §3.5.3, App. A), size
configurable.

Input per frame: ``X_lin``, the measure's evenly spaced keyframes interpolated by linear
translation + quaternion SLERP (§3.1) in the 225-d FACT layout (6 zeros + trans + 24 row-major
3×3), plus, per variant, the 9/G-d genre one-hot or per-frame audio features. Output: the
residual ``D_rotmat − X_lin``; the reconstruction is ``X_lin + f(·)``.

* ``motion``: X_lin → input projection → self-attention encoder.
* ``genre``: concat(genre broadcast over frames, X_lin) → self-attention encoder.
* ``merged_full`` / ``merged_drum``: audio → audio encoder; concat(audio encoding, X_lin) →
  self-attention encoder.
* ``cross_full`` / ``cross_drum``: audio → audio encoder (memory); X_lin → decoder layers
  (self-attention, cross-attention to the audio, MLP).

Thesis size: d_model 800, 4 layers, 10 heads, MLP 3072, dropout 0.1, GELU (the thesis says
"softmax", which is the attention's normalisation; GELU follows FACT/mint, §3.3). The audio
encoder's depth is not stated; it uses the same number of layers. Pre-norm layers (as mint's
``base_models.Transformer``). Learned absolute positional embeddings of ``max_len`` frames. The
final projection starts at zero, so an untrained model returns X_lin exactly (the baseline) and
training can only move away from it where the train loss says so.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import torch
from torch import nn

MOTION_DIM = 225
VARIANTS = ("motion", "genre", "merged_full", "merged_drum", "cross_full", "cross_drum")

# Presets: the thesis's size (App. A) and the reduced size that trains on CPU in minutes.
SIZES: dict[str, dict[str, int]] = {
    "thesis": {"d_model": 800, "layers": 4, "heads": 10, "ffn": 3072},
    "small": {"d_model": 64, "layers": 2, "heads": 4, "ffn": 256},
    "tiny": {"d_model": 32, "layers": 1, "heads": 2, "ffn": 64},
}


@dataclass(frozen=True)
class ModelConfig:
    """Every architectural choice, saved in the checkpoint."""

    variant: str = "motion"
    d_model: int = 64
    layers: int = 2
    heads: int = 4
    ffn: int = 256
    dropout: float = 0.1
    max_len: int = 180
    genre_dim: int = 0
    audio_dim: int = 0

    def __post_init__(self) -> None:
        if self.variant not in VARIANTS:
            raise ValueError(f"unknown variant {self.variant!r}; known: {', '.join(VARIANTS)}")
        if self.d_model % self.heads:
            raise ValueError(f"d_model {self.d_model} is not divisible by heads {self.heads}")
        if self.uses_audio and self.audio_dim <= 0:
            raise ValueError(f"variant {self.variant} needs audio features (audio_dim > 0)")
        if self.variant == "genre" and self.genre_dim <= 0:
            raise ValueError("variant genre needs the genre one-hot width (genre_dim > 0)")

    @property
    def uses_audio(self) -> bool:
        return self.variant.startswith(("merged", "cross"))

    def as_dict(self) -> dict[str, object]:
        return asdict(self)


def _encoder(cfg: ModelConfig, width: int) -> nn.TransformerEncoder:
    layer = nn.TransformerEncoderLayer(
        width,
        cfg.heads,
        cfg.ffn,
        cfg.dropout,
        activation="gelu",
        batch_first=True,
        norm_first=True,
    )
    return nn.TransformerEncoder(layer, cfg.layers, enable_nested_tensor=False)


class InbetweenTransformer(nn.Module):
    """f(X_lin, genre, audio) → residual (B, T, 225); see the module docstring."""

    def __init__(self, cfg: ModelConfig) -> None:
        super().__init__()
        self.cfg = cfg
        d = cfg.d_model
        in_dim = MOTION_DIM
        if cfg.variant == "genre":
            in_dim += cfg.genre_dim
        if cfg.variant.startswith("merged"):
            in_dim += d
        self.input = nn.Linear(in_dim, d)
        self.position = nn.Parameter(torch.zeros(1, cfg.max_len, d))
        nn.init.normal_(self.position, std=0.02)
        if cfg.uses_audio:
            self.audio_input = nn.Linear(cfg.audio_dim, d)
            self.audio_position = nn.Parameter(torch.zeros(1, cfg.max_len, d))
            nn.init.normal_(self.audio_position, std=0.02)
            self.audio_encoder = _encoder(cfg, d)
        if cfg.variant.startswith("cross"):
            layer = nn.TransformerDecoderLayer(
                d,
                cfg.heads,
                cfg.ffn,
                cfg.dropout,
                activation="gelu",
                batch_first=True,
                norm_first=True,
            )
            self.decoder = nn.TransformerDecoder(layer, cfg.layers)
        else:
            self.encoder = _encoder(cfg, d)
        self.norm = nn.LayerNorm(d)
        self.output = nn.Linear(d, MOTION_DIM)
        nn.init.zeros_(self.output.weight)
        nn.init.zeros_(self.output.bias)

    def forward(
        self,
        x_lin: torch.Tensor,
        pad_mask: torch.Tensor,
        genre: torch.Tensor | None = None,
        audio: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """x_lin (B, T, 225), pad_mask (B, T) True at padding, genre (B, G), audio (B, T, A)
        → residual (B, T, 225); the six FACT padding columns are always 0."""
        b, t, _ = x_lin.shape
        if t > self.cfg.max_len:
            raise ValueError(f"{t} frames exceed the model's max_len {self.cfg.max_len}")
        parts = [x_lin]
        memory = None
        if self.cfg.uses_audio:
            if audio is None:
                raise ValueError(f"variant {self.cfg.variant} needs audio")
            a = self.audio_input(audio) + self.audio_position[:, :t]
            memory = self.audio_encoder(a, src_key_padding_mask=pad_mask)
            if self.cfg.variant.startswith("merged"):
                parts.insert(0, memory)
        if self.cfg.variant == "genre":
            if genre is None:
                raise ValueError("variant genre needs the genre one-hot")
            parts.insert(0, genre[:, None, :].expand(b, t, genre.shape[-1]))
        h = self.input(torch.cat(parts, dim=-1)) + self.position[:, :t]
        if self.cfg.variant.startswith("cross"):
            h = self.decoder(
                h, memory, tgt_key_padding_mask=pad_mask, memory_key_padding_mask=pad_mask
            )
        else:
            h = self.encoder(h, src_key_padding_mask=pad_mask)
        out = self.output(self.norm(h))
        return torch.cat([torch.zeros_like(out[..., :6]), out[..., 6:]], dim=-1)
