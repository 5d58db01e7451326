"""The bad-input corpus (tests/data/bad/make_corpus.py): every case is refused with one line that
names the file and the problem, or under ``--on-error skip`` is recorded in the manifest with its
reason while the other inputs are ingested; nothing already in the store is lost, and nothing a
malicious pickle names is ever executed."""

from __future__ import annotations

import json
import pickle
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from dancedata.errors import InputError
from dancedata.ingest.aist import AistIngestOptions, ingest_aist
from dancedata.io.aist import read_motion
from dancedata.io.audio import load_mono
from dancedata.io.bvh import read_bvh
from dancedata.io.openpose import read_openpose_folder
from dancedata.store.layout import StoreLayout
from dancedata.store.validate import validate_store
from dancedata.synth.aist import synth_aist
from tests.data.bad.make_corpus import BVH_GOOD, Case, make_corpus, summary
from tests.helpers import run_cli

READERS = {
    "pickle": read_motion,
    "bvh": read_bvh,
    "audio": lambda path: load_mono(path, 30720),
    "openpose": read_openpose_folder,
}


@pytest.fixture(scope="module")
def corpus(tmp_path_factory) -> tuple[Path, list[Case]]:
    root = tmp_path_factory.mktemp("bad") / "corpus"
    return root, make_corpus(root)


def _one_line_naming(message: str, path: Path) -> str:
    """The problem part of an error that must be one line starting with ``path`` (a folder's
    error may name the file inside it). Returns the text after ``<file>: ``."""
    assert "\n" not in message, message
    assert message.startswith(str(path)), f"{message!r} does not name {path}"
    return message[len(str(path)) :].split(": ", 1)[1]


def _snapshot(store: Path) -> dict[str, bytes]:
    return {str(p.relative_to(store)): p.read_bytes() for p in store.rglob("*") if p.is_file()}


def _no_payload_ran(root: Path) -> None:
    assert not list(root.glob("pwned-*")), "a malicious pickle was executed"


# -- the corpus itself -------------------------------------------------------------------------
@pytest.mark.slow
def test_corpus_covers_every_kind_of_bad_input(corpus):
    root, cases = corpus
    counts = summary(cases)
    assert counts["pickle/reader"] >= 25 and counts["pickle/ingest"] == counts["pickle/reader"]
    assert counts["bvh/reader"] >= 25
    assert counts["audio/reader"] >= 4 and counts["audio/ingest"] >= 3
    assert counts["openpose/reader"] >= 8
    assert counts["split/ingest"] >= 1
    listed = json.loads((root / "cases.json").read_text())
    assert len(listed) == len(cases)
    names = {c.name for c in cases if c.kind == "pickle"}
    assert {"truncated", "missing_poses", "poses_69", "poses_strings", "nan_poses"} <= names
    assert {"zero_frames", "evil_os_system", "evil_protocol0_inst", "evil_memory_bomb"} <= names
    assert {  # issue 11: memory safety of the unpickler, values checked as stored
        "evil_dtype_object_flags",
        "evil_ndarray_uninitialised",
        "evil_ndarray_huge",
        "evil_huge_shape_few_bytes",
        "evil_zero_stride_view",
        "evil_deep_nesting",
        "evil_long_binput",
        "scaling_1e-40",
        "poses_1e300_float64",
        "scaling_string",
    } <= names
    huge = (root / "pickle" / "evil_ndarray_huge.pkl").stat().st_size
    assert huge < 400  # a few hundred bytes that used to allocate 2.3 GB
    bvh = {c.name for c in cases if c.kind == "bvh"}
    assert {"channel_count_short", "truncated_motion", "glued_numbers", "missing_motion"} <= bvh
    assert {"unbalanced_open_brace", "unknown_channel", "joint_without_brace"} <= bvh


# -- each reader refuses each case with one clear line -----------------------------------------
@pytest.mark.parametrize("kind", sorted(READERS))
def test_every_case_is_refused_with_one_line_naming_the_file_and_problem(corpus, kind):
    root, cases = corpus
    failures = []
    for case in (c for c in cases if c.kind == kind and c.via == "reader"):
        path = root / case.path
        try:
            READERS[kind](path)
        except InputError as exc:
            try:
                problem = _one_line_naming(str(exc), path)
            except AssertionError as bad:
                failures.append(f"{case.name}: {bad}")
                continue
            if not re.search(case.expect, problem):
                failures.append(f"{case.name}: {problem!r} does not match {case.expect!r}")
        except Exception as exc:  # anything but InputError is a crash
            failures.append(f"{case.name}: crashed with {type(exc).__name__}: {exc}")
        else:
            failures.append(f"{case.name}: accepted")
    assert failures == []
    _no_payload_ran(root)


