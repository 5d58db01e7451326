"""One video read for ``ingest video``: its poses on the store's time base and its own audio
track, from one picklable item, with no store access.

:func:`read_video` is what a worker runs per video (a top-level function, so process pools
pickle it): :func:`~dancedata.ingest.video.poses.process_video` (clock, poses, frame check,
track, fill, resample), then, when the video's own audio track is its music, that track
described (:func:`~dancedata.ingest.video.music.music_from_video`; tempo estimated unless
given). What it returns holds arrays, JSON scalars and dancedata dataclasses only, so a
resumable ingest saves it between runs without pickle. Bad input raises
:class:`~dancedata.errors.InputError` naming the file; ``--on-error`` is applied by the caller.

A ``--music`` file is not read here: many videos may share one, so it is described once per
run (:func:`~dancedata.ingest.video.music.music_from_file`) by the caller.
"""

from __future__ import annotations

from dataclasses import dataclass

from dancedata.ingest.video.inputs import VideoInputs
from dancedata.ingest.video.music import MusicTrack, music_from_video
from dancedata.ingest.video.poses import PoseSettings, VideoPoses, process_video


@dataclass(frozen=True)
class VideoReadItem:
    """Everything one video's read needs (picklable; its repr names the work exactly).

    Attributes:
        inputs: the video's files.
        settings: the per-video pipeline settings.
        skip_bad_files: a malformed pose file is a missing frame (``--on-error skip``).
        audio_track: the video's own audio track is its music (no ``--music``, no
            ``--no-music``).
        video_sha256: checksum of the video (the music row's ``sha256`` for its audio track).
        bpm: ``--bpm``; None: estimate the audio track's tempo.
    """

    inputs: VideoInputs
    settings: PoseSettings
    skip_bad_files: bool = False
    audio_track: bool = False
    video_sha256: str | None = None
    bpm: float | None = None


@dataclass
class VideoRead:
    """One video read: its poses, and its audio track when that is its music (None: no track,
    or the music comes from ``--music`` or there is none)."""

    poses: VideoPoses
    audio: MusicTrack | None = None


def read_video(item: VideoReadItem) -> VideoRead:
    """Read one video's poses (and its audio track, see :class:`VideoReadItem`).

    Raises:
        InputError: naming the file, for unreadable or malformed input (see
            :func:`~dancedata.ingest.video.poses.process_video` and
            :func:`~dancedata.ingest.video.music.music_from_video`).
    """
    poses = process_video(item.inputs, item.settings, skip_bad_files=item.skip_bad_files)
    audio = None
    if item.audio_track:
        audio = music_from_video(item.inputs.video, item.video_sha256 or "", item.bpm)
    return VideoRead(poses, audio)
