"""Store the default audio feature set of the code before the audio speed-up, as the reference
that ``tests/featurize/test_audio_reference.py`` compares today's code against.

Generated once, at commit b417ef3 (the last commit before the audio speed-up), with
``python tests/data/audio_reference/make_reference.py``; its output ``reference.npz`` is
committed. Do not regenerate it with newer code: it is the old code's numbers.

Tracks (:data:`TRACKS`):

* ``vibe_ace``: the real recording Kevin_MacLeod_-_Vibe_Ace.hq.ogg (Ogg Vorbis, 44.1 kHz stereo,
  61.46 s), read from the real public data folder (``$DANCEDATA_REAL_DATA`` or
  ``../shared/data/real`` relative to the repository); its audio is not stored, only its sha256
  (checked by the test) and the features.
* ``synth_a`` .. ``synth_c``: :func:`dancedata.synth.music.synth_dance_music` at three tempos and
  seeds, written as 16-bit PCM WAV at 24 kHz (as the synthetic AIST++ twin writes its music)
  and decoded from that file like any track.

For each track every array the default families (``fact``, ``stems``, ``nmfd``; offline stems)
compute per track is stored untrimmed, as :func:`compute_track_features` returns it (before
featurize trims the track to a common length and slices sequences): key ``<track>/<array path>``,
float arrays as float32, one-hot arrays as uint8. ``<track>/_bpm`` holds the tempo given.
"""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[2]
OUT = HERE / "reference.npz"
VIBE_ACE = "Kevin_MacLeod_-_Vibe_Ace.hq.ogg"
# name → (bpm, seconds, seed) of the synthetic tracks; bpm None for the real one.
TRACKS: dict[str, tuple[float | None, float, int]] = {
    "vibe_ace": (None, 0.0, 0),
    "synth_a": (120.0, 12.0, 1),
    "synth_b": (97.0, 9.0, 2),
    "synth_c": (142.0, 15.0, 3),
}
SYNTH_SR = 24000


def real_audio_dir() -> Path:
    root = Path(os.environ.get("DANCEDATA_REAL_DATA", ROOT.parent / "shared" / "data" / "real"))
    return root / "audio"


def write_synth(folder: Path, name: str) -> Path:
    """The synthetic track ``name`` as a 16-bit WAV file in ``folder``."""
    import soundfile as sf

    from dancedata.synth.music import synth_dance_music

    bpm, seconds, seed = TRACKS[name]
    assert bpm is not None
    path = folder / f"{name}.wav"
    sf.write(path, synth_dance_music(bpm, seconds, sr=SYNTH_SR, seed=seed), SYNTH_SR, "PCM_16")
    return path


def track_path(folder: Path, name: str) -> Path:
    if name == "vibe_ace":
        return real_audio_dir() / VIBE_ACE
    return write_synth(folder, name)


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def features(path: Path, bpm: float | None) -> dict[str, np.ndarray]:
    """Every array of the default families on the track at ``path``, untrimmed, no cache."""
    from dancedata.compute.audio_features import AudioFeatureConfig
    from dancedata.featurize.audio_track import compute_track_features
    from dancedata.featurize.families.audio import default_families
    from dancedata.featurize.family_settings import AudioSettings

    settings = AudioSettings()
    arrays, _ = compute_track_features(
        tuple(default_families(settings)), settings, AudioFeatureConfig(), str(path), bpm
    )
    return arrays


def main() -> int:
    stored: dict[str, np.ndarray] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, (bpm, _, _) in TRACKS.items():
            path = track_path(Path(tmp), name)
            if not path.is_file():
                print(f"missing: {path}", file=sys.stderr)
                return 1
            for key, values in sorted(features(path, bpm).items()):
                values = np.asarray(values)
                dtype = np.uint8 if values.dtype == np.uint8 else np.float32
                stored[f"{name}/{key}"] = values.astype(dtype)
            stored[f"{name}/_bpm"] = np.float64(np.nan if bpm is None else bpm)
            if name == "vibe_ace":
                stored[f"{name}/_sha256"] = np.array(sha256(path))
    np.savez_compressed(OUT, **stored)
    print(f"{OUT.name}: {len(stored)} arrays, {OUT.stat().st_size / 1e6:.2f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
