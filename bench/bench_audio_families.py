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

Then **CPU seconds per track of the default set, before and after** the audio speed-up: the
code at ``--before`` (default: the commit before it) is extracted with ``git archive`` into a
temporary folder and run side by side with this checkout, each in its own fresh process,
alternately (``--rounds``), on the same track: the song above as a file, its first ``--seconds``
decoded. Each process pins BLAS/OpenMP to one thread first, as featurize's worker processes
do (``dancedata.exec.threads.pin_threads``), and reports

* ``startup``: imports, numba compilation and a first 2 s track (what every worker process pays
  before its first real track);
* per part, from featurize's own per-track step timings (:func:`compute_track_features`), with
  the process's clock switched to CPU time: ``decode``, ``fact`` (with the mix's STFT, which
  the stems now reuse), ``separate`` (offline stems), ``stems`` (per-stem features, with the
  drums stem's |STFT|, which ``nmfd`` now reuses), ``nmfd``;
* ``track``: the whole track (all of the above), the median of ``--repeats`` tracks.

CPU seconds are the stable figure on a shared machine (wall time follows the load); the load
average is printed with them. ``--no-before`` skips the side-by-side run.

Usage: .venv/bin/python bench/bench_audio_families.py [--seconds 30] [--umxl] [--json]
       [--before COMMIT] [--rounds 2] [--repeats 3] [--no-before] [--per-track-only]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

SR = 30720
ROOT = Path(__file__).resolve().parents[1]
BEFORE = "b417ef3"  # the last commit before the audio speed-up
VIBE_ACE = "Kevin_MacLeod_-_Vibe_Ace.hq.ogg"
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
        from dancedata.featurize import stem_separation

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


def song_file(folder: Path, seconds: float) -> Path:
    """The bench song as a file: Vibe Ace itself, else the generated song written as WAV."""
    path = _REAL / "audio" / VIBE_ACE
    if path.is_file():
        return path
    import soundfile as sf

    y, _ = load_song(seconds)
    out = folder / "song.wav"
    sf.write(out, y, SR, subtype="FLOAT")
    return out


def child(path: str, seconds: float, repeats: int) -> dict[str, object]:
    """Runs in a fresh process whose ``sys.path`` starts at the code to measure: CPU seconds of
    startup, of each step of one track, and of whole tracks (see the module docstring)."""
    import warnings

    warnings.simplefilter("ignore")
    start = time.process_time()
    # featurize's step timings read time.perf_counter; in this process they read CPU time
    time.perf_counter = time.process_time
    import dancedata
    from dancedata.exec.threads import pin_threads

    # featurize runs every audio unit with one BLAS thread (worker processes pin their pools,
    # in-process units run under ``single_threaded``); unpinned, OpenBLAS's second thread spins
    # and bills CPU time that featurize does not pay (the mel products: ~0.15 CPU s a track)
    pin_threads(1)
    from dancedata.compute.audio_features import AudioFeatureConfig

    # (a test of the folder, not try/except ImportError: the editable install's finder would
    # serve this checkout's dancedata.featurize to an older tree on PYTHONPATH)
    if (Path(dancedata.__file__).parent / "featurize").is_dir():
        from dancedata.featurize.audio_track import compute_track_features
        from dancedata.featurize.families.audio import default_families
        from dancedata.featurize.family_settings import AudioSettings
    else:  # code from before the layers redesign (b417ef3): the same functions, elsewhere
        from dancedata.pipeline.audio_families import default_families  # type: ignore
        from dancedata.pipeline.audio_track import compute_track_features  # type: ignore
        from dancedata.pipeline.family_settings import AudioSettings  # type: ignore

    settings, cfg = AudioSettings(), AudioFeatureConfig()
    families = tuple(default_families(settings))
    compute_track_features(families, settings, cfg, path, 120.0, span_s=2.0)
    startup = time.process_time() - start
    tracks, parts = [], []
    for _ in range(repeats):
        began = time.process_time()
        _, stats = compute_track_features(families, settings, cfg, path, 120.0, span_s=seconds)
        tracks.append(time.process_time() - began)
        parts.append(stats["seconds"])
    median = {k: statistics.median(p.get(k, 0.0) for p in parts) for k in parts[0]}
    return {
        "code": str(Path(dancedata.__file__).parent.parent),
        "startup_cpu_s": startup,
        "track_cpu_s": statistics.median(tracks),
        "parts_cpu_s": median,
        "beat_module_imported": "librosa.beat" in sys.modules,
    }


def run_child(code: Path, path: Path, seconds: float, repeats: int) -> dict[str, object]:
    env = {**os.environ, "PYTHONPATH": str(code)}
    argv = [sys.executable, __file__, "--child", str(path), "--seconds", str(seconds)]
    argv += ["--repeats", str(repeats)]
    load = os.getloadavg()[0]
    wall = time.perf_counter()
    out = subprocess.run(argv, env=env, capture_output=True, text=True, check=True).stdout
    result = json.loads(out.strip().splitlines()[-1])
    result.update(load=load, wall_s=time.perf_counter() - wall)
    return result


def extract(commit: str, folder: Path) -> Path | None:
    """The package at ``commit`` in ``folder`` (git archive), or None without git or commit."""
    try:
        tar = subprocess.run(
            ["git", "-C", str(ROOT), "archive", commit, "dancedata"],
            capture_output=True,
            check=True,
        ).stdout
        subprocess.run(["tar", "-x", "-C", str(folder)], input=tar, check=True)
    except (OSError, subprocess.CalledProcessError):
        return None
    return folder


def per_track(args: argparse.Namespace) -> dict[str, object]:
    """Before/after CPU seconds per track, each side in fresh processes, alternately."""
    sides: dict[str, list[dict[str, object]]] = {"after": []}
    with tempfile.TemporaryDirectory() as tmp:
        path = song_file(Path(tmp), args.seconds)
        (Path(tmp) / "before").mkdir()
        before = None if args.no_before else extract(args.before, Path(tmp) / "before")
        if before is not None:
            sides["before"] = []
        for _ in range(args.rounds):
            if before is not None:
                sides["before"].append(run_child(before, path, args.seconds, args.repeats))
            sides["after"].append(run_child(ROOT, path, args.seconds, args.repeats))
    return {"song": path.name, "seconds": args.seconds, "runs": sides}


def _best(runs: list[dict[str, object]], key: str, part: str | None = None) -> float:
    """The lowest over the runs: on a shared machine other jobs only ever add CPU time."""
    if part is None:
        return min(float(r[key]) for r in runs)  # type: ignore[arg-type]
    return min(float(r[key].get(part, 0.0)) for r in runs)  # type: ignore[union-attr]


def print_per_track(result: dict[str, object]) -> None:
    runs: dict[str, list[dict[str, object]]] = result["runs"]  # type: ignore[assignment]
    loads = [float(r["load"]) for side in runs.values() for r in side]
    print(
        f"\nCPU s per track of the default set (fact + offline stems + per-stem features + "
        f"nmfd), {result['seconds']:g} s of {result['song']}, best of {len(runs['after'])} "
        f"fresh processes per side; load average {min(loads):.1f}-{max(loads):.1f}"
    )
    parts = ["decode", "fact", "separate", "stems", "nmfd"]
    sides = [s for s in ("before", "after") if s in runs]
    print(
        f"  {'step':<22}"
        + "".join(f"{s:>10}" for s in sides)
        + ("   ratio" if len(sides) > 1 else "")
    )
    rows = [(p, "parts_cpu_s", p) for p in parts]
    rows += [
        ("track (all steps)", "track_cpu_s", None),
        ("startup (imports, JIT)", "startup_cpu_s", None),
    ]
    for label, key, part in rows:
        values = [_best(runs[s], key, part) for s in sides]
        ratio = f"  x{values[0] / values[1]:.2f}" if len(values) > 1 and values[1] > 0 else ""
        print(f"  {label:<22}" + "".join(f"{v:10.3f}" for v in values) + ratio)
    for side in sides:
        walls = ", ".join(f"{float(r['wall_s']):.0f}" for r in runs[side])
        imported = any(r["beat_module_imported"] for r in runs[side])
        print(f"  {side}: process wall s {walls}; librosa.beat imported: {imported}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--umxl", action="store_true", help="umxl-sized network (hidden 1024)")
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--before", default=BEFORE, help="commit of the code to compare with")
    parser.add_argument("--no-before", action="store_true", help="skip the side-by-side run")
    parser.add_argument("--rounds", type=int, default=2, help="fresh processes per side")
    parser.add_argument("--repeats", type=int, default=3, help="tracks per process")
    parser.add_argument("--per-track-only", action="store_true")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(json.dumps(child(args.child, args.seconds, args.repeats)))
        return 0
    if args.per_track_only:
        result = per_track(args)
        print(json.dumps(result) if args.json else "", end="")
        if not args.json:
            print_per_track(result)
        return 0

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
    track = per_track(args)
    if args.json:
        print(
            json.dumps(
                {"song": source, "seconds": args.seconds, "results": results, "per_track": track}
            )
        )
        return 0
    load = os.getloadavg()[0]
    print(f"{args.seconds:g} s of {source} at {SR} Hz, {os.cpu_count()} cpu(s), load {load:.1f}")
    print(f"  {'family':<16} {'wall s':>8} {'cpu s':>8}   (cpu = all threads of this process)")
    for name, t in results.items():
        print(f"  {name:<16} {t['wall_s']:8.2f} {t['cpu_s']:8.2f}")
    if umx_dir is None:
        print("  stems_openunmix  skipped (pip install 'dancedata[stems]')")
    print_per_track(track)
    return 0


if __name__ == "__main__":
    sys.exit(main())
