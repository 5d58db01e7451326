"""Which sequences a synthetic AIST++ dataset holds, and how they fall into the splits.

Pure planning, no IO. The full twin mirrors AIST++: 10 genres × 6 music ids (real tempi),
basic pieces of 4 measures and advanced pieces of about 16 measures, held-out music ids for
crossmodal val/test. The demo picks a small, balanced subset of the same plan.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

from dancedata.aist_names import GENRES, HELD_OUT_MUSIC_IDS, music_bpm

FPS = 60.0
GENRE_ORDER: tuple[str, ...] = tuple(GENRES)  # gBR, gPO, gLO, gMH, gLH, gHO, gWA, gKR, gJS, gJB


@dataclass(frozen=True)
class PlannedSequence:
    seq_id: str
    genre: str
    situation: str
    dancer: str
    music_id: str
    choreo: str
    n_frames: int
    split: str  # crossmodal split: train / val / test / none

    @property
    def bpm(self) -> float:
        return music_bpm(self.music_id)


def stable_seed(*parts: object) -> int:
    """A seed that depends only on ``parts`` (not on Python's per-process hash salt)."""
    return zlib.crc32("|".join(map(str, parts)).encode())


def frames_for_measures(bpm: float, measures: float, fps: float = FPS) -> int:
    """Frames spanned by ``measures`` 4/4 measures at ``bpm``: measures × 4 × 60 / bpm × fps."""
    return int(round(measures * 4 * 60.0 / bpm * fps))


def _dancers(genre_index: int) -> list[str]:
    return [f"d{3 * genre_index + k:02d}" for k in (1, 2, 3)]


def _name(genre: str, situation: str, dancer: str, music_id: str, choreo: int) -> str:
    return f"{genre}_{situation}_cAll_{dancer}_{music_id}_ch{choreo:02d}"


def _sequence(
    genre: str, situation: str, dancer: str, music_id: str, choreo: int, split: str, seed: int
) -> PlannedSequence:
    bpm = music_bpm(music_id)
    if situation == "sBM":
        n_frames = frames_for_measures(bpm, 4)
    else:
        # Advanced pieces: about 16 measures, a frame or two short of the last downbeat.
        n_frames = frames_for_measures(bpm, 16) - 1 - stable_seed(seed, genre, dancer) % 2
    seq_id = _name(genre, situation, dancer, music_id, choreo)
    return PlannedSequence(
        seq_id, genre, situation, dancer, music_id, f"ch{choreo:02d}", n_frames, split
    )


def demo_plan(n_sequences: int, seed: int = 0) -> list[PlannedSequence]:
    """A balanced demo subset: per genre a basic and an advanced piece sharing a training song,
    then a test and a val basic piece on the genre's held-out song, over as many genres as
    ``n_sequences`` allows (at least 3, so at least 3 tempi)."""
    if n_sequences < 1:
        raise ValueError("n_sequences must be at least 1")
    n_genres = min(len(GENRE_ORDER), max(3, -(-n_sequences // 4)))
    per_genre: list[list[PlannedSequence]] = []
    for gi, genre in enumerate(GENRE_ORDER[:n_genres]):
        held_out = next(m for m in HELD_OUT_MUSIC_IDS if m[1:3] == genre[1:3])
        train_music = f"m{genre[1:3]}{(int(held_out[-1]) + 1 + gi) % 6}"
        if train_music == held_out:
            train_music = f"m{genre[1:3]}{(int(held_out[-1]) + 2) % 6}"
        a, b, _ = _dancers(gi)
        per_genre.append(
            [
                _sequence(genre, "sBM", a, train_music, 1, "train", seed),
                _sequence(genre, "sFM", b, train_music, 3, "train", seed),
                _sequence(genre, "sBM", a, held_out, 2, "test", seed),
                _sequence(genre, "sBM", b, held_out, 2, "val", seed),
            ]
        )
    plan: list[PlannedSequence] = []
    for round_ in range(4):
        for genre_seqs in per_genre:
            if len(plan) < n_sequences:
                plan.append(genre_seqs[round_])
    return plan


def full_plan(seed: int = 0) -> list[PlannedSequence]:
    """AIST++ scale: 1408 sequences over 10 genres × 6 music ids.

    Per genre, 3 dancers × 6 music ids × 7 basic choreographies (126 basic pieces) plus 15
    advanced pieces (14 in the last two genres) on the training songs. Crossmodal test and val
    take two basic ch02 pieces of the held-out song each, as the official split does; the
    remaining pieces on held-out songs belong to no crossmodal split.
    """
    plan: list[PlannedSequence] = []
    for gi, genre in enumerate(GENRE_ORDER):
        held_out = next(m for m in HELD_OUT_MUSIC_IDS if m[1:3] == genre[1:3])
        dancers = _dancers(gi)
        music_ids = [f"m{genre[1:3]}{k}" for k in range(6)]
        for music_id in music_ids:
            for di, dancer in enumerate(dancers):
                for choreo in range(1, 8):
                    if music_id != held_out:
                        split = "train"
                    elif choreo == 2 and di < 2:
                        split = "test"
                    elif choreo == 3 and di < 2:
                        split = "val"
                    else:
                        split = "none"
                    plan.append(_sequence(genre, "sBM", dancer, music_id, choreo, split, seed))
        train_music = [m for m in music_ids if m != held_out]
        n_advanced = 14 if gi >= 8 else 15
        for k in range(n_advanced):
            music_id = train_music[k % len(train_music)]
            dancer = dancers[k % 3]
            plan.append(_sequence(genre, "sFM", dancer, music_id, 10 + k, "train", seed))
    return plan


def ignore_list(plan: list[PlannedSequence], seed: int = 0) -> list[str]:
    """About 3% of the sequences (at least one when any are planned), drawn from training
    sequences, as AIST++'s ignore list of sequences with bad motion fits."""
    train = [s.seq_id for s in plan if s.split == "train"]
    if not train:
        return []
    n = max(1, round(0.032 * len(plan)))
    ranked = sorted(train, key=lambda name: stable_seed(seed, "ignore", name))
    return sorted(ranked[:n])
