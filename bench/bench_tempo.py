"""Tempo of a music file in a fresh process: ``librosa.beat.beat_track`` (what ingest ran before)
against :func:`dancedata.compute.tempo.estimate_tempo` and the ``dancedata tempo`` command itself
(issue 23, item 5).

Each way runs in its own new Python process (imports, decoding and numba compilation included,
as a user running one command pays them): decode the file to mono 22050 Hz, estimate, print.
Reported: wall seconds, CPU seconds of the child (user + system, the stable figure on a shared
machine), the estimate, and the load average before and after.

Usage: .venv/bin/python bench/bench_tempo.py [FILE ...] (default: the Vibe Ace track of the
real-data folder, ``$DANCEDATA_REAL_DATA`` or ``../shared/data/real``)
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
REAL = Path(os.environ.get("DANCEDATA_REAL_DATA", REPO.parent / "shared" / "data" / "real"))
DEFAULT = REAL / "audio" / "Kevin_MacLeod_-_Vibe_Ace.hq.ogg"

BEAT_TRACK = """
import sys, librosa
from dancedata.io.audio import load_mono
y = load_mono(sys.argv[1], 22050)
tempo, _ = librosa.beat.beat_track(y=y, sr=22050, hop_length=512)
print(float(tempo[0]) if hasattr(tempo, '__len__') else float(tempo))
"""

DANCEDATA = """
import sys
from dancedata.compute.tempo import estimate_tempo, onset_envelope
from dancedata.io.audio import load_mono
y = load_mono(sys.argv[1], 22050)
print(estimate_tempo(onset_envelope(y)).bpm)
"""


# The command a user runs (CLI import, decode, estimate, the printed line), read back as JSON.
COMMAND = ["-m", "dancedata.cli", "tempo", "--json"]


def run(args: list[str], path: Path) -> tuple[float, float, str]:
    """(wall s, child CPU s, BPM as text) of ``python ARGS PATH`` in a new interpreter."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, *args, str(path)], capture_output=True, text=True, check=True
    )
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    out = done.stdout.strip()
    if args is COMMAND:
        out = str(json.loads(out)["tempo"][0]["bpm"])
    return wall, cpu, out


def main(argv: list[str]) -> int:
    files = [Path(a) for a in argv] or [DEFAULT]
    print(f"load average at start {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    print("| file | way | wall s | CPU s | BPM |")
    print("|---|---|---:|---:|---:|")
    for path in files:
        ways = (
            ("beat_track (before)", ["-c", BEAT_TRACK]),
            ("dancedata estimate_tempo", ["-c", DANCEDATA]),
            ("dancedata tempo (command)", COMMAND),
        )
        for name, args in ways:
            wall, cpu, out = run(args, path)
            print(f"| {path.name} | {name} | {wall:.1f} | {cpu:.1f} | {float(out):.2f} |")
    print(f"load average at the end {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
