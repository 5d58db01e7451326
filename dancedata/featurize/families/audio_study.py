"""Study feature sets as audio families, computed only on request (``--audio-families``).

All run at the store's feature rate (``cfg.fps`` rows per second, sr = fps × hop Hz) and give
A = 1 + n // hop rows for a track of n samples, like the FACT features, so nothing is trimmed.

``mel96``
    ChoreoGraph (ACM MM 2022): ``audio/mel96`` (A, 96) float32, log-power mel spectrogram in dB
    (``librosa.feature.melspectrogram``, Hann, n_fft = cfg.n_fft, hop = cfg.hop_length, 96 bands
    up to sr / 2, then ``power_to_db``: ref 1, 80 dB below the peak floored).
``stft_frames``
    Genre-based dance generation (MSc 2019): ``audio/stft_frames`` (A, 1025, k) float32 STFT
    magnitudes. The track is resampled to ``stft_sr`` Hz (16000) and cut into one chunk of
    L = round(stft_sr / fps) samples per feature frame (chunk i starts at round(i · stft_sr / fps)
    samples, zero-padded past the end); each chunk gets its own centred Hann STFT, hop 200,
    n_fft 2048, so k = 1 + L // 200 STFT frames per chunk. At 60 fps L = 267, k = 2 (2050 values
    per frame); at 30 fps L = 533, k = 3. The dissertation's 1025 × 6 = 6150 values per frame
    needs chunks of 1000–1199 samples (e.g. 32 kHz at 30 fps, or 16 kHz at 15 fps); its text
    gives 16 kHz at 30 fps, which cannot produce 6 frames per chunk with hop 200, so the stored
    k follows the parameters (``--stft-sr``) and is recorded in the array attrs.
``tempogram``
    ``audio/tempogram`` (A, W) float32, the local autocorrelation tempogram of the mix's onset
    envelope (``librosa.feature.tempogram``, window W = ``tempogram_frames`` = 384 frames,
    6.4 s at 60 fps); column j is a lag of j frames, 60 · sr / (hop · j) BPM.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dancedata.compute.audio_features import AudioFeatureConfig
from dancedata.compute.study_features import (
    CHOREOGRAPH_N_MELS,
    GENRE_STFT_HOP,
    GENRE_STFT_N_FFT,
    frames_per_chunk,
)
from dancedata.featurize.families.audio_base import (
    ArraySpec,
    AudioFamily,
    AudioSettings,
    TrackAudio,
)
from dancedata.featurize.family import register_family

_DEFAULT = AudioSettings()
MEL_TOP_DB = 80.0


def _frames(track: TrackAudio) -> int:
    """Feature frames of the track: 1 + n // hop (the count of every centred-STFT feature)."""
    return 1 + track.y.shape[0] // track.cfg.hop_length


@register_family("mel96")
class Mel96Family(AudioFamily):
    """ChoreoGraph's 96-bin mel spectrogram at the motion frame rate."""

    outputs = (
        ArraySpec(
            "mel96",
            (CHOREOGRAPH_N_MELS,),
            np.float32,
            required_attrs=("n_mels", "units"),
            extension=True,
            note="ChoreoGraph: log-power mel (dB) at the motion frame rate",
        ),
    )

    def arrays(
        self, cfg: AudioFeatureConfig, settings: AudioSettings | None = None
    ) -> list[ArraySpec]:
        attrs = {
            "n_mels": CHOREOGRAPH_N_MELS,
            "units": "dB",
            "recipe": "librosa.feature.melspectrogram, power_to_db(ref=1, top_db=80)",
            "n_fft": cfg.n_fft,
            "hop_length": cfg.hop_length,
            "sr": cfg.sr,
            "fps": cfg.fps,
            "study": "ChoreoGraph (ACM MM 2022)",
        }
        return [ArraySpec("mel96", (CHOREOGRAPH_N_MELS,), np.float32, attrs)]

    def compute_track(
        self, track: TrackAudio, settings: AudioSettings | None = None
    ) -> dict[str, np.ndarray]:
        from dancedata.compute.study_features import choreograph_mel

        cfg = track.cfg
        mel = choreograph_mel(
            track.y, cfg.sr, fps=cfg.fps, n_mels=CHOREOGRAPH_N_MELS, n_fft=cfg.n_fft
        )
        return {"mel96": mel}

    def config(self, settings: AudioSettings | None = None) -> dict[str, Any]:
        return {"n_mels": CHOREOGRAPH_N_MELS, "db": True, "top_db": MEL_TOP_DB}


