"""OpenUnmix stem separation (Stöter, Uhlich, Liutkus & Mitsufuji 2019) by a loaded separator.

Needs the optional extra ``dancedata[stems]`` (torch, torchaudio, openunmix); everything here
imports them lazily, so ``import dancedata`` never loads torch. The network architecture and the
multichannel Wiener filter are those of the ``openunmix`` package (``openunmix.model.OpenUnmix``
and ``Separator``); this module runs a loaded ``Separator`` over whole tracks or chunks.

The separator is loaded from local weight files by :mod:`dancedata.io.openunmix_model`
(:func:`~dancedata.io.openunmix_model.load_separator`, cached per weight files; the files are
found by :mod:`dancedata.io.openunmix_weights`, never downloaded); the functions here take the
loaded separator and run it. The settings that choose and load it are :data:`LOAD_OPTIONS`; the
others of :data:`DEFAULTS` say how it is run. The Wiener window length and the rate, n_fft, hop
and channels are read from the loaded separator (:func:`separator_settings`).

What the model sees (:func:`separate_channels`): the input's own channels at the model rate,
as ``openunmix.utils.preprocess`` feeds them (mono duplicated, only the first two of more;
another rate resampled with :data:`INPUT_RESAMPLER`). featurize passes the music file's own
samples (:mod:`dancedata.io.audio_native`), not the feature-rate mono mix, so nothing above
half the feature rate and no stereo image is lost before separation. Each stem is then the mean
of its channels, resampled to the requested output rate.

Whole tracks or chunks (:func:`separation_plan`): a track is separated in one pass, exactly as
``openunmix`` separates a file, when the measured memory estimate (:func:`whole_track_mb`, about
26 MB per second of stereo 44.1 kHz for umxhq) fits ``memory_mb``; otherwise in chunks that fit,
each separated alone (its own LSTM context and Wiener filter) and blended by linear cross-fades
over ``overlap_seconds`` (overlap-add, normalised by the summed weights). Chunks start on the
whole track's Wiener windows (multiples of ``wiener_win_len`` × hop samples) when they are long
enough, so each chunk's EM step sees the windows the whole-track pass sees: on a 41 s test track
15 s chunks gave 42-49 dB against whole-track separation, unaligned ones 27-30 dB.
``chunk_seconds`` forces chunks of that length.

``umxhq`` (MUSDB18-HQ) is the default; ``umxl`` is larger and better, but its weights are licensed
for non-commercial use only (CC BY-NC-SA 4.0).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dancedata.errors import InputError

MODEL_SAMPLE_RATE = 44100

DEFAULTS: dict[str, Any] = {
    "model": "umxhq",
    "weights_dir": None,
    "device": "cpu",
    "niter": 1,
    "wiener_win_len": 300,
    "chunk_seconds": None,
    "overlap_seconds": 4.0,
    "memory_mb": 4096.0,
}
# The DEFAULTS that choose and load the separator (dancedata.io.openunmix_model.load_separator's
# arguments); the others are run options of separate_channels.
LOAD_OPTIONS: tuple[str, ...] = ("model", "weights_dir", "device", "niter", "wiener_win_len")
# Resampler from a file's rate to the model's (44.1 kHz) when they differ.
INPUT_RESAMPLER = "soxr_hq"
# Peak MB per complex STFT value of the mix (bins × frames × channels) of one Separator pass with
# four targets, plus a fixed part: measured with ru_maxrss on CPU, umxhq-shaped network (n_fft
# 4096, hop 1024, 2 channels), niter 1, wiener_win_len 300: 334 MB for 10 s, 852 MB for 30 s of
# stereo 44.1 kHz, i.e. 25.9 MB/s = 1.47e-4 MB per value and 75 MB fixed (rounded up below).
MB_PER_STFT_VALUE = 1.5e-4
FIXED_MB = 100.0


def separator_settings(separator: Any) -> dict[str, Any]:
    """What the loaded separator runs at: {"sample_rate" (Hz), "n_fft", "n_hop", "channels"}."""
    target = next(iter(separator.target_models.values()))
    return {
        "sample_rate": float(separator.sample_rate),
        "n_fft": int(separator.stft.n_fft),
        "n_hop": int(separator.stft.n_hop),
        "channels": int(target.fc1.in_features // target.nb_bins),
    }


def whole_track_mb(n_samples: int, n_fft: int, n_hop: int, channels: int, n_targets: int) -> float:
    """Estimated peak memory (MB) of one OpenUnmix ``Separator`` pass over ``n_samples`` at the
    model rate, beyond the models themselves: :data:`MB_PER_STFT_VALUE` MB per complex STFT
    value of the mix (bins × frames × channels) plus :data:`FIXED_MB`, measured on CPU (umxhq:
    about 26 MB per second of stereo 44.1 kHz, so 4096 MB holds 2.6 minutes) and scaled by the
    number of targets over the four it was measured with."""
    frames = n_samples // n_hop + 1
    values = (n_fft // 2 + 1) * frames * channels
    return FIXED_MB + values * MB_PER_STFT_VALUE * max(n_targets, 1) / 4.0


def separation_plan(
    n_samples: int,
    sample_rate: float,
    *,
    n_fft: int,
    n_hop: int,
    channels: int,
    n_targets: int = 4,
    chunk_seconds: float | None = None,
    overlap_seconds: float = 4.0,
    memory_mb: float = 4096.0,
) -> dict[str, Any]:
    """How a track of ``n_samples`` (model rate) is separated, as recorded in the store.

    ``{"method": "whole_track"}`` when ``chunk_seconds`` is None and the estimate of
    :func:`whole_track_mb` fits ``memory_mb``: one pass, exactly what ``openunmix`` computes.
    Otherwise ``{"method": "overlap_add_crossfade", "chunk_seconds", "overlap_seconds"}``:
    chunks of ``chunk_seconds`` (or the longest that fits ``memory_mb``), each separated alone,
    blended by linear cross-fades over ``overlap_seconds`` (see :func:`run_chunked`).
    ``estimated_mb`` is the whole-track estimate either way.
    """
    estimate = whole_track_mb(n_samples, n_fft, n_hop, channels, n_targets)
    plan: dict[str, Any] = {"estimated_mb": round(estimate, 1), "memory_mb": float(memory_mb)}
    if chunk_seconds is None and estimate <= memory_mb:
        return {"method": "whole_track", **plan}
    if chunk_seconds is None:
        per_second = whole_track_mb(int(sample_rate), n_fft, n_hop, channels, n_targets) - FIXED_MB
        chunk_seconds = float(np.floor(max(memory_mb - FIXED_MB, 0.0) / per_second))
        floor = 2.0 * overlap_seconds + 1.0
        if chunk_seconds < floor:
            raise InputError(
                f"OpenUnmix memory limit {memory_mb:g} MB allows chunks of {chunk_seconds:g} s, "
                f"under {floor:g} s (twice the {overlap_seconds:g} s overlap, plus 1 s): "
                "raise the limit or shorten the overlap"
            )
    return {
        "method": "overlap_add_crossfade",
        "chunk_seconds": float(chunk_seconds),
        "overlap_seconds": float(overlap_seconds),
        "crossfade": "linear",
        **plan,
    }


def chunk_bounds(n_samples: int, chunk: int, overlap: int, align: int = 1) -> list[tuple[int, int]]:
    """[start, stop) ranges of ``chunk`` samples, each overlapping the next by at least
    ``overlap``, covering ``n_samples``.

    ``align`` 1: the last one ends at ``n_samples`` and is full length when the signal is long
    enough (a short tail would starve the network of context). ``align`` > 1: every start is a
    multiple of ``align`` (the step is the largest multiple of ``align`` that keeps the overlap,
    so ``chunk - overlap >= align`` is required) and the last chunk may be shorter; with
    ``align`` = Wiener window × hop, each chunk's Wiener windows are those of the whole track.
    """
    if chunk <= overlap or overlap < 0:
        raise InputError(f"chunk ({chunk} samples) must be longer than its overlap ({overlap})")
    if n_samples <= chunk:
        return [(0, n_samples)]
    if align > 1:
        if chunk - overlap < align:
            raise InputError(
                f"chunk {chunk} minus overlap {overlap} is under the alignment {align}"
            )
        step = (chunk - overlap) // align * align
        starts = list(range(0, n_samples - overlap, step))
        bounds = [(start, min(start + chunk, n_samples)) for start in starts]
        return bounds[: next(i for i, (_, stop) in enumerate(bounds) if stop == n_samples) + 1]
    starts = list(range(0, n_samples - chunk, chunk - overlap)) + [n_samples - chunk]
    return [(start, start + chunk) for start in starts]


def crossfade_weights(length: int, overlap: int, first: bool, last: bool) -> np.ndarray:
    """Per-sample weight of one chunk: linear ramps over ``overlap`` samples at inner edges."""
    weights = np.ones(length, dtype=np.float64)
    ramp = (np.arange(min(overlap, length)) + 0.5) / max(overlap, 1)
    if not first:
        weights[: ramp.size] = np.minimum(weights[: ramp.size], ramp)
    if not last:
        weights[length - ramp.size :] = np.minimum(weights[length - ramp.size :], ramp[::-1])
    return weights


def run_chunked(
    separator: Any, audio: np.ndarray, chunk: int, overlap: int, device: str, align: int = 1
) -> np.ndarray:
    """Separator output for (channels, samples) model-rate audio, averaged over the channels:
    (stems, samples) float32, stems in ``separator.target_models`` order.

    A signal no longer than ``chunk`` is one pass (what ``openunmix`` computes for the file).
    Longer ones go in chunks of ``chunk`` samples (see :func:`chunk_bounds`), each separated alone;
    overlapping parts are blended with :func:`crossfade_weights` and normalised by the summed
    weights, so the blend is exact where the chunks agree.

    OpenUnmix's EM step inverts 2 × 2 spatial covariances regularised by sqrt(1e-10); with
    duplicated-mono input and channel-symmetric estimates they are singular, and in float32 the
    inverse can come out inf/NaN. A chunk whose estimate is not finite is run again without the
    EM step (plain ratio masks, ``niter`` 0), with a warning, rather than failing the track.
    """
    import torch

    n_samples = audio.shape[-1]
    bounds = chunk_bounds(n_samples, chunk, overlap, align)
    out = np.zeros((len(separator.target_models), n_samples), dtype=np.float32)
    total = np.zeros(n_samples, dtype=np.float32)
    with torch.inference_mode():
        for i, (start, stop) in enumerate(bounds):
            short = max(0, int(separator.stft.n_fft) - (stop - start))  # STFT reflect padding
            padded = np.pad(audio[None, :, start:stop], ((0, 0), (0, 0), (0, short)))
            piece = torch.as_tensor(padded, dtype=torch.float32, device=device)
            estimate = separator(piece)[0].detach().cpu().numpy()[..., : stop - start]
            if not np.all(np.isfinite(estimate)) and separator.niter > 0:
                estimate = _without_em(separator, piece)
            mono = estimate.astype(np.float64).mean(axis=1)
            del estimate
            if len(bounds) == 1:
                return mono.astype(np.float32)
            weights = crossfade_weights(stop - start, overlap, i == 0, i == len(bounds) - 1)
            out[:, start:stop] += (mono * weights).astype(np.float32)
            total[start:stop] += weights.astype(np.float32)
    out /= total
    return out


def _without_em(separator: Any, piece: Any) -> np.ndarray:
    """The separator's estimate of ``piece`` with ``niter`` 0 (see :func:`run_chunked`)."""
    import warnings

    niter = separator.niter
    warnings.warn(
        f"OpenUnmix EM step gave non-finite values (singular spatial covariance); this "
        f"{piece.shape[-1] / MODEL_SAMPLE_RATE:.1f} s chunk uses the ratio masks (niter 0)",
        RuntimeWarning,
        stacklevel=3,
    )
    separator.niter = 0
    try:
        return separator(piece)[0].detach().cpu().numpy().astype(np.float64)
    finally:
        separator.niter = niter