def test_malicious_payloads_are_real_but_never_run(corpus, tmp_path):
    root, cases = corpus
    evil = [c for c in cases if c.kind == "pickle" and c.name.startswith("evil_")]
    assert len(evil) >= 7
    for case in evil:
        with pytest.raises(InputError, match="unsafe pickle"):
            read_motion(root / case.path)
    _no_payload_ran(root)
    # The payloads are live: a plain pickle.load of one of them does create its file.
    data = (root / "pickle" / "evil_builtins_open.pkl").read_bytes()
    pickle.loads(data).close()
    assert (root / "pwned-open").exists()
    (root / "pwned-open").unlink()


# -- through `dancedata ingest aist` -----------------------------------------------------------
@pytest.fixture
def store_v1(tmp_path) -> Path:
    """A store whose v1 (a clean ingest) no failed or partial ingest may touch."""
    raw = tmp_path / "clean"
    synth_aist(raw, n_sequences=2, seed=99)
    store = tmp_path / "store"
    ingest_aist(store, raw, AistIngestOptions())
    return store


def _ingest_cases(cases: list[Case], folder: str) -> list[Case]:
    return [c for c in cases if c.via == "ingest" and c.path.startswith(folder + "/")]


@pytest.mark.slow
def test_ingest_stops_at_the_first_bad_motion_with_one_line_and_keeps_the_store(corpus, store_v1):
    root, cases = corpus
    before = _snapshot(store_v1)
    proc = run_cli(
        "ingest", "aist", str(root / "aist_motions"), "--store", str(store_v1), "-q", check=False
    )
    assert proc.returncode == 1
    line = proc.stderr.strip()
    assert "\n" not in line and line.startswith("error: "), proc.stderr
    bad = {str(root / c.path): c for c in _ingest_cases(cases, "aist_motions") if c.kind != "split"}
    named = next((p for p in bad if line.startswith(f"error: {p}: ")), None)
    assert named is not None, line
    assert re.search(bad[named].expect, line), (line, bad[named].expect)
    assert _snapshot(store_v1) == before
    assert StoreLayout(store_v1).temp_dirs() == []
    _no_payload_ran(root)


@pytest.mark.slow
@pytest.mark.parametrize("workers", ["1", "2"])
def test_ingest_skip_records_every_bad_motion_and_ingests_the_rest(corpus, store_v1, workers):
    """Every hostile pickle (object-flag dtypes, deep nesting, ...) is one skipped line, also
    when the reads run in two worker processes: nothing crashes a worker or the run."""
    root, cases = corpus
    raw = root / "aist_motions"
    before = _snapshot(store_v1)
    proc = run_cli(
        "ingest",
        "aist",
        str(raw),
        "--store",
        str(store_v1),
        "-q",
        "--on-error",
        "skip",
        "--workers",
        workers,
        "--json",
    )
    result = json.loads(proc.stdout)
    assert result["version"] == "v2" and result["created"] is True
    layout = StoreLayout(store_v1)
    manifest = layout.read_manifest("v2")
    skipped = {item["path"]: item["error"] for item in manifest["skipped"]}
    expected = {
        str(root / c.path): c for c in _ingest_cases(cases, "aist_motions") if c.kind != "split"
    }
    assert set(skipped) == set(expected)
    for path, case in expected.items():
        assert "\n" not in skipped[path]
        assert re.search(case.expect, skipped[path]), (case.name, skipped[path])
    # The good sequences are in; the bad are not; v1 is untouched; the new version is valid.
    from dancedata.store.reader import _VersionReader

    seq_ids = set(_VersionReader(store_v1, "v2").table("sequences").column("seq_id").to_pylist())
    good = {p.stem for p in (raw / "motions").glob("*.pkl")} - {Path(p).stem for p in expected}
    assert seq_ids == good and len(good) == 3
    assert {k: v for k, v in _snapshot(store_v1).items() if k.startswith("versions/v1/")} == {
        k: v for k, v in before.items() if k.startswith("versions/v1/")
    }
    assert validate_store(store_v1, deep=True) == []
    _no_payload_ran(root)


