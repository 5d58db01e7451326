"""``dancedata tempo``: the estimated tempo of music files, with its half and double."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from dancedata.cli.common import Json
from dancedata.cli.main import app


@app.command()
def tempo(
    files: Annotated[list[Path], typer.Argument(help="Music files (WAV, FLAC, OGG, MP3, ...).")],
    max_seconds: Annotated[
        float,
        typer.Option("--max-seconds", min=1.0, help="Analyse at most the first this many seconds."),
    ] = 600.0,
    as_json: Json = False,
) -> None:
    """Estimate each file's tempo as ingest does (librosa beat_track's estimate at 22050 Hz,
    hop 512, without the beat tracker) and print it with its half and double. Confidence: each
    candidate's share of the three candidates' mean tempogram strength (1/3 each when equal).

    Example: dancedata tempo music/mBR0.wav music/mPO1.ogg --json
    """
    from dancedata.compute.tempo import (
        START_BPM,
        TEMPO_HOP,
        TEMPO_SR,
        estimate_tempo,
        onset_envelope,
    )
    from dancedata.io.audio import load_mono

    results = []
    for path in files:
        y = load_mono(path, TEMPO_SR, max_seconds=max_seconds)
        estimate = estimate_tempo(onset_envelope(y, TEMPO_SR, TEMPO_HOP), TEMPO_SR, TEMPO_HOP)
        seconds = y.shape[0] / TEMPO_SR
        results.append((path, seconds, estimate))
        if not as_json:
            typer.echo(f"{path}: {estimate.line()} over {seconds:.1f} s")
    if as_json:
        rows = [
            {"file": str(path), "seconds": round(seconds, 3), **estimate.as_dict()}
            for path, seconds, estimate in results
        ]
        method = {"method": "librosa.beat.beat_track tempo", "sr": TEMPO_SR, "hop": TEMPO_HOP}
        typer.echo(json.dumps({"tempo": rows, "estimator": method}, indent=2))
        return
    stronger = [path for path, _, estimate in results if estimate.stronger_alternative()]
    if stronger:
        typer.echo(
            f"note: in {len(stronger)} of {len(results)} file(s) the half or double has the higher "
            f"confidence: the estimate weighs the tempogram by a prior around {START_BPM:g} BPM "
            "(as librosa's beat_track and ingest do), the confidence does not; if you know the "
            "tempo, pass it to ingest with --bpm"
        )
