"""The settings dataclasses of the feature families, and the command-line options they declare.

A field that the command line sets carries its option in ``metadata["cli"]`` (see
:func:`setting`): the help text, a lower bound, and whether the value is a path. ``dancedata
featurize`` builds its family options from these fields (``cli/audio_options.py``), so a new
setting is one field here, with its help, and it reaches the command line, the settings passed
to the families and (through each family's ``config``) the fingerprint.

Kept free of numpy, scipy and librosa: ``dancedata featurize --help`` imports this module.
"""

from __future__ import annotations

import os
from dataclasses import MISSING, Field, dataclass, field, fields
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from dancedata.compute.stems import StemBackend

__all__ = [
    "STEM_CHOICES",
    "AudioSettings",
    "CliSetting",
    "MotionSettings",
    "cli_settings",
    "setting",
]

STEM_CHOICES: tuple[str, ...] = ("offline", "openunmix", "none")


def setting(
    default: Any = MISSING,
    *,
    help: str | None = None,  # noqa: A002 - the option's help, as click names it
    min: float | None = None,  # noqa: A002 - the option's lower bound, as click names it
    path: bool = False,
    default_factory: Any = MISSING,
) -> Any:
    """A settings field; with ``help`` it is also a ``featurize`` option (``--field-name``).
    ``path``: the option takes a path, resolved to an absolute one before it reaches the
    settings."""
    metadata = {"cli": {"help": help, "min": min, "path": path}} if help else {}
    if default_factory is not MISSING:
        return field(default_factory=default_factory, metadata=metadata)
    return field(default=default, metadata=metadata)


def _default_representations() -> tuple[str, ...]:
    from dancedata.compute.motion_representations import REPRESENTATIONS

    return REPRESENTATIONS


@dataclass
class MotionSettings:
    """Settings every motion family may read; all are fingerprinted via ``config()``.

    ``representations`` and ``euler_order`` are resolved by featurize from its own options
    (the Euler order from the store's rigs when none is given), so they are no options here.
    """

    representations: tuple[str, ...] = field(default_factory=_default_representations)
    euler_order: Any = "XYZ"  # scipy order, or one per joint (EulerOrder)
    # The CLI resolves --smpl-model (else $DANCEDATA_SMPL_MODEL) once; the value travels to
    # workers inside this dataclass, which every task carries.
    smpl_model: str | None = setting(
        help="SMPL model file (.npz/.pkl) for positions of SMPL stores; not bundled (licence): "
        "get it from https://smpl.is.tue.mpg.de. Default: $DANCEDATA_SMPL_MODEL, else the "
        "built-in edge_smpl_offsets skeleton (root at trans, betas 0).",
        path=True,
        default_factory=lambda: os.environ.get("DANCEDATA_SMPL_MODEL"),
    )


@dataclass(frozen=True)
class AudioSettings:
    """Settings of the audio families beyond the FACT recipe; each family fingerprints the ones
    it reads through its ``config``.

    ``stems``: stem backend, ``offline`` (weight-free), ``openunmix`` (pretrained
    ``stems_model`` weights from ``stems_weights`` or the torch hub cache) or ``none``;
    ``stems_memory_mb`` bounds an OpenUnmix pass (whole tracks up to it, else cross-faded chunks).
    ``nmfd_iterations`` (KL multiplicative updates) and ``nmfd_template_frames`` (template length
    in feature frames, 8 → 133 ms at 60 fps) set the drums NMFD. ``stft_sr`` (Hz) is the rate of
    the per-motion-frame STFT family; ``tempogram_frames`` its window in feature frames.
    """

    stems: str = setting(
        "offline",
        help="Stem backend for the stems and nmfd families: offline (no weights: HPSS, "
        "frequency bands, repetition mask), openunmix (pretrained OpenUnmix; needs the 'stems' "
        "extra and local weights, see --stems-weights) or none (no stem families).",
    )
    stems_model: str = setting(
        "umxhq",
        help="OpenUnmix model: umxhq (MUSDB18-HQ) or umxl (larger; weights CC BY-NC-SA 4.0).",
    )
    stems_weights: str | None = setting(
        None,
        help="Folder with the OpenUnmix weight files (<DIR>/<model>/<file> or <DIR>/<file>), or "
        "an openunmix model folder (separator.json + <target>.pth, its settings are read); "
        "default: the torch hub cache. Nothing is downloaded. Their sha256 go into the config.",
        path=True,
    )
    stems_device: str = "cpu"
    stems_memory_mb: float = setting(
        4096.0,
        help="OpenUnmix: separate a whole track in one pass (as openunmix does) when its "
        "estimated peak memory fits this many MB (about 26 MB per second of stereo 44.1 kHz), "
        "else in cross-faded chunks that fit. Recorded.",
        min=1.0,
    )
    nmfd_iterations: int = setting(
        30, help="NMFD iterations (KL multiplicative updates) on the drums stem.", min=1
    )
    nmfd_template_frames: int = setting(
        8, help="NMFD template length in feature frames (8 → 133 ms at 60 fps).", min=1
    )
    stft_sr: int = setting(
        16000,
        help="Sample rate (Hz) of the stft_frames family; k = 1 + round(sr / fps) // 200 STFT "
        "frames per motion frame (the genre study's 1025 × 6 needs e.g. 32000 at 30 fps).",
        min=1000,
    )
    tempogram_frames: int = setting(
        384, help="Tempogram window in feature frames (384 → 6.4 s at 60 fps).", min=2
    )

    @property
    def stem_backend(self) -> StemBackend:
        """The backend object ``stems`` names, chosen from the registry of
        :mod:`dancedata.compute.stems`; the stem families ask it what it needs rather than
        comparing names. InputError for ``none`` or an unknown name."""
        from dancedata.compute.stems import stem_backend

        return stem_backend(self.stems)


@dataclass(frozen=True)
class CliSetting:
    """One settings field as a command-line option: ``--name`` (underscores as dashes),
    ``kind`` (str, int, float, bool or path), the CLI default (a path's is None) and its help."""

    name: str
    kind: str
    default: Any
    help: str
    min: float | None
    optional: bool


def _kind(cls: type, item: Field[Any]) -> tuple[str, bool]:
    """The option type of a field from its annotation: (str | int | float | bool | path,
    optional); a bool is a ``--name/--no-name`` flag."""
    text = item.type if isinstance(item.type, str) else getattr(item.type, "__name__", "")
    parts = [p.strip() for p in str(text).split("|")]
    optional = "None" in parts
    base = [p for p in parts if p != "None"]
    if item.metadata["cli"]["path"]:
        return "path", optional
    if len(base) != 1 or base[0] not in ("str", "int", "float", "bool"):
        raise TypeError(f"{cls.__name__}.{item.name}: option type {text!r} is not str/int/float")
    return base[0], optional


def cli_settings(cls: type) -> list[CliSetting]:
    """The fields of the settings dataclass ``cls`` that are command-line options, in order."""
    out = []
    for item in fields(cls):
        cli = item.metadata.get("cli")
        if not cli:
            continue
        kind, optional = _kind(cls, item)
        default = None if item.default is MISSING else item.default
        out.append(CliSetting(item.name, kind, default, cli["help"], cli["min"], optional))
    return out
