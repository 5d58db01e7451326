"""The baseline of bench_pipeline.py: what published AIST++ preprocessing scripts do.

Per sequence, with no reuse between sequences: load the motion pickle, load the music with
librosa (decoding and resampling to 30720 Hz), compute the FACT 35-d audio features (onset
strength, 20 MFCC, 12 chroma_cens, onset peaks, beats with the known BPM), and np.save one file
per sequence. Written for this bench from the recipe (docs/FORMATS.md), not copied.

Usage: python bench/baseline_fact.py RAW OUT SEQ_ID...   → JSON lines, one per sequence, with
wall and CPU seconds.
"""

from __future__ import annotations

import json
import pickle
import sys
import time
from pathlib import Path

import numpy as np

SR = 30720
HOP = 512


def music_bpm(music_id: str) -> float:
    """AIST++ tempo: 80 + 10k BPM, House 110 + 5k."""
    k = int(music_id[-1])
    return 110.0 + 5 * k if music_id[1:3] == "HO" else 80.0 + 10 * k


def one_sequence(raw: Path, out: Path, seq_id: str) -> None:
    import librosa

    # Plain pickle.load, as the published scripts do (these are our own synthetic files).
    with open(raw / "motions" / f"{seq_id}.pkl", "rb") as handle:
        data = pickle.load(handle)
    motion = np.concatenate(
        [data["smpl_trans"] / data["smpl_scaling"], data["smpl_poses"]], axis=1
    ).astype(np.float32)
    music_id = seq_id.split("_")[4]
    y, _ = librosa.load(str(raw / "wav" / f"{music_id}.wav"), sr=SR)
    envelope = librosa.onset.onset_strength(y=y, sr=SR, hop_length=HOP)
    mfcc = librosa.feature.mfcc(y=y, sr=SR, n_mfcc=20, hop_length=HOP).T
    chroma = librosa.feature.chroma_cens(y=y, sr=SR, hop_length=HOP, n_chroma=12).T
    peaks = librosa.onset.onset_detect(onset_envelope=envelope, sr=SR, hop_length=HOP)
    _, beats = librosa.beat.beat_track(
        onset_envelope=envelope,
        sr=SR,
        hop_length=HOP,
        start_bpm=music_bpm(music_id),
        tightness=100,
    )
    n = min(len(envelope), mfcc.shape[0], chroma.shape[0])
    peak_onehot = np.zeros(n, np.float32)
    peak_onehot[peaks[peaks < n]] = 1
    beat_onehot = np.zeros(n, np.float32)
    beat_onehot[beats[beats < n]] = 1
    audio = np.concatenate(
        [envelope[:n, None], mfcc[:n], chroma[:n], peak_onehot[:, None], beat_onehot[:, None]],
        axis=1,
    )
    frames = min(n, motion.shape[0])
    np.save(out / f"{seq_id}.npy", np.concatenate([motion[:frames], audio[:frames]], axis=1))


def main(argv: list[str]) -> int:
    raw, out, seq_ids = Path(argv[0]), Path(argv[1]), argv[2:]
    out.mkdir(parents=True, exist_ok=True)
    for seq_id in seq_ids:
        wall, cpu = time.perf_counter(), time.process_time()
        one_sequence(raw, out, seq_id)
        record = {
            "seq_id": seq_id,
            "seconds": time.perf_counter() - wall,
            "cpu_seconds": time.process_time() - cpu,
        }
        print(json.dumps(record), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
