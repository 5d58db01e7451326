"""Synthetic 4/4 dance music at a known tempo: kick, snare, hi-hats, bass line and melody.

Pure functions: parameters in, float32 samples out. The point is music whose onsets, beats and
(later) drum/bass/melody stems mean something, at the exact tempo of an AIST music id.
"""

from __future__ import annotations

import numpy as np

# A minor pentatonic over two octaves, as semitone offsets from A2 (110 Hz).
_PENTATONIC = np.array([0, 3, 5, 7, 10, 12, 15, 17, 19, 22, 24])
# One chord root per measure, cycling: i – VI – III – VII in A minor (semitones from A).
_PROGRESSION = np.array([0, 8, 3, 10])


def _decay(n: int, sr: int, tau_s: float) -> np.ndarray:
    return np.exp(-np.arange(n) / (tau_s * sr))


def _kick(sr: int) -> np.ndarray:
    n = int(0.25 * sr)
    t = np.arange(n) / sr
    freq = 45.0 + 80.0 * np.exp(-t / 0.03)  # pitch drops from 125 Hz to 45 Hz
    phase = 2 * np.pi * np.cumsum(freq) / sr
    return (np.sin(phase) * _decay(n, sr, 0.08)).astype(np.float32)


def _snare(sr: int, rng: np.random.Generator) -> np.ndarray:
    n = int(0.18 * sr)
    t = np.arange(n) / sr
    noise = rng.standard_normal(n) * _decay(n, sr, 0.045)
    tone = 0.5 * np.sin(2 * np.pi * 190.0 * t) * _decay(n, sr, 0.03)
    return (0.6 * noise + tone).astype(np.float32)


def _hihat(sr: int, rng: np.random.Generator) -> np.ndarray:
    n = int(0.05 * sr)
    noise = rng.standard_normal(n)
    bright = np.diff(noise, prepend=0.0)  # first difference: a cheap high-pass
    return (0.35 * bright * _decay(n, sr, 0.012)).astype(np.float32)


def _tone(freq_hz: float, n: int, sr: int, harmonics: int, tau_s: float) -> np.ndarray:
    t = np.arange(n) / sr
    wave = sum(np.sin(2 * np.pi * freq_hz * h * t) / h for h in range(1, harmonics + 1))
    attack = np.minimum(1.0, np.arange(n) / (0.005 * sr))
    return (wave * attack * _decay(n, sr, tau_s)).astype(np.float32)


def _place(out: np.ndarray, sample: np.ndarray, start: int, gain: float) -> None:
    stop = min(out.shape[0], start + sample.shape[0])
    if start < stop:
        out[start:stop] += gain * sample[: stop - start]


def synth_dance_music(
    bpm: float,
    duration_s: float,
    sr: int = 22050,
    seed: int = 0,
) -> np.ndarray:
    """Mono float32 music in [-1, 1] at ``bpm`` in 4/4, starting on a downbeat at t = 0.

    Kick on beats 1 and 3 (plus a pickup on the "and" of 4 in odd measures), snare on 2 and 4,
    closed hi-hat on every eighth note, a bass note on every beat following a four-chord
    progression, and a pentatonic melody on eighth notes. ``seed`` varies timbre and melody.
    """
    rng = np.random.default_rng(seed)
    n = int(round(duration_s * sr))
    drums = np.zeros(n, dtype=np.float32)
    bass = np.zeros(n, dtype=np.float32)
    melody = np.zeros(n, dtype=np.float32)
    beat_s = 60.0 / bpm
    kick, snare, hihat = _kick(sr), _snare(sr, rng), _hihat(sr, rng)
    n_beats = int(np.ceil(duration_s / beat_s)) + 1
    bass_len = int(0.9 * beat_s * sr)
    note_len = int(0.5 * beat_s * sr)
    # A song repeats a handful of pitches: render each tone once (same samples, far faster).
    bass_tones: dict[float, np.ndarray] = {}
    melody_tones: dict[float, np.ndarray] = {}
    for beat in range(n_beats):
        measure, position = divmod(beat, 4)
        start = int(round(beat * beat_s * sr))
        half = int(round((beat + 0.5) * beat_s * sr))
        if position in (0, 2):
            _place(drums, kick, start, 1.0)
        else:
            _place(drums, snare, start, 0.8)
        if position == 3 and measure % 2 == 1:
            _place(drums, kick, half, 0.7)
        _place(drums, hihat, start, 1.0)
        _place(drums, hihat, half, 0.6)
        root = _PROGRESSION[measure % len(_PROGRESSION)]
        bass_freq = 55.0 * 2 ** ((root + (7 if position == 2 else 0)) / 12)
        if bass_freq not in bass_tones:
            bass_tones[bass_freq] = _tone(bass_freq, bass_len, sr, 4, 0.35 * beat_s)
        _place(bass, bass_tones[bass_freq], start, 0.5)
        for onset in (start, half):
            if rng.random() < 0.8:
                step = _PENTATONIC[rng.integers(len(_PENTATONIC))]
                freq = 220.0 * 2 ** ((root + step) / 12)
                if freq not in melody_tones:
                    melody_tones[freq] = _tone(freq, note_len, sr, 3, 0.25 * beat_s)
                _place(melody, melody_tones[freq], onset, 0.25)
    mix = 0.55 * drums + 0.35 * bass + 0.3 * melody
    peak = float(np.max(np.abs(mix))) or 1.0
    return (0.9 * mix / peak).astype(np.float32)