def model_input(audio: np.ndarray, sr: float, model_sr: float, channels: int) -> np.ndarray:
    """(channels, samples) audio at ``sr`` Hz → what the model is fed, as ``openunmix`` feeds it
    (``openunmix.utils.preprocess``): mono duplicated to two channels, only the first two of
    more; for a one-channel model the channel mean. Resampled to ``model_sr`` with
    :data:`INPUT_RESAMPLER` when the rates differ (openunmix uses torchaudio's sinc resampler)."""
    import librosa

    audio = np.atleast_2d(np.asarray(audio, dtype=np.float32))
    if channels == 1:
        audio = audio.mean(axis=0, keepdims=True)
    elif audio.shape[0] == 1:
        audio = np.repeat(audio, channels, axis=0)
    else:
        audio = audio[:channels]
    if sr != model_sr:
        audio = librosa.resample(audio, orig_sr=sr, target_sr=model_sr, res_type=INPUT_RESAMPLER)
    return np.ascontiguousarray(audio, dtype=np.float32)


def separate_channels(
    audio: np.ndarray,
    sr: float,
    separator: Any,
    *,
    out_sr: float | None = None,
    out_length: int | None = None,
    res_type: str = "soxr_hq",
    chunk_seconds: float | None = None,
    overlap_seconds: float = 4.0,
    memory_mb: float = 4096.0,
) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Four OpenUnmix stems of ``audio`` ((samples,) or (channels, samples) at ``sr`` Hz, e.g. a
    file's own samples at its own rate) by ``separator`` (an ``openunmix.model.Separator``, see
    :func:`dancedata.io.openunmix_model.load_separator`), and the plan they were made with.

    The model sees the channels and the rate of the input (see :func:`model_input`), over the
    whole track or in cross-faded chunks (see :func:`separation_plan`). Each stem is then the mean
    of its channels, resampled from the model rate to ``out_sr`` Hz (default ``sr``) with
    ``librosa.resample(res_type=res_type)`` and cut or zero-padded to ``out_length`` samples
    (default: the input's length at ``out_sr``, as librosa.resample gives it): mono float32.
    """
    import librosa

    device = str(separator.sample_rate.device)
    stft = separator_settings(separator)
    model_sr = stft["sample_rate"]
    out_sr = float(sr if out_sr is None else out_sr)
    audio = np.atleast_2d(np.asarray(audio, dtype=np.float32))
    if out_length is None:
        out_length = (
            int(np.ceil(audio.shape[-1] * out_sr / sr)) if out_sr != sr else audio.shape[-1]
        )
    fed = model_input(audio, sr, model_sr, stft["channels"])
    n_model = fed.shape[-1]
    if n_model < stft["n_fft"]:  # the STFT's reflect padding needs at least n_fft / 2 samples
        fed = np.pad(fed, ((0, 0), (0, stft["n_fft"] - n_model)))
    plan = separation_plan(
        fed.shape[-1],
        model_sr,
        n_fft=stft["n_fft"],
        n_hop=stft["n_hop"],
        channels=stft["channels"],
        n_targets=len(separator.target_models),
        chunk_seconds=chunk_seconds,
        overlap_seconds=overlap_seconds,
        memory_mb=memory_mb,
    )
    overlap = int(round(overlap_seconds * model_sr))
    align = 1
    if plan["method"] == "whole_track":
        chunk = fed.shape[-1] + overlap + 1
    else:
        chunk = int(round(plan["chunk_seconds"] * model_sr))
        # Chunk starts on the whole track's Wiener windows (wiener_win_len frames), when the
        # chunks are long enough; else on STFT frames.
        windows = (separator.wiener_win_len or 0) * stft["n_hop"]
        align = windows if windows and chunk - overlap >= windows else stft["n_hop"]
        plan["aligned_to"] = "wiener_windows" if align == windows else "stft_frames"
        plan["step_seconds"] = (chunk - overlap) // align * align / model_sr
    estimates = run_chunked(separator, fed, chunk, overlap, device, align)
    plan.update(
        input_sr=float(sr),
        input_channels=int(audio.shape[0]),
        separation_sr=model_sr,
        separation_channels=stft["channels"],
        output_sr=out_sr,
    )
    stems = {}
    for name, mono in zip(separator.target_models.keys(), estimates, strict=True):
        mono = mono[:n_model]
        if out_sr != model_sr:
            mono = librosa.resample(mono, orig_sr=model_sr, target_sr=out_sr, res_type=res_type)
        stems[name] = librosa.util.fix_length(mono, size=out_length).astype(np.float32)
    return stems, plan


def separate(y: np.ndarray, sr: float, separator: Any, **options: Any) -> dict[str, np.ndarray]:
    """Four OpenUnmix stems of ``y`` ((samples,) or (channels, samples)) at ``sr`` Hz by the loaded
    ``separator``: mono float32 with ``y``'s length and rate. ``options`` are the run options of
    :data:`DEFAULTS` (not :data:`LOAD_OPTIONS`); see :func:`separate_channels`."""
    return separate_channels(y, sr, separator, **options)[0]
