"""Loading an OpenUnmix separator from local weight files (Stöter et al. 2019).

The weight files are found and read by :mod:`dancedata.io.openunmix_weights` (never downloaded:
``weights_dir``, then the torch hub cache). This module builds the ``openunmix.model.Separator``
from them, once per process per weight files (path and mtime) and settings; the separation itself
(chunking, resampling, stem averaging) is :mod:`dancedata.compute.stems.openunmix`, which takes
the loaded separator. The architecture (hidden size, layers, bins, channels) is read from the
state dict, so any OpenUnmix-shaped weights load. From an OpenUnmix model folder (one with
``separator.json``) the separator runs with that file's settings, whatever ``model`` says; without
one, the published models' settings apply (44.1 kHz, n_fft from the weights, hop n_fft / 4).

torch and openunmix are imported lazily (the optional extra ``dancedata[stems]``).
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

from dancedata.errors import InputError
from dancedata.io.openunmix_weights import (
    find_weights,
    import_torch,
    is_model_folder,
    read_separator_json,
    read_state_dict,
)

# The published models' sample rate (Hz), used when no separator.json says otherwise.
PUBLISHED_SAMPLE_RATE = 44100


def _build_target(path: Path) -> Any:
    """One OpenUnmix target model, its shape read from the state dict at ``path``."""
    from openunmix.model import OpenUnmix

    state = read_state_dict(path)
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
    paths: tuple[tuple[str, str, float], ...],
    device: str,
    niter: int,
    wiener_win_len: int | None,
    stft: tuple[float, int, int, int] | None,
) -> Any:
    import_torch()
    from openunmix.model import Separator

    targets = {stem: _build_target(Path(path)) for stem, path, _ in paths}
    shapes = {(t.nb_output_bins, t.fc1.in_features // t.nb_bins) for t in targets.values()}
    if len(shapes) != 1:
        raise InputError(f"OpenUnmix stem models disagree in bins/channels: {sorted(shapes)}")
    nb_bins, nb_channels = shapes.pop()
    n_fft = 2 * (nb_bins - 1)
    sample_rate, n_hop = float(PUBLISHED_SAMPLE_RATE), n_fft // 4
    if stft is not None:  # separator.json of an OpenUnmix model folder
        sample_rate, json_fft, n_hop, json_channels = stft
        if (json_fft // 2 + 1, json_channels) != (nb_bins, nb_channels):
            raise InputError(
                f"separator.json says nfft {json_fft}, {json_channels} channel(s), but the weights "
                f"have {nb_bins} bins (nfft {n_fft}) and {nb_channels} channel(s)"
            )
    separator = Separator(
        target_models=targets,
        niter=niter,
        residual=False,
        sample_rate=sample_rate,
        n_fft=n_fft,
        n_hop=n_hop,
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
    ``device`` is a torch device name, or ``"auto"`` for CUDA when available, else CPU. From an
    OpenUnmix model folder the sample rate, n_fft and hop come from its ``separator.json``
    (as ``openunmix.utils.load_separator`` reads them); otherwise 44.1 kHz, n_fft from the
    weights' bins and hop n_fft / 4 (the published models' settings).
    """
    torch = import_torch()
    if device == "auto":
        device = "cuda" if torch.cuda.is_available() else "cpu"
    files = find_weights(model, weights_dir)
    key = tuple((stem, str(path), path.stat().st_mtime) for stem, path in files.items())
    stft = None
    if is_model_folder(weights_dir):
        conf = read_separator_json(weights_dir)  # type: ignore[arg-type]
        stft = (conf["sample_rate"], conf["nfft"], conf["nhop"], conf["nb_channels"])
    return _cached_separator(key, device, int(niter), wiener_win_len, stft)