def stft_layout(cfg: AudioFeatureConfig, settings: AudioSettings) -> dict[str, int]:
    """Chunk length L (samples at ``stft_sr``), STFT frames per chunk k and values per frame."""
    chunk = int(round(settings.stft_sr / cfg.fps))
    k = frames_per_chunk(chunk, GENRE_STFT_HOP)
    bins = 1 + GENRE_STFT_N_FFT // 2
    return {"chunk_samples": chunk, "frames_per_chunk": k, "bins": bins, "values": bins * k}


@register_family("stft_frames")
class StftFramesFamily(AudioFamily):
    """The genre dissertation's per-motion-frame STFT: (A, 1025, k) magnitudes."""

    outputs = (
        ArraySpec(
            "stft_frames",
            (1 + GENRE_STFT_N_FFT // 2, None),
            np.float32,
            required_attrs=("sr", "hop_length", "n_fft", "chunk_samples", "frames_per_chunk"),
            extension=True,
            note="genre study: one STFT per motion-frame chunk; k = frames_per_chunk (2 at 60 "
            "fps, 16 kHz)",
        ),
    )

    def arrays(
        self, cfg: AudioFeatureConfig, settings: AudioSettings | None = None
    ) -> list[ArraySpec]:
        settings = settings or _DEFAULT
        layout = stft_layout(cfg, settings)
        attrs = {
            "layout": "frame, frequency bin, STFT frame within the chunk",
            "units": "magnitude",
            "sr": settings.stft_sr,
            "hop_length": GENRE_STFT_HOP,
            "n_fft": GENRE_STFT_N_FFT,
            **layout,
            "study": "genre-based dance generation (MSc 2019): 1025 x 6 = 6150 in the text",
        }
        shape = (layout["bins"], layout["frames_per_chunk"])
        return [ArraySpec("stft_frames", shape, np.float32, attrs)]

    def compute_track(
        self, track: TrackAudio, settings: AudioSettings | None = None
    ) -> dict[str, np.ndarray]:
        from dancedata.compute.study_features import stft_per_motion_frame

        settings = settings or _DEFAULT
        cfg = track.cfg
        spec = stft_per_motion_frame(
            track.y,
            cfg.sr,
            fps=cfg.fps,
            target_sr=settings.stft_sr,
            hop_length=GENRE_STFT_HOP,
            n_fft=GENRE_STFT_N_FFT,
            n_frames=_frames(track),
        )
        return {"stft_frames": spec}

    def config(self, settings: AudioSettings | None = None) -> dict[str, Any]:
        settings = settings or _DEFAULT
        return {"sr": settings.stft_sr, "hop_length": GENRE_STFT_HOP, "n_fft": GENRE_STFT_N_FFT}

    def check(self, settings: AudioSettings) -> str | None:
        if settings.stft_sr < 1000:
            return f"--stft-sr must be at least 1000 Hz, got {settings.stft_sr}"
        return None


@register_family("tempogram")
class TempogramFamily(AudioFamily):
    """Autocorrelation tempogram of the mix's onset envelope."""

    outputs = (
        ArraySpec("tempogram", (None,), np.float32, required_attrs=("win_length",), extension=True),
    )

    def arrays(
        self, cfg: AudioFeatureConfig, settings: AudioSettings | None = None
    ) -> list[ArraySpec]:
        width = (settings or _DEFAULT).tempogram_frames
        attrs = {
            "win_length": width,
            "columns": "lag j frames = 60 * sr / (hop_length * j) BPM (column 0: lag 0)",
            "recipe": "librosa.feature.tempogram of librosa.onset.onset_strength",
            "sr": cfg.sr,
            "hop_length": cfg.hop_length,
        }
        return [ArraySpec("tempogram", (width,), np.float32, attrs)]

    def compute_track(
        self, track: TrackAudio, settings: AudioSettings | None = None
    ) -> dict[str, np.ndarray]:
        from dancedata.compute.audio_features import onset_envelope
        from dancedata.compute.study_features import tempogram

        cfg = track.cfg
        env = track.shared("onset_env", lambda: onset_envelope(track.y, cfg))
        gram = tempogram(
            sr=cfg.sr,
            hop_length=cfg.hop_length,
            win_length=(settings or _DEFAULT).tempogram_frames,
            onset_envelope=env,
        )
        return {"tempogram": gram}

    def config(self, settings: AudioSettings | None = None) -> dict[str, Any]:
        return {"win_length": (settings or _DEFAULT).tempogram_frames}

    def check(self, settings: AudioSettings) -> str | None:
        if settings.tempogram_frames < 2:
            return "the tempogram window must be at least 2 frames"
        return None
