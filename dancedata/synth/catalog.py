"""Which sequences a synthetic AIST++ dataset holds, and how they fall into the splits.

Pure planning, no IO. The full twin mirrors AIST++: 1408 sequences over 10 genres × 6 music ids
(real tempi), basic pieces of 4 measures and advanced pieces of about 16 measures (7.4–48 s),
the real split sizes (crossmodal train/val/test 980/20/20 with val/test on the held-out music
ids, pose 868/70/470) and an ignore list of 45 with 28 of them in crossmodal train. The demo
picks a small, balanced subset of the same plan, with splits in the same proportions.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, replace

from dancedata.io.aist_names import GENRES, HELD_OUT_MUSIC_IDS, music_bpm

FPS = 60.0
GENRE_ORDER: tuple[str, ...] = tuple(GENRES)  # gBR, gPO, gLO, gMH, gLH, gHO, gWA, gKR, gJS, gJB
N_FULL = 1408
# The real AIST++ split sizes (docs/FORMATS.md, "Splits").
CROSSMODAL_SIZES: dict[str, int] = {"train": 980, "val": 20, "test": 20}
POSE_SIZES: dict[str, int] = {"train": 868, "val": 70, "test": 470}
IGNORE_SIZE, IGNORE_IN_CROSSMODAL_TRAIN = 45, 28
# Real durations run from 7.4 s to 48 s; basic pieces at the fastest tempi are stretched to 7.4 s.
MIN_DURATION_S = 7.4


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
    pose_split: str = "train"  # pose split: train / val / test

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
        n_frames = max(frames_for_measures(bpm, 4), math.ceil(MIN_DURATION_S * FPS))
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
    return assign_pose_splits(plan, seed)


def _ranked(names: list[str], seed: int, purpose: str) -> list[str]:
    """``names`` in a seed-dependent order that does not depend on their input order."""
    return sorted(names, key=lambda name: (stable_seed(seed, purpose, name), name))


def _scaled(sizes: dict[str, int], n: int) -> dict[str, int]:
    """Split sizes in the proportions of ``sizes`` for ``n`` sequences (exact when n = 1408)."""
    total = sum(sizes.values())
    scaled = {k: round(v * n / total) for k, v in sizes.items() if k != "train"}
    scaled["train"] = n - sum(scaled.values())
    return scaled


def assign_pose_splits(plan: list[PlannedSequence], seed: int) -> list[PlannedSequence]:
    """Pose split of every sequence: test and val drawn at random in the real proportions
    (470 and 70 of 1408), the rest train."""
    sizes = _scaled(POSE_SIZES, len(plan))
    ranked = _ranked([s.seq_id for s in plan], seed, "pose")
    split_of = {name: "test" for name in ranked[: sizes["test"]]}
    split_of |= {name: "val" for name in ranked[sizes["test"] : sizes["test"] + sizes["val"]]}
    return [replace(s, pose_split=split_of.get(s.seq_id, "train")) for s in plan]


def full_plan(seed: int = 0) -> list[PlannedSequence]:
    """AIST++ scale: 1408 sequences over 10 genres × 6 music ids.

    Per genre, 3 dancers × 6 music ids × 7 basic choreographies (126 basic pieces) plus 15
    advanced pieces (14 in the last two genres) on the training songs. Crossmodal test and val
    take two basic ch02 / ch03 pieces of the held-out song each, as the official split does (20
    each); train takes every advanced piece and basic pieces on the other songs up to 980; the
    rest belong to no crossmodal split. Pose splits: see :func:`assign_pose_splits`.
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
    # Trim crossmodal train to the real 980: advanced pieces stay, basic ones are drawn.
    advanced = sum(s.split == "train" and s.situation == "sFM" for s in plan)
    basic = [s.seq_id for s in plan if s.split == "train" and s.situation == "sBM"]
    keep = set(_ranked(basic, seed, "crossmodal")[: CROSSMODAL_SIZES["train"] - advanced])
    plan = [
        replace(s, split="none")
        if s.situation == "sBM" and s.split == "train" and s.seq_id not in keep
        else s
        for s in plan
    ]
    return assign_pose_splits(plan, seed)


def ignore_list(plan: list[PlannedSequence], seed: int = 0) -> list[str]:
    """Sequences with "bad motion fits", as AIST++'s ignore list: 45 of 1408 (3.2%, at least
    one), 28 of the 45 from crossmodal train and the rest from sequences in no crossmodal split
    (from train when there are none), never from val or test."""
    train = [s.seq_id for s in plan if s.split == "train"]
    other = [s.seq_id for s in plan if s.split == "none"]
    if not train and not other:
        return []
    n = max(1, round(IGNORE_SIZE * len(plan) / N_FULL))
    n_train = round(n * IGNORE_IN_CROSSMODAL_TRAIN / IGNORE_SIZE) if other else n
    chosen = _ranked(train, seed, "ignore")[:n_train]
    chosen += _ranked(other, seed, "ignore")[: n - len(chosen)]
    return sorted(chosen)
