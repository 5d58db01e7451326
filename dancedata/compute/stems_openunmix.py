"""OpenUnmix stem separation (Stöter, Uhlich, Liutkus & Mitsufuji 2019) from local weights.

Needs the optional extra ``dancedata[stems]`` (torch, torchaudio, openunmix); everything here
imports them lazily, so ``import dancedata`` never loads torch. The network architecture and the
multichannel Wiener filter are those of the ``openunmix`` package (``openunmix.model.OpenUnmix``
and ``Separator``); this module only finds the weights, builds the models from their state dicts
and runs them in chunks.

Weights are never downloaded: there may be no network, and a silent multi-hundred-MB download is
not something a featurize run should do. For model ``M`` and stem ``t`` the file is the published
file name (see :data:`MODELS`), looked up in this order:

1. ``weights_dir/M/<published name>`` or ``weights_dir/M/<t>.pth``
2. ``weights_dir/<published name>``
3. the torch hub cache, ``torch.hub.get_dir()/checkpoints/<published name>`` (where
   ``openunmix``'s own hub loader leaves them after an online run)

When a file is missing, :class:`~dancedata.errors.InputError` lists every missing file, its URL and
the folders it may go in. The architecture (hidden size, layers, bins, channels) is read from the
state dict, so any OpenUnmix-shaped weights load. The models run at 44.1 kHz (all published music
models do): input is resampled to 44.1 kHz, mono input is duplicated to the model's channels,
and each stem is averaged to mono and resampled back to the input rate and length.

Memory stays bounded on long tracks: the signal goes through the network in chunks of
``chunk_seconds`` that overlap by ``overlap_seconds`` and are blended with linear cross-fades.
``umxhq`` (MUSDB18-HQ) is the default; ``umxl`` is larger and better, but its weights are licensed
for non-commercial use only (CC BY-NC-SA 4.0).
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.compute.stems import STEM_NAMES
from dancedata.errors import DancedataError, InputError

MODEL_SAMPLE_RATE = 44100
EXTRA_HINT = "pip install 'dancedata[stems]' (torch, torchaudio, openunmix)"

MODELS: dict[str, dict[str, Any]] = {
    "umxhq": {
        "url": "https://zenodo.org/records/3370489/files/",
        "files": {
            "bass": "bass-8d85a5bd.pth",
            "drums": "drums-9619578f.pth",
            "other": "other-b52fbbf7.pth",
            "vocals": "vocals-b62c91ce.pth",
        },
    },
    "umxl": {
        "url": "https://zenodo.org/records/5069601/files/",
        "files": {
            "bass": "bass-2ca1ce51.pth",
            "drums": "drums-69e0ebd4.pth",
            "other": "other-c8c5b3e6.pth",
            "vocals": "vocals-bccbd9aa.pth",
        },
    },
}

DEFAULTS: dict[str, Any] = {
    "model": "umxhq",
    "weights_dir": None,
    "device": "cpu",
    "niter": 1,
    "wiener_win_len": 300,
    "chunk_seconds": 30.0,
    "overlap_seconds": 1.0,
}


def _import_torch() -> Any:
    try:
        import openunmix.model  # noqa: F401
        import torch
    except ImportError as exc:
        raise DancedataError(
            f"stem backend 'openunmix' needs the optional extra: {EXTRA_HINT} ({exc})"
        ) from exc
    except OSError as exc:  # e.g. a CUDA torchaudio next to a CPU-only torch
        raise DancedataError(
            "stem backend 'openunmix': torchaudio does not load with this torch "
            f"({exc}); install matching builds, e.g. torch==2.14.1 torchaudio==2.11.0"
        ) from exc
    return torch


def hub_checkpoint_dir() -> Path:
    """The torch hub cache folder for weight files (``torch.hub.get_dir()/checkpoints``)."""
    return Path(_import_torch().hub.get_dir()) / "checkpoints"


def find_weights(model: str = "umxhq", weights_dir: str | Path | None = None) -> dict[str, Path]:
    """Path of each stem's weight file, {stem: path}; raises InputError naming every missing file.

    See the module docstring for the search order. Cheap: no weights are read.
    """
    if model not in MODELS:
        raise InputError(f"unknown OpenUnmix model {model!r}; choose one of {', '.join(MODELS)}")
    spec = MODELS[model]
    folders: list[Path] = []
    if weights_dir is not None:
        root = Path(weights_dir).expanduser()
        if not root.is_dir():
            raise InputError("OpenUnmix weights folder does not exist", root)
        folders += [root / model, root]
    hub = hub_checkpoint_dir()
    folders.append(hub)

    found: dict[str, Path] = {}
    missing: list[str] = []
    for stem in STEM_NAMES:
        name = spec["files"][stem]
        candidates = [folder / name for folder in folders]
        if weights_dir is not None:
            candidates.insert(1, Path(weights_dir).expanduser() / model / f"{stem}.pth")
        hit = next((path for path in candidates if path.is_file()), None)
        if hit is None:
            missing.append(name)
        else:
            found[stem] = hit
    if missing:
        where = (
            f"{Path(weights_dir).expanduser() / model}/ (--stems-weights) or {hub}/"
            if weights_dir is not None
            else f"a folder given as --stems-weights DIR (as DIR/{model}/) or {hub}/"
        )
        raise InputError(
            f"OpenUnmix {model!r} weights missing: {', '.join(missing)}. Nothing is downloaded "
            f"automatically: fetch each from {spec['url']}<file name> and put them in {where}",
            weights_dir,
        )
    return found


def _build_target(path: Path, torch: Any) -> Any:
    """One OpenUnmix target model, its shape read from the state dict at ``path``."""
    from openunmix.model import OpenUnmix

    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # noqa: BLE001 - any unpickling failure means a bad file
        raise InputError(f"cannot read OpenUnmix weights ({exc})", path) from exc
    need = ("fc1.weight", "input_mean", "output_mean", "lstm.weight_ih_l0")
    if not isinstance(state, dict) or any(key not in state for key in need):
        raise InputError("not an OpenUnmix state dict (needs fc1, lstm, input/output_mean)", path)
    max_bin = int(state["input_mean"].shape[0])
    nb_bins = int(state["output_mean"].shape[0])
    hidden, fc1_in = (int(v) for v in state["fc1.weight"].shape)
    n_layers = sum(1 for key in state if key.startswith("lstm.weight_ih_l") and "_rev" not in key)
    target = OpenUnmix(
        nb_bins=nb_bins,
        nb_channels=fc1_in // max_bin,
        hidden_size=hidden,
        nb_layers=n_layers,
        unidirectional="lstm.weight_ih_l0_reverse" not in state,
        max_bin=max_bin,
    )
    result = target.load_state_dict(state, strict=False)
    if result.missing_keys:
        raise InputError(f"OpenUnmix weights lack {', '.join(result.missing_keys[:5])}", path)
    return target


@functools.lru_cache(maxsize=2)
def _cached_separator(
    paths: tuple[tuple[str, str, float], ...], device: str, niter: int, wiener_win_len: int | None
) -> Any:
    torch = _import_torch()
    from openunmix.model import Separator

    targets = {stem: _build_target(Path(path), torch) for stem, path, _ in paths}
    shapes = {(t.nb_output_bins, t.fc1.in_features // t.nb_bins) for t in targets.values()}
    if len(shapes) != 1:
        raise InputError(f"OpenUnmix stem models disagree in bins/channels: {sorted(shapes)}")
    nb_bins, nb_channels = shapes.pop()
    n_fft = 2 * (nb_bins - 1)
    separator = Separator(
        target_models=targets,
        niter=niter,
        residual=False,
        sample_rate=float(MODEL_SAMPLE_RATE),
        n_fft=n_fft,
        n_hop=n_fft // 4,
        nb_channels=nb_channels,
        wiener_win_len=wiener_win_len,
        filterbank="torch",
    )
    separator.freeze()
    return separator.to(device)


def load_separator(
    model: str = "umxhq",
    weights_dir: str | Path | None = None,
    device: str = "cpu",
    niter: int = 1,
    wiener_win_len: int | None = 300,
) -> Any:
    """An ``openunmix.model.Separator`` for the four stems, in eval mode on ``device``.

    Cached per weight files (path and mtime) and settings, so a featurize run loads weights once.
    ``device`` is a torch device name, or ``"auto"`` for CUDA when available, else CPU.
    """
    torch = _import_torch()
    if device == "auto":
        device = "cuda" if torch.cuda.is_available() else "cpu"
    files = find_weights(model, weights_dir)
    key = tuple((stem, str(path), path.stat().st_mtime) for stem, path in files.items())
    return _cached_separator(key, device, int(niter), wiener_win_len)


def chunk_bounds(n_samples: int, chunk: int, overlap: int) -> list[tuple[int, int]]:
    """[start, stop) ranges of ``chunk`` samples, each overlapping the next by at least
    ``overlap``, covering ``n_samples``; the last one ends at ``n_samples`` and is full length
    when the signal is long enough (a short tail would starve the network of context)."""
    if chunk <= overlap or overlap < 0:
        raise InputError(f"chunk ({chunk} samples) must be longer than its overlap ({overlap})")
    if n_samples <= chunk:
        return [(0, n_samples)]
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
    separator: Any, audio: np.ndarray, chunk: int, overlap: int, device: str
) -> np.ndarray:
    """Separator output for (channels, samples) model-rate audio → (stems, channels, samples).

    Each chunk runs alone through the network; overlapping parts are blended with
    :func:`crossfade_weights` and normalised by the summed weights, so the blend is exact.

    OpenUnmix's EM step inverts 2 × 2 spatial covariances regularised by sqrt(1e-10); with
    duplicated-mono input and channel-symmetric estimates they are singular, and in float32 the
    inverse can come out inf/NaN. A chunk whose estimate is not finite is run again without the
    EM step (plain ratio masks, ``niter`` 0), with a warning, rather than failing the track.
    """
    torch = _import_torch()
    n_samples = audio.shape[-1]
    bounds = chunk_bounds(n_samples, chunk, overlap)
    out = np.zeros((len(separator.target_models),) + audio.shape, dtype=np.float64)
    total = np.zeros(n_samples, dtype=np.float64)
    with torch.inference_mode():
        for i, (start, stop) in enumerate(bounds):
            piece = torch.as_tensor(audio[None, :, start:stop], dtype=torch.float32, device=device)
            estimate = separator(piece)[0].detach().cpu().numpy().astype(np.float64)
            if not np.all(np.isfinite(estimate)) and separator.niter > 0:
                estimate = _without_em(separator, piece)
            weights = crossfade_weights(stop - start, overlap, i == 0, i == len(bounds) - 1)
            out[..., start:stop] += estimate * weights
            total[start:stop] += weights
    return out / total


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


def separate(
    y: np.ndarray,
    sr: float,
    model: str = "umxhq",
    weights_dir: str | Path | None = None,
    device: str = "cpu",
    niter: int = 1,
    wiener_win_len: int | None = 300,
    chunk_seconds: float = 30.0,
    overlap_seconds: float = 1.0,
) -> dict[str, np.ndarray]:
    """Four OpenUnmix stems of ``y`` ((samples,) or (channels, samples)) at ``sr`` Hz.

    Stems are mono float32 with ``y``'s length and rate. See :func:`load_separator` for the model
    settings and :func:`run_chunked` for ``chunk_seconds`` / ``overlap_seconds``.
    """
    import librosa

    separator = load_separator(model, weights_dir, device, niter, wiener_win_len)
    device = str(separator.sample_rate.device)
    audio = np.atleast_2d(np.asarray(y, dtype=np.float32))
    n_samples = audio.shape[-1]
    if sr != MODEL_SAMPLE_RATE:
        audio = librosa.resample(audio, orig_sr=sr, target_sr=MODEL_SAMPLE_RATE, res_type="soxr_hq")
    channels = next(iter(separator.target_models.values())).fc1.in_features
    channels //= next(iter(separator.target_models.values())).nb_bins
    if audio.shape[0] != channels:
        audio = np.repeat(audio.mean(axis=0, keepdims=True), channels, axis=0)
    n_model = audio.shape[-1]
    n_fft = 2 * (next(iter(separator.target_models.values())).nb_output_bins - 1)
    if n_model < n_fft:  # the STFT's reflect padding needs at least n_fft / 2 samples
        audio = np.pad(audio, ((0, 0), (0, n_fft - n_model)))
    chunk = int(round(chunk_seconds * MODEL_SAMPLE_RATE))
    overlap = int(round(overlap_seconds * MODEL_SAMPLE_RATE))
    estimates = run_chunked(separator, audio, chunk, overlap, device)
    stems = {}
    for name, estimate in zip(separator.target_models.keys(), estimates, strict=True):
        mono = estimate[:, :n_model].mean(axis=0)
        if sr != MODEL_SAMPLE_RATE:
            mono = librosa.resample(
                mono, orig_sr=MODEL_SAMPLE_RATE, target_sr=sr, res_type="soxr_hq"
            )
        stems[name] = librosa.util.fix_length(mono, size=n_samples).astype(np.float32)
    return stems
