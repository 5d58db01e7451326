"""Per-song seconds of each audio feature family on one 30 s song at sr 30720 Hz (60 fps).

Prints wall-clock and CPU seconds (all threads) per family; on a shared machine the CPU column is
the steadier of the two.

The song is the first 30 s of the real Vibe Ace recording (shared/data/real/audio) when present,
else 30 s of generated drums + bass. Every family runs once on a 2 s clip first, so that imports,
numba compilation and filter-bank caches are not billed to the song. Families:

* ``fact``            the lead's FACT features (onset_env, mfcc, chroma_cens, peaks, beats)
* ``stems_offline``   weight-free HPSS/band/REPET separation into 4 stems
* ``stems_openunmix`` OpenUnmix with umxhq-sized (or ``--umxl``-sized) random weights: the same
                      compute as the pretrained model, which cannot be downloaded here; skipped
                      without the ``stems`` extra
* ``stem_features``   onset_env + 20 MFCC + onset peaks for each of the 4 stems
* ``nmfd_drums``      NMFD (3 components, 8-frame templates, 50 iterations) of the drums stem
* ``choreograph_mel`` 96-bin mel spectrogram at 60 fps
* ``stft_per_frame``  16 kHz, one STFT chunk per 30 fps motion frame (1025 × 3)
* ``tempogram``       384-lag tempogram at 60 fps

Usage: .venv/bin/python bench/bench_audio_families.py [--seconds 30] [--umxl] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

SR = 30720
_REAL = Path(
    os.environ.get(
        "DANCEDATA_REAL_DATA", Path(__file__).resolve().parents[1].parent / "shared/data/real"
    )
)


def load_song(seconds: float) -> tuple[np.ndarray, str]:
    import librosa

    path = _REAL / "audio" / "Kevin_MacLeod_-_Vibe_Ace.hq.ogg"
    if path.is_file():
        y, _ = librosa.load(path, sr=SR, duration=seconds)
        return y, path.name
    t = np.arange(int(seconds * SR)) / SR
    beat = (t % 0.5) < 0.05
    y = 0.3 * np.sin(2 * np.pi * 60 * t) + beat * np.random.default_rng(0).standard_normal(t.size)
    return y.astype(np.float32), "generated drums + bass"


def umx_weights(folder: Path, hidden: int) -> Path:
    """Random OpenUnmix models with the published architecture, saved under the umxhq names."""
    import torch
    from openunmix.model import OpenUnmix
    from openunmix.utils import bandwidth_to_max_bin

    from dancedata.io.openunmix_weights import MODELS

    max_bin = int(bandwidth_to_max_bin(rate=44100.0, n_fft=4096, bandwidth=16000))
    target = folder / "umxhq"
    target.mkdir(parents=True)
    for file_name in MODELS["umxhq"]["files"].values():
        model = OpenUnmix(nb_bins=2049, nb_channels=2, hidden_size=hidden, max_bin=max_bin)
        torch.save(model.state_dict(), target / file_name)
    return folder


def families(
    umx_dir: Path | None, clips: list[np.ndarray]
) -> dict[str, Callable[[np.ndarray], object]]:
    """Name → function of the song. Stem-based families read offline stems made beforehand for
    each clip in ``clips``, so that separation is billed to ``stems_offline`` only."""
    from dancedata.compute import nmfd, stem_features, stems, study_features

    out: dict[str, Callable[[np.ndarray], object]] = {}
    try:
        from dancedata.compute.audio_features import AudioFeatureConfig, fact_features

        out["fact"] = lambda y: fact_features(y, 120.0, AudioFeatureConfig())
    except ImportError:
        pass
    out["stems_offline"] = lambda y: stems.separate(y, SR, backend="offline")
    if umx_dir is not None:
        from dancedata.pipeline import stem_separation

        out["stems_openunmix"] = lambda y: stem_separation.separate(
            y, SR, backend="openunmix", weights_dir=umx_dir
        )
    prepared = {clip.size: stems.separate(clip, SR) for clip in clips}

    def offline_stems(y: np.ndarray) -> dict[str, np.ndarray]:
        return prepared[y.size]

    out["stem_features"] = lambda y: stem_features.all_stem_features(offline_stems(y), SR)
    out["nmfd_drums"] = lambda y: nmfd.nmfd_drums(offline_stems(y)["drums"], SR)
    out["choreograph_mel"] = lambda y: study_features.choreograph_mel(y, SR)
    out["stft_per_frame"] = lambda y: study_features.stft_per_motion_frame(y, SR, fps=30.0)
    out["tempogram"] = lambda y: study_features.tempogram(y, SR)
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--umxl", action="store_true", help="umxl-sized network (hidden 1024)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()

    song, source = load_song(args.seconds)
    with tempfile.TemporaryDirectory() as tmp:
        try:
            umx_dir = umx_weights(Path(tmp), 1024 if args.umxl else 512)
        except ImportError:
            umx_dir = None
        runs = families(umx_dir, [song[: 2 * SR], song])
        results: dict[str, dict[str, float]] = {}
        for name, run in runs.items():
            run(song[: 2 * SR])  # warm-up: imports, JIT, caches
            wall, cpu = time.perf_counter(), time.process_time()
            run(song)
            results[name] = {
                "wall_s": time.perf_counter() - wall,
                "cpu_s": time.process_time() - cpu,
            }
    if args.json:
        print(json.dumps({"song": source, "seconds": args.seconds, "results": results}))
        return 0
    load = os.getloadavg()[0]
    print(f"{args.seconds:g} s of {source} at {SR} Hz, {os.cpu_count()} cpu(s), load {load:.1f}")
    print(f"  {'family':<16} {'wall s':>8} {'cpu s':>8}   (cpu = all threads of this process)")
    for name, t in results.items():
        print(f"  {name:<16} {t['wall_s']:8.2f} {t['cpu_s']:8.2f}")
    if umx_dir is None:
        print("  stems_openunmix  skipped (pip install 'dancedata[stems]')")
    return 0


if __name__ == "__main__":
    sys.exit(main())