def test_values_are_checked_as_stored_not_as_read(tmp_path):
    """A finite float64 that the float32 cast turns into Inf is refused naming the file, for
    motions (corpus: poses_1e300_float64, scaling_1e-40) and for keypoints alike."""
    from dancedata.ingest.aist.annotations import read_annotations

    n = 12
    rng = np.random.default_rng(1)
    kp3d = rng.normal(0, 50, (n, 17, 3))
    kp3d[4, 2, 1] = np.nan  # NaN is AIST++'s "missing": kept
    path3d = tmp_path / "kp3d.pkl"
    path3d.write_bytes(pickle.dumps({"keypoints3d": kp3d, "keypoints3d_optim": kp3d}))
    annotations = read_annotations(path3d, None, n, 60.0)
    assert np.isnan(annotations.keypoints3d.keypoints3d[4, 2, 1])
    kp3d[7, 0, 0] = 1e300
    path3d.write_bytes(pickle.dumps({"keypoints3d": kp3d, "keypoints3d_optim": kp3d}))
    with pytest.raises(InputError) as info:
        read_annotations(path3d, None, n, 60.0)
    assert str(info.value) == (
        f"{path3d}: keypoints3d as stored (float32 m) holds Inf (first at frame 7)"
    )
    kp3d[7, 0, 0] = 2e5  # 2 km once in metres: finite, implausible
    path3d.write_bytes(pickle.dumps({"keypoints3d": kp3d, "keypoints3d_optim": kp3d}))
    with pytest.raises(InputError, match=r"keypoints3d as stored .* outside the plausible range"):
        read_annotations(path3d, None, n, 60.0)
    kp2d = rng.uniform(0, 1000, (9, n, 17, 3))
    kp2d[3, 5, 0, 0] = 1e300
    path2d = tmp_path / "kp2d.pkl"
    path2d.write_bytes(pickle.dumps({"keypoints2d": kp2d, "det_scores": np.ones((9, n))}))
    with pytest.raises(
        InputError, match=r"keypoints2d as stored \(float32\) holds Inf \(first at frame 5\)"
    ):
        read_annotations(None, path2d, n, 60.0)


def test_split_files_naming_missing_sequences_are_reported_and_skipped(corpus, tmp_path):
    root, _ = corpus
    store = tmp_path / "store"
    result = ingest_aist(store, root / "aist_motions", AistIngestOptions(on_error="skip"))
    from dancedata.store.reader import _VersionReader

    reader = _VersionReader(store, result.version)
    present = set(reader.table("sequences").column("seq_id").to_pylist())
    split_ids = set(reader.table("splits").column("seq_id").to_pylist())
    assert split_ids <= present  # no row for a ghost name
    assert not any("d99" in s or "not_even" in s or "d98" in s for s in split_ids)
    schemes = reader.manifest["counts"]["splits"]["schemes"]["crossmodal"]
    assert schemes["train"]["missing_from_store"] >= 3 and schemes["val"]["missing_from_store"] >= 3
    assert validate_store(store) == []


@pytest.mark.slow
def test_undecodable_music_stops_ingest_with_one_line_naming_it(corpus, store_v1):
    root, cases = corpus
    before = _snapshot(store_v1)
    proc = run_cli(
        "ingest", "aist", str(root / "aist_music"), "--store", str(store_v1), "-q", check=False
    )
    assert proc.returncode == 1
    line = proc.stderr.strip()
    assert "\n" not in line, proc.stderr
    music = {str(root / c.path): c for c in _ingest_cases(cases, "aist_music")}
    named = next((p for p in music if line.startswith(f"error: {p}: ")), None)
    assert named is not None, line
    assert re.search(music[named].expect, line)
    assert _snapshot(store_v1) == before


def test_undecodable_music_is_skipped_with_its_sequences_under_skip(corpus, tmp_path):
    root, cases = corpus
    store = tmp_path / "store"
    result = ingest_aist(store, root / "aist_music", AistIngestOptions(on_error="skip"))
    skipped = " | ".join(f"{s['path']}: {s['error']}" for s in result.skipped)
    for case in _ingest_cases(cases, "aist_music"):
        assert case.note in skipped or str(root / case.path) in skipped, case.name
    assert result.counts["sequences"] == 2


