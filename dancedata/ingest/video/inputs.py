"""Which pose folder, joints CSV and music file belong to each video of ``ingest video``.

Each video becomes one sequence whose ``seq_id`` is the video's file stem (so stems must be
unique). Its inputs are found by these rules, in order:

OpenPose JSON (``--poses DIR``):
  1. ``DIR/<stem>/`` when that folder exists (one subfolder per video);
  2. the files ``DIR/<stem>_<frame>_keypoints.json`` (OpenPose's own naming when it is run on
     several videos into one folder);
  3. with a single video only: every ``*_keypoints.json`` in ``DIR`` whatever its prefix (the
     folder OpenPose wrote for that one video, e.g. ``video_000000000000_keypoints.json``).

3-d joints (``--joints-csv PATH``): ``PATH`` itself when it is a file (a single video only), or
``PATH/<stem>.csv`` when it is a folder.

Music (``--music PATH``): ``PATH`` itself when it is a file (shared by every video), or
``PATH/<stem>.{wav,flac,ogg,mp3}`` when it is a folder. Without ``--music`` the video's own
audio track is used when it has one (see :mod:`dancedata.ingest.video.music`).

No video (``ingest video --poses DIR --fps F`` with no VIDEO argument, for users who have only
the pose files; :func:`pose_only_inputs`): the sequences are found in the pose inputs instead.

* ``--poses DIR`` holding ``*_keypoints.json``: one sequence per file-name prefix (OpenPose
  names its files ``<video stem>_<frame>_keypoints.json``, so the prefix is the video's stem;
  files with no prefix take the folder's name). A folder without such files: one sequence per
  subfolder that has them, named after the subfolder.
* ``--joints-csv`` alone: the file (named by its stem), or every ``*.csv`` in the folder.
  With ``--poses`` too, each pose sequence takes its CSV by the rule above, as if it were a
  video of that name.
* Music only from ``--music`` (there is no audio track).

The pose files are then the clock: pose frame i (the number in the JSON file name, or the CSV
row / frame column) sits at ``i / F`` seconds, and the duration is the frame count over F
(:mod:`dancedata.ingest.video.poses`).

Planning (:func:`find_video_inputs`, :func:`sequence_key`): the inputs of every video and the
fingerprint line binding each sequence id to the checksums of its files; a folder of OpenPose
JSON counts as one input (:func:`pose_digest`).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

from dancedata.errors import InputError
from dancedata.ingest.source import InputChecksums, SkipPolicy
from dancedata.io.audio import MUSIC_EXTENSIONS, find_music
from dancedata.io.openpose import keypoint_file_prefix, list_keypoint_files
from dancedata.store.checksums import describe_input


@dataclass(frozen=True)
class VideoInputs:
    """The files one video's sequence is built from.

    Attributes:
        seq_id: the video's file stem (without a video: the pose sequence's name).
        video: the video file (its clock is the time base); without a video, the pose folder
            or CSV the sequence comes from (``has_video`` False).
        poses: folder of OpenPose JSON, or None when only 3-d joints are given.
        poses_prefix: file-name prefix to keep inside ``poses`` (rule 2), else None.
        joints_csv: 3-d joints CSV, or None.
        music: music file given with ``--music``, or None (then the video's audio track).
        has_video: False when there is no video: the pose files are the clock (``--fps``).
    """

    seq_id: str
    video: Path
    poses: Path | None
    poses_prefix: str | None
    joints_csv: Path | None
    music: Path | None
    has_video: bool = True

    def pose_files(self) -> list[Path]:
        """The OpenPose JSON files of this video, in frame order (empty without poses)."""
        if self.poses is None:
            return []
        return list(list_keypoint_files(self.poses, self.poses_prefix).values())


def _has_prefixed_files(folder: Path, stem: str) -> bool:
    return any(keypoint_file_prefix(p.name) == stem for p in folder.iterdir())


def find_pose_folder(poses: Path, video: Path, single: bool) -> tuple[Path, str | None]:
    """(folder, prefix) of ``video``'s OpenPose output under ``poses`` (module docstring)."""
    if not poses.is_dir():
        raise InputError("--poses is not a folder", poses)
    stem = video.stem
    if (poses / stem).is_dir():
        return poses / stem, None
    if _has_prefixed_files(poses, stem):
        return poses, stem
    if single and any(p.name.endswith("_keypoints.json") for p in poses.iterdir()):
        return poses, None
    where = f"{poses / stem}/ or {poses / stem}_<frame>_keypoints.json"
    if single:
        where += f", or *_keypoints.json files in {poses}"
    raise InputError(f"no OpenPose output for this video (looked for {where})", video)


def find_joints_csv(path: Path, video: Path, single: bool) -> Path:
    """``video``'s 3-d joints CSV under ``--joints-csv`` (module docstring)."""
    if path.is_file():
        if not single:
            raise InputError(
                "--joints-csv is one file but several videos are given; point it at a folder "
                "holding <video stem>.csv for each",
                path,
            )
        return path
    if path.is_dir():
        candidate = path / f"{video.stem}.csv"
        if candidate.is_file():
            return candidate
        raise InputError(f"no 3-d joints CSV for this video (looked for {candidate})", video)
    raise InputError("--joints-csv: no such file or folder", path)


def find_music_for(path: Path, video: Path) -> Path:
    """``video``'s music under ``--music``: the file itself, or ``<stem>.<ext>`` in a folder."""
    if path.is_file():
        return path
    if path.is_dir():
        found = find_music(path, video.stem)
        if found is None:
            exts = "/".join(MUSIC_EXTENSIONS)
            raise InputError(
                f"no music for this video (looked for {path / video.stem}{{{exts}}})", video
            )
        return found
    raise InputError("--music: no such file or folder", path)


def resolve_inputs(
    video: Path, poses: Path | None, joints_csv: Path | None, music: Path | None, single: bool
) -> VideoInputs:
    """All inputs of one video; raises :class:`InputError` naming what is missing."""
    if not video.is_file():
        raise InputError("video file not found", video)
    folder, prefix = (None, None) if poses is None else find_pose_folder(poses, video, single)
    if folder is not None:
        list_keypoint_files(folder, prefix)  # fails early on an empty or mixed folder
    return VideoInputs(
        seq_id=video.stem,
        video=video,
        poses=folder,
        poses_prefix=prefix,
        joints_csv=None if joints_csv is None else find_joints_csv(joints_csv, video, single),
        music=None if music is None else find_music_for(music, video),
    )


def check_unique_stems(videos: list[Path]) -> None:
    """Sequence ids are video stems: two videos with one stem are refused, naming both."""
    seen: dict[str, Path] = {}
    for video in videos:
        if video.stem in seen:
            raise InputError(
                f"same file stem as {seen[video.stem]}; sequence ids are video stems, so rename "
                "one of them",
                video,
            )
        seen[video.stem] = video


def _prefix_sequences(folder: Path) -> dict[str, str | None]:
    """seq_id → file prefix of every OpenPose sequence directly in ``folder``."""
    found: dict[str, str | None] = {}
    for path in sorted(folder.iterdir()):
        prefix = keypoint_file_prefix(path.name) if path.is_file() else None
        if prefix is None and not (path.is_file() and path.name.endswith("_keypoints.json")):
            continue
        found.setdefault(prefix or folder.name, prefix or "")
    return found


def _pose_sequences(poses: Path) -> list[tuple[str, Path, str | None]]:
    """(seq_id, folder, prefix) of each OpenPose sequence under ``poses`` (module docstring)."""
    if not poses.is_dir():
        raise InputError("--poses is not a folder", poses)
    direct = _prefix_sequences(poses)
    if direct:
        single = len(direct) == 1
        return [(seq, poses, None if single else prefix) for seq, prefix in direct.items()]
    found = []
    for sub in sorted(p for p in poses.iterdir() if p.is_dir()):
        if _prefix_sequences(sub):
            found.append((sub.name, sub, None))
    if not found:
        raise InputError(
            "no *_keypoints.json files in the folder or its subfolders (no video given, so the "
            "sequences come from the pose files)",
            poses,
        )
    return found


def pose_only_inputs(
    poses: Path | None, joints_csv: Path | None, music: Path | None
) -> list[VideoInputs]:
    """The sequences of pose files given without any video (module docstring: the rules)."""
    if poses is not None:
        found = _pose_sequences(poses)
        sources = [(seq, folder, prefix, folder) for seq, folder, prefix in found]
    elif joints_csv is not None and joints_csv.is_dir():
        csvs = sorted(p for p in joints_csv.iterdir() if p.suffix.lower() == ".csv")
        if not csvs:
            raise InputError("no *.csv files in the folder", joints_csv)
        sources = [(p.stem, None, None, p) for p in csvs]
    elif joints_csv is not None:
        if not joints_csv.is_file():
            raise InputError("--joints-csv: no such file or folder", joints_csv)
        sources = [(joints_csv.stem, None, None, joints_csv)]
    else:
        raise InputError("give the poses: --poses DIR (OpenPose JSON) and/or --joints-csv")
    single = len(sources) == 1
    inputs = []
    for seq_id, folder, prefix, source in sources:
        if folder is not None:
            list_keypoint_files(folder, prefix)  # fails early on an empty or mixed folder
        named = Path(seq_id)  # stands for a video of this name in the CSV and music rules
        csv = source if folder is None else None
        if folder is not None and joints_csv is not None:
            csv = find_joints_csv(joints_csv, named, single)
        inputs.append(
            VideoInputs(
                seq_id=seq_id,
                video=source,
                poses=folder,
                poses_prefix=prefix,
                joints_csv=csv,
                music=None if music is None else find_music_for(music, named),
                has_video=False,
            )
        )
    return inputs


# ----------------------------------------------------------------------------- planning


def find_video_inputs(
    videos: list[Path],
    poses: Path | None,
    joints_csv: Path | None,
    music: Path | None,
    skips: SkipPolicy,
) -> list[VideoInputs]:
    """The inputs of every video (none given: of every pose sequence); a video whose inputs
    are missing goes through ``skips``. InputError when none is left."""
    if not videos:  # pose files only (--fps): the sequences come from them
        return pose_only_inputs(poses, joints_csv, music)
    found: list[VideoInputs] = []
    for video in videos:
        try:
            found.append(resolve_inputs(video, poses, joints_csv, music, len(videos) == 1))
        except InputError as exc:
            skips.fail_or_skip(exc, video)
    if not found:
        raise InputError("every video was skipped; nothing to ingest")
    return found


def pose_digest(checksums: InputChecksums, inputs: VideoInputs) -> str:
    """One manifest input for a video's pose files: the folder (and file prefix), their total
    bytes, file count, and the sha256 over ``<file name>:<sha256>`` lines."""
    key = str(inputs.poses) + (
        "" if inputs.poses_prefix is None else f"/{inputs.poses_prefix}_*_keypoints.json"
    )
    if key not in checksums.described:
        digest, total, files = hashlib.sha256(), 0, inputs.pose_files()
        for path in files:
            entry = describe_input(path)
            digest.update(f"{path.name}:{entry['sha256']}\n".encode())
            total += entry["bytes"]
        checksums.described[key] = {
            "path": key,
            "bytes": total,
            "sha256": digest.hexdigest(),
            "files": len(files),
        }
    return checksums.described[key]["sha256"]


def sequence_key(checksums: InputChecksums, inputs: VideoInputs) -> str:
    """Fingerprint line binding a sequence id to its inputs' checksums."""
    parts = [
        inputs.seq_id,
        f"video={checksums.sha(inputs.video) if inputs.has_video else None}",
        f"poses={pose_digest(checksums, inputs) if inputs.poses else None}",
        f"csv={checksums.sha(inputs.joints_csv) if inputs.joints_csv else None}",
        f"music={checksums.sha(inputs.music) if inputs.music else None}",
    ]
    return "|".join(parts)


def sequence_sha256(checksums: InputChecksums, inputs: VideoInputs) -> str:
    """The checksum the sequences table records: the video's, else the pose folder's digest,
    else the joints CSV's."""
    if inputs.has_video:
        return checksums.sha(inputs.video)
    if inputs.poses:
        return pose_digest(checksums, inputs)
    return checksums.sha(inputs.joints_csv)  # type: ignore[arg-type]
