"""Options of ``dancedata featurize`` that choose and configure the audio feature families."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

AudioFamilies = Annotated[
    str | None,
    typer.Option(
        help="Audio feature families, comma-separated. Default set: fact (onset_env, mfcc, "
        "chroma_cens, onset_peaks, beats), stems (onset_env, mfcc, onset_peaks of each of "
        "drums, bass, vocals, other under audio/stems/<stem>/), nmfd (audio/nmfd_drums (A, 3): "
        "kick, snare, hi-hat NMFD activations of the drums stem). On request: mel96 (96-bin "
        "log-power mel at the motion frame rate, ChoreoGraph), stft_frames (per-motion-frame "
        "STFT: --stft-sr Hz, one chunk per frame, hop 200, n_fft 2048 → (A, 1025, k), k = 2 at "
        "60 fps and 16 kHz), tempogram (autocorrelation tempogram, --tempogram-frames lags). "
        "Default: fact,stems,nmfd (fact alone with --stems none).",
    ),
]
Stems = Annotated[
    str,
    typer.Option(
        help="Stem backend for the stems and nmfd families: offline (no weights: HPSS, "
        "frequency bands, repetition mask), openunmix (pretrained OpenUnmix; needs the 'stems' "
        "extra and local weights, see --stems-weights) or none (no stem families).",
    ),
]
StemsModel = Annotated[
    str,
    typer.Option(
        help="OpenUnmix model: umxhq (MUSDB18-HQ) or umxl (larger; weights CC BY-NC-SA 4.0).",
    ),
]
StemsWeights = Annotated[
    Path | None,
    typer.Option(
        help="Folder with the OpenUnmix weight files (<DIR>/<model>/<file> or <DIR>/<file>), or "
        "an openunmix model folder (separator.json + <target>.pth, its settings are read); "
        "default: the torch hub cache. Nothing is downloaded. Their sha256 go into the config.",
    ),
]
StemsMemoryMb = Annotated[
    float,
    typer.Option(
        min=1.0,
        help="OpenUnmix: separate a whole track in one pass (as openunmix does) when its estimated "
        "peak memory fits this many MB (about 26 MB per second of stereo 44.1 kHz), else in "
        "cross-faded chunks that fit. Recorded.",
    ),
]
NmfdIterations = Annotated[
    int, typer.Option(min=1, help="NMFD iterations (KL multiplicative updates) on the drums stem.")
]
NmfdTemplateFrames = Annotated[
    int,
    typer.Option(min=1, help="NMFD template length in feature frames (8 → 133 ms at 60 fps)."),
]
StftSr = Annotated[
    int,
    typer.Option(
        min=1000,
        help="Sample rate (Hz) of the stft_frames family; k = 1 + round(sr / fps) // 200 STFT "
        "frames per motion frame (the genre study's 1025 × 6 needs e.g. 32000 at 30 fps).",
    ),
]
TempogramFrames = Annotated[
    int, typer.Option(min=2, help="Tempogram window in feature frames (384 → 6.4 s at 60 fps).")
]
CacheDir = Annotated[
    Path | None,
    typer.Option(
        help="Feature cache folder (per-track audio features by content). Default: "
        "$DANCEDATA_CACHE, else ~/.cache/dancedata/features.",
    ),
]
UseCache = Annotated[
    bool,
    typer.Option(
        "--cache/--no-cache",
        help="Reuse and save per-track audio features in the feature cache.",
    ),
]
AcceptChangedMusic = Annotated[
    bool,
    typer.Option(
        "--accept-changed-music",
        help="Use music files that changed since ingest as they are now: re-hash them and "
        "record the new sha256, size, mtime and header in the new version's music table (and "
        "the new hashes in its config). Without it a changed file stops featurize with a line "
        "naming it.",
    ),
]
MaxAudioSeconds = Annotated[
    float,
    typer.Option(
        min=0,
        help="Most seconds of one track to decode (the span its sequences need plus 30 s, or "
        "the whole track when shorter). A track needing more is refused before decoding; 0: "
        "no limit. With the default families 10 decoded minutes peak at 2.5 GB per worker.",
    ),
]
