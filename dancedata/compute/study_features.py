"""Audio feature sets of the other studies the toolkit serves (docs/FORMATS.md, "The three
studies").

Pure functions of a mono waveform, each named after the study whose recipe it follows:

* :func:`choreograph_mel` — ChoreoGraph (ACM MM 2022): a 96-bin mel spectrogram at the motion
  frame rate (60 fps), one STFT hop per motion frame: hop = sr / fps samples.
* :func:`stft_per_motion_frame` — genre-based dance generation (MSc 2019): audio at 16 kHz cut
  into one chunk per motion frame (1/fps s), each chunk its own STFT with hop 200 and n_fft 2048,
  giving 1025 × k values per motion frame (k STFT frames per chunk, :func:`frames_per_chunk`).
* :func:`tempogram` — local autocorrelation tempogram of the onset envelope at the feature frame
  rate (Bailando's 438-d set carries one), computed on request only: 384 values per frame.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from dancedata.errors import InputError

CHOREOGRAPH_N_MELS = 96
CHOREOGRAPH_FPS = 60.0
GENRE_STFT_SR = 16000
GENRE_STFT_HOP = 200
GENRE_STFT_N_FFT = 2048
TEMPOGRAM_WIN_LENGTH = 384


def _mono(y: np.ndarray) -> np.ndarray:
    signal = np.asarray(y, dtype=np.float32)
    if signal.ndim != 1 or signal.size == 0:
        raise InputError(f"audio must be a non-empty mono signal, got shape {signal.shape}")
    if not np.all(np.isfinite(signal)):
        raise InputError("audio contains NaN or infinite samples")
    return signal


def _resample(signal: np.ndarray, sr: float, target_sr: float) -> np.ndarray:
    """``librosa.resample`` (soxr_hq) cut or padded to round(n · target_sr / sr) samples
    (librosa's own ceil can add a sample through float rounding: 30720 → 16000 Hz gives 16001)."""
    import librosa

    if target_sr == sr:
        return signal
    out = librosa.resample(signal, orig_sr=sr, target_sr=target_sr, res_type="soxr_hq")
    return librosa.util.fix_length(out, size=int(round(signal.size * target_sr / sr)))


def hop_for_fps(sr: float, fps: float) -> tuple[int, int]:
    """(sample rate, hop) that give exactly ``fps`` frames per second.

    hop = sr / fps when that is a whole number of samples (30720 Hz at 60 fps → 512); otherwise the
    audio must be resampled to fps × ceil(sr / fps) Hz (22050 Hz at 60 fps → 22080 Hz, hop 368),
    so that feature frame i sits exactly at i / fps seconds instead of drifting.
    """
    if not (sr > 0 and fps > 0):
        raise InputError(f"sample rate and fps must be positive, got sr={sr}, fps={fps}")
    ratio = sr / fps
    if abs(ratio - round(ratio)) < 1e-9 * ratio:
        return int(round(sr)), int(round(ratio))
    hop = math.ceil(ratio)
    rate = fps * hop
    if abs(rate - round(rate)) > 1e-9 * rate:
        raise InputError(f"no integer sample rate gives {fps} fps with a whole-sample hop")
    return int(round(rate)), hop


def choreograph_mel(
    y: np.ndarray,
    sr: float,
    fps: float = CHOREOGRAPH_FPS,
    n_mels: int = CHOREOGRAPH_N_MELS,
    n_fft: int = 2048,
    db: bool = True,
) -> np.ndarray:
    """ChoreoGraph music input: (A, n_mels) float32 mel spectrogram, one row per motion frame.

    Power mel spectrogram (``librosa.feature.melspectrogram``, Hann, centred, n_fft samples) with
    hop = sr / fps (see :func:`hop_for_fps` when that is not whole: the signal is resampled
    first); with ``db`` it is ``librosa.power_to_db`` (ref 1, 80 dB floor below the peak).
    A = 1 + n // hop for n = round(samples · rate / sr) samples at the rate actually used.
    """
    import librosa

    signal = _mono(y)
    rate, hop = hop_for_fps(sr, fps)
    signal = _resample(signal, sr, rate)
    mel = librosa.feature.melspectrogram(
        y=signal, sr=rate, n_fft=n_fft, hop_length=hop, n_mels=n_mels
    )
    if db:
        mel = librosa.power_to_db(mel)
    return np.ascontiguousarray(mel.T, dtype=np.float32)


def frames_per_chunk(chunk_samples: int, hop_length: int = GENRE_STFT_HOP) -> int:
    """STFT frames of one centred chunk: k = 1 + chunk_samples // hop_length.

    At 16 kHz and 30 fps a chunk is 533 samples → k = 3 (1025 × 3 = 3075 values per frame).
    The dissertation's 1025 × 6 = 6150 needs 1000–1199 samples per chunk, e.g. 32 kHz at 30 fps
    (1067 samples) or 16 kHz at 15 fps; pass ``target_sr`` / ``fps`` accordingly.
    """
    return 1 + int(chunk_samples) // int(hop_length)


def stft_per_motion_frame(
    y: np.ndarray,
    sr: float,
    fps: float = 30.0,
    target_sr: int = GENRE_STFT_SR,
    hop_length: int = GENRE_STFT_HOP,
    n_fft: int = GENRE_STFT_N_FFT,
    n_frames: int | None = None,
) -> np.ndarray:
    """Genre-dissertation music input: (F, 1 + n_fft // 2, k) float32 STFT magnitudes.

    The signal is resampled to ``target_sr`` Hz and cut into F chunks of
    L = round(target_sr / fps) samples, chunk i starting at round(i · target_sr / fps) (so chunks
    never drift from the motion clock), zero-padded past the end. Each chunk gets its own centred
    Hann STFT (``librosa.stft``, hop ``hop_length``, ``n_fft``, zero padding), k =
    :func:`frames_per_chunk` (L). F defaults to ceil(duration · fps), the motion frames the audio
    covers. Reshape to (F, (1 + n_fft // 2) · k) for the flat per-frame vector.
    """
    import librosa

    signal = _mono(y)
    if not fps > 0:
        raise InputError(f"fps must be positive, got {fps}")
    if n_frames is None:
        n_frames = math.ceil(signal.size * fps / sr - 1e-9)
    signal = _resample(signal, sr, target_sr)
    per_frame = target_sr / fps
    if n_frames < 1:
        raise InputError(f"need at least one motion frame, got n_frames={n_frames}")
    chunk = int(round(per_frame))
    starts = np.round(np.arange(n_frames) * per_frame).astype(np.int64)
    padded = np.zeros(max(int(starts[-1]) + chunk, signal.size), dtype=np.float32)
    padded[: signal.size] = signal
    chunks = padded[starts[:, None] + np.arange(chunk)[None, :]]
    with warnings.catch_warnings():
        # A chunk is shorter than n_fft by design of the recipe; centring zero-pads it.
        warnings.filterwarnings("ignore", message="n_fft=.*is too large")
        spec = librosa.stft(chunks, n_fft=n_fft, hop_length=hop_length, pad_mode="constant")
    return np.abs(spec).astype(np.float32)


def tempogram(
    y: np.ndarray | None = None,
    sr: float = 30720,
    hop_length: int = 512,
    win_length: int = TEMPOGRAM_WIN_LENGTH,
    onset_envelope: np.ndarray | None = None,
) -> np.ndarray:
    """Autocorrelation tempogram at the feature frame rate, (A, win_length) float32.

    ``librosa.feature.tempogram`` of the onset envelope (computed from ``y`` with
    ``librosa.onset.onset_strength`` at ``hop_length`` unless ``onset_envelope`` is given), window
    ``win_length`` frames (384 → 6.4 s at 60 fps). Column j is lag j frames, i.e. tempo
    60 · sr / (hop_length · j) BPM (:func:`tempogram_bpms`).
    """
    import librosa

    if onset_envelope is None:
        if y is None:
            raise InputError("tempogram needs audio or an onset envelope")
        onset_envelope = librosa.onset.onset_strength(y=_mono(y), sr=sr, hop_length=hop_length)
    gram = librosa.feature.tempogram(
        onset_envelope=np.asarray(onset_envelope, dtype=np.float32),
        sr=sr,
        hop_length=hop_length,
        win_length=win_length,
    )
    return np.ascontiguousarray(gram.T, dtype=np.float32)


def tempogram_bpms(win_length: int, sr: float = 30720, hop_length: int = 512) -> np.ndarray:
    """Tempo in BPM of each tempogram column (lag j frames → 60·sr/(hop·j); column 0 is inf)."""
    lags = np.arange(win_length, dtype=np.float64)
    with np.errstate(divide="ignore"):
        return 60.0 * sr / (hop_length * lags)


def local_tempo(
    gram: np.ndarray,
    sr: float = 30720,
    hop_length: int = 512,
    min_bpm: float = 20.0,
    max_bpm: float = 320.0,
) -> np.ndarray:
    """Per-frame tempo (A,) in BPM: the strongest tempogram lag between ``min_bpm`` and
    ``max_bpm`` (no prior, so octave errors are possible on real music)."""
    bpms = tempogram_bpms(gram.shape[1], sr, hop_length)
    allowed = (bpms >= min_bpm) & (bpms <= max_bpm)
    if not np.any(allowed):
        raise InputError(f"no tempogram lag lies between {min_bpm} and {max_bpm} BPM")
    return bpms[allowed][np.argmax(gram[:, allowed], axis=1)].astype(np.float32)
