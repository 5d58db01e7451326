"""OpenUnmix weight files: where they are and what is in them (the lookup, no model building).

The pretrained OpenUnmix models (Stöter, Uhlich, Liutkus & Mitsufuji 2019) are four state dicts,
one per target. Weights are never downloaded: there may be no network, and a silent
multi-hundred-MB download is not something a featurize run should do. For model ``M`` and stem
``t`` the file is the published file name (see :data:`MODELS`), looked up in this order:

1. ``weights_dir/M/<published name>`` or ``weights_dir/M/<t>.pth``
2. ``weights_dir/<published name>``
3. the torch hub cache, ``torch.hub.get_dir()/checkpoints/<published name>`` (where
   ``openunmix``'s own hub loader leaves them after an online run)

When a file is missing, :class:`~dancedata.errors.InputError` lists every missing file, its URL and
the folders it may go in.

An **OpenUnmix model folder** as ``openunmix`` writes and reads it (``separator.json`` with
``sample_rate``, ``nfft``, ``nhop``, ``nb_channels``, next to ``<target>.pth`` or
``<target>-<hash>.pth``) is recognised by its ``separator.json`` (:func:`is_model_folder`,
:func:`read_separator_json`) and its files found whatever the model name says.

The network is built from these state dicts by :mod:`dancedata.io.openunmix_model` and run by
:mod:`dancedata.compute.stems.openunmix`.
torch is imported lazily (the optional extra ``dancedata[stems]``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from dancedata.errors import DancedataError, InputError

# The four targets of the published models, in dancedata's stem order
# (dancedata.compute.stems.STEM_NAMES; a test keeps the two equal).
TARGETS: tuple[str, ...] = ("drums", "bass", "vocals", "other")
EXTRA_HINT = "pip install 'dancedata[stems]' (torch, torchaudio, openunmix)"
# Keys every OpenUnmix target state dict has (checked before the network is built from it).
STATE_DICT_KEYS: tuple[str, ...] = ("fc1.weight", "input_mean", "output_mean", "lstm.weight_ih_l0")

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


def import_torch() -> Any:
    """``torch`` (with ``openunmix.model`` importable), or one clear error naming the extra."""
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
    return Path(import_torch().hub.get_dir()) / "checkpoints"


SEPARATOR_JSON = "separator.json"


def is_model_folder(weights_dir: str | Path | None) -> bool:
    """Whether ``weights_dir`` is an OpenUnmix model folder as ``openunmix`` itself writes and
    loads them (``separator.json`` next to ``<target>.pth``)."""
    return weights_dir is not None and (Path(weights_dir).expanduser() / SEPARATOR_JSON).is_file()


def read_separator_json(weights_dir: str | Path) -> dict[str, Any]:
    """The STFT and audio settings of an OpenUnmix model folder's ``separator.json``:
    {"sample_rate" (Hz), "nfft", "nhop" (samples), "nb_channels"}, checked."""
    import json

    path = Path(weights_dir).expanduser() / SEPARATOR_JSON
    try:
        conf = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read OpenUnmix separator settings ({exc})", path) from None
    need = {"sample_rate": float, "nfft": int, "nhop": int, "nb_channels": int}
    if not isinstance(conf, dict) or any(key not in conf for key in need):
        raise InputError(f"separator.json needs keys {', '.join(need)}", path)
    try:
        out = {key: kind(conf[key]) for key, kind in need.items()}
    except (TypeError, ValueError):
        raise InputError(
            "separator.json: sample_rate, nfft, nhop, nb_channels must be numbers", path
        ) from None
    if out["sample_rate"] <= 0 or out["nfft"] < 2 or not 0 < out["nhop"] <= out["nfft"]:
        raise InputError(f"separator.json: implausible settings {out}", path)
    if out["nb_channels"] not in (1, 2):
        raise InputError(
            f"separator.json: nb_channels must be 1 or 2, got {out['nb_channels']}", path
        )
    return out


def model_folder_weights(root: Path) -> dict[str, Path]:
    """{stem: path} in an OpenUnmix model folder: ``<stem>.pth``, else the one ``<stem>*.pth``
    (openunmix's own loader takes ``<target>*.pth``, e.g. ``vocals-b62c91ce.pth``)."""
    found: dict[str, Path] = {}
    missing: list[str] = []
    for stem in TARGETS:
        exact = root / f"{stem}.pth"
        matches = [exact] if exact.is_file() else sorted(root.glob(f"{stem}*.pth"))
        if len(matches) > 1:
            raise InputError(
                f"OpenUnmix model folder has several {stem} weight files "
                f"({', '.join(m.name for m in matches)}); keep one",
                root,
            )
        if matches:
            found[stem] = matches[0]
        else:
            missing.append(f"{stem}.pth")
    if missing:
        raise InputError(
            f"OpenUnmix model folder (it has {SEPARATOR_JSON}) lacks {', '.join(missing)}: "
            "dancedata needs all four stems (drums, bass, vocals, other)",
            root,
        )
    return found


def find_weights(model: str = "umxhq", weights_dir: str | Path | None = None) -> dict[str, Path]:
    """Path of each stem's weight file, {stem: path}; raises InputError naming every missing file.

    See the module docstring for the search order. An OpenUnmix model folder (one with
    ``separator.json``) is read as ``openunmix`` reads it, whatever ``model`` says. Cheap: no
    weights are read.
    """
    if is_model_folder(weights_dir):
        return model_folder_weights(Path(weights_dir).expanduser())  # type: ignore[arg-type]
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
    for stem in TARGETS:
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


def read_state_dict(path: Path) -> dict[str, Any]:
    """One target's state dict from ``path`` (``torch.load``, tensors only, on CPU), checked to
    have the keys of an OpenUnmix model (:data:`STATE_DICT_KEYS`)."""
    torch = import_torch()
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # noqa: BLE001 - any unpickling failure means a bad file
        raise InputError(f"cannot read OpenUnmix weights ({exc})", path) from exc
    if not isinstance(state, dict) or any(key not in state for key in STATE_DICT_KEYS):
        raise InputError("not an OpenUnmix state dict (needs fc1, lstm, input/output_mean)", path)
    return state