@pytest.mark.slow
def test_music_with_a_wrong_extension_is_read_by_content_or_reported_missing(tmp_path):
    import soundfile as sf

    raw = tmp_path / "raw"
    synth_aist(raw, n_sequences=2, seed=5)
    wavs = sorted((raw / "wav").glob("*.wav"))
    assert len(wavs) == 2
    # FLAC bytes under a .wav name: decoded by content, same length as before.
    y, sr = sf.read(wavs[0])
    flac = tmp_path / "x.flac"
    sf.write(flac, y, sr, format="FLAC")
    shutil.copy(flac, wavs[0])
    ok = ingest_aist(tmp_path / "s1", raw, AistIngestOptions())
    from dancedata.store.reader import _VersionReader

    music = _VersionReader(tmp_path / "s1", ok.version).table("music").to_pylist()
    row = next(r for r in music if r["music_id"] == wavs[0].stem)
    assert row["n_samples"] == len(y) and row["sr"] == sr
    # A music file with an extension dancedata does not read: reported as not found, one line.
    wavs[1].rename(wavs[1].with_suffix(".aiff"))
    proc = run_cli("ingest", "aist", str(raw), "--store", str(tmp_path / "s2"), "-q", check=False)
    assert proc.returncode == 1
    line = proc.stderr.strip()
    assert "\n" not in line
    assert f"music {wavs[1].stem} not found (looked for {wavs[1].stem}.wav" in line


@pytest.mark.slow
def test_silent_music_is_accepted_with_finite_features_and_no_beats(tmp_path):
    """Silence is valid audio (a silent stem is normal, e.g. the drums of Ballet Jazz): it must
    not produce NaN features or phantom beats."""
    import soundfile as sf

    from dancedata.featurize.featurize import FeaturizeOptions, featurize

    raw = tmp_path / "raw"
    synth_aist(raw, n_sequences=1, seed=3)
    [wav] = (raw / "wav").glob("*.wav")
    info = sf.info(wav)
    sf.write(wav, np.zeros(info.frames, np.int16), info.samplerate, subtype="PCM_16")
    store = tmp_path / "store"
    ingest_aist(store, raw, AistIngestOptions())
    featurize(store, FeaturizeOptions(motion=False))
    from dancedata.store.reader import _VersionReader

    reader = _VersionReader(store)
    for name in reader.array_names():
        if name.startswith("audio/"):
            values = np.asarray(reader.array(name)[...])
            assert np.isfinite(values).all(), name
    assert int(np.asarray(reader.array("audio/beats")[...]).sum()) == 0
    assert int(np.asarray(reader.array("audio/onset_peaks")[...]).sum()) == 0
    assert validate_store(store) == []


@pytest.mark.slow
def test_non_utf8_split_file_is_named_in_one_line(tmp_path):
    raw = tmp_path / "raw"
    synth_aist(raw, n_sequences=2, seed=4)
    split = raw / "splits" / "crossmodal_val.txt"
    split.write_bytes(split.read_bytes() + "gBR_sBM_cAll_d01_mBR1_ch0\xe9\n".encode("latin-1"))
    proc = run_cli("ingest", "aist", str(raw), "--store", str(tmp_path / "s"), "-q", check=False)
    assert proc.returncode == 1
    assert proc.stderr.strip() == f"error: {split}: split file is not UTF-8 text"


# -- through `dancedata ingest bvh` ------------------------------------------------------------
@pytest.mark.slow
def test_ingest_bvh_skips_each_bad_file_with_its_line_and_keeps_the_good(corpus, tmp_path):
    pytest.importorskip("dancedata.ingest.bvh")
    root, cases = corpus
    good = [tmp_path / "good_a.bvh", tmp_path / "good_b.bvh"]
    for path in good:
        path.write_text(BVH_GOOD)
    bad = [c for c in cases if c.kind == "bvh"]
    paths = [str(p) for p in good] + [str(root / c.path) for c in bad]
    store = tmp_path / "store"
    failing = run_cli(
        "ingest", "bvh", *paths, "--store", str(store), "--no-size-check", "-q", check=False
    )
    assert failing.returncode == 1
    line = failing.stderr.strip()
    assert "\n" not in line and line.startswith(f"error: {root / bad[0].path}: "), line
    proc = run_cli(
        "ingest",
        "bvh",
        *paths,
        "--store",
        str(store),
        "--no-size-check",
        "-q",
        "--on-error",
        "skip",
        "--json",
    )
    result = json.loads(proc.stdout)
    skipped = {item["path"]: item["error"] for item in result["skipped"]}
    assert set(skipped) == {str(root / c.path) for c in bad}
    for case in bad:
        assert re.search(case.expect, skipped[str(root / case.path)]), case.name
    assert result["counts"]["sequences"] == 2
    assert validate_store(store) == []
