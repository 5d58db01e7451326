"""Loud, not empty (issue 14, item 4), and a failed first ingest leaves nothing (item 7): every
case that used to give an empty result or an empty new version now gives one clear error line
or a one-line warning with the reason. Real stores from the synthetic AIST++ generator (with
all, some or none of their music) and a hand-written BVH file without a tempo."""

from __future__ import annotations

import shutil

import pytest

import dancedata
from dancedata.errors import DancedataError, StoreError
from dancedata.featurize.featurize import FeaturizeOptions, featurize
from dancedata.featurize.segment import SegmentOptions, segment
from dancedata.ingest.aist import AistIngestOptions, ingest_aist
from dancedata.store.layout import StoreLayout
from dancedata.synth.aist import synth_aist
from tests.helpers import run_cli

torch = pytest.importorskip("torch")
from dancedata.read.torch_data import MeasureDataset, SecondsDataset  # noqa: E402

# slow: three featurized stores (all, partial, no music)
pytestmark = pytest.mark.slow


def _one_error_line(proc, *words: str) -> str:
    assert proc.returncode == 1, proc.stdout + proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    for word in words:
        assert word in lines[0], lines[0]
    return lines[0]


@pytest.fixture(scope="module")
def raw(tmp_path_factory):
    path = tmp_path_factory.mktemp("loud") / "raw"
    synth_aist(path, n_sequences=2, seed=0)
    return path


def _store(raw, root, music: str, audio: bool):
    """ingest (music: all, one missing, none) → featurize (no stems) → segment."""
    src = raw
    if music != "all":
        src = root / f"raw-{music}"
        shutil.copytree(raw, src)
        wavs = sorted((src / "wav").glob("*.wav"))
        for wav in wavs if music == "none" else wavs[:1]:
            wav.unlink()
    store = root / f"store-{music}"
    ingest_aist(store, src, AistIngestOptions(allow_missing_music=music != "all"))
    from dancedata.featurize.families.audio import AudioSettings

    featurize(store, FeaturizeOptions(audio=audio, audio_settings=AudioSettings(stems="none")))
    segment(store, SegmentOptions())
    return store


@pytest.fixture(scope="module")
def full(raw, tmp_path_factory):
    return _store(raw, tmp_path_factory.mktemp("loud"), "all", audio=True)


@pytest.fixture(scope="module")
def partial(raw, tmp_path_factory):
    return _store(raw, tmp_path_factory.mktemp("loud"), "one", audio=True)


@pytest.fixture(scope="module")
def silent(raw, tmp_path_factory):
    return _store(raw, tmp_path_factory.mktemp("loud"), "none", audio=False)


# -- splits ------------------------------------------------------------------------------------
def test_an_unknown_split_name_is_an_error(full):
    store = dancedata.open_store(full)
    assert store.seq_ids(split="train")  # the real one works
    for call in (
        lambda: store.seq_ids(split="trian"),
        lambda: store.measure_rows(split="trian"),
        lambda: list(store.iter_measures(split="trian")),
        lambda: MeasureDataset(full, split="trian"),
        lambda: SecondsDataset(full, split="trian"),
    ):
        with pytest.raises(StoreError, match=r"no split 'trian' in scheme 'crossmodal' \(splits: "):
            call()


def test_a_split_with_no_sequences_says_why(full, capfd):
    store = dancedata.open_store(full)
    # the synthetic split files list no test sequence: a known split, empty in this store
    reason = (
        "split 'test' of scheme 'crossmodal' has no sequences in version v3 (its split file "
        "lists 0, 0 of them on the ignore list, 0 in the store)"
    )
    capfd.readouterr()
    assert store.seq_ids(split="test") == []  # a listing: empty, with one warning line
    assert capfd.readouterr().err.strip() == f"warning: {full}: {reason}"
    for dataset in (MeasureDataset, SecondsDataset):  # a dataset: an error
        with pytest.raises(StoreError) as exc:
            dataset(full, split="test")
        assert str(exc.value) == f"{full}: {reason}"


def test_a_split_too_short_for_any_window_says_why(full):
    too_long = r"no 3600(\.0)? s windows in split 'train'.*long enough"
    with pytest.raises(DancedataError, match=too_long):
        SecondsDataset(full, split="train", seconds=3600.0, audio=None)
    with pytest.raises(DancedataError, match="no 1000-measure windows in split 'train'"):
        MeasureDataset(full, split="train", n_measures=1000, audio=None)


# -- music -------------------------------------------------------------------------------------
def test_audio_windows_of_a_store_without_music_name_the_cause(silent):
    store = dancedata.open_store(silent)
    seq = store.seq_ids()[0]
    assert store.view(seq, "fact_motion_225").shape[1] == 225  # motion reads fine
    hint = "this store has no music (sources: aistpp; 0 music tracks)"
    for call in (
        lambda: store.view(seq, "fact_audio_35"),
        lambda: MeasureDataset(silent, split="train"),
    ):
        with pytest.raises(StoreError, match=r"view 'fact_audio_35' needs audio/onset_env") as exc:
            call()
        assert hint in str(exc.value) and "run `dancedata featurize`" not in str(exc.value)
    assert len(MeasureDataset(silent, split="train", audio=None)) > 0
    with pytest.raises(StoreError, match=f"sequence {seq} has no audio: this store has no music"):
        store.audio(seq, "onset_env")


def test_a_sequence_without_music_in_a_store_with_music(partial, capfd):
    store = dancedata.open_store(partial)
    without = [s for s in store.seq_ids() if store.audio_frames(s) == 0]
    with_music = [s for s in store.seq_ids() if store.audio_frames(s) > 0]
    assert len(without) == 1 and len(with_music) == 1
    assert store.view(with_music[0], "fact_audio_35").shape[1] == 35
    with pytest.raises(StoreError, match=f"sequence {without[0]} has no audio: its music "):
        store.view(without[0], "fact_audio_35")
    capfd.readouterr()
    everything = MeasureDataset(partial, audio="fact_audio_35")
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("warning: ") and "1 of 2 sequences" in err[0]
    assert "have no music" in err[0] and "audio=None keeps them" in err[0]
    motion_only = MeasureDataset(partial, audio=None)
    assert 0 < len(everything) < len(motion_only)


# -- commands that used to write empty versions ------------------------------------------------
def test_featurize_that_computes_nothing_writes_nothing(silent, full):
    before = StoreLayout(silent).committed_versions()
    proc = run_cli("featurize", str(silent), "--no-motion", "-q", check=False)
    _one_error_line(proc, "featurize computes nothing, nothing written", "the store has no music")
    proc = run_cli("featurize", str(full), "--no-motion", "--no-audio", "-q", check=False)
    _one_error_line(proc, "motion is off (--no-motion); audio is off (--no-audio)")
    assert StoreLayout(silent).committed_versions() == before
    assert StoreLayout(full).committed_versions() == ["v1", "v2", "v3"]
    assert not list((silent / "versions").glob(".tmp-*"))


def test_featurize_warns_when_audio_was_asked_of_a_store_without_music(silent, tmp_path):
    work = tmp_path / "store"
    shutil.copytree(silent, work)
    proc = run_cli("featurize", str(work), "--stems", "none", "--representations", "quat", "-q")
    assert proc.stdout.strip() == "featurize: wrote version v4"
    assert proc.stderr.strip() == (
        f"warning: featurize: {work} has no music, so no audio features are computed"
    )


def _bvh(path, frames: int = 240) -> None:
    """A four-joint rig (cm) at 30 fps: no music, no tempo."""
    head = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Spine
  {
    OFFSET 0 50 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT Head
    {
      OFFSET 0 60 0
      CHANNELS 3 Zrotation Xrotation Yrotation
      End Site
      {
        OFFSET 0 20 0
      }
    }
  }
  JOINT LegL
  {
    OFFSET 10 -5 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 -90 0
    }
  }
}
MOTION
"""
    rows = [
        f"0 {90 + i * 0.01:.3f} 0 {i % 10} 0 0 {i % 5} 0 0 0 0 0 0 {i % 7} 0" for i in range(frames)
    ]
    path.write_text(head + f"Frames: {frames}\nFrame Time: 0.0333333\n" + "\n".join(rows) + "\n")


def test_segment_without_a_bpm_is_an_error_and_writes_nothing(tmp_path):
    _bvh(tmp_path / "walk.bvh")
    store = tmp_path / "store"
    run_cli("ingest", "bvh", str(tmp_path / "walk.bvh"), "--store", str(store), "-q")
    proc = run_cli("segment", str(store), "-q", check=False)
    _one_error_line(
        proc, "no measures, nothing written", "none of its 1 sequences has a BPM", "--bpm"
    )
    assert StoreLayout(store).committed_versions() == ["v1"]
    # with a tempo the same file segments: 240 frames at 30 fps, 120 BPM → 60-frame measures
    tempo = tmp_path / "tempo"
    run_cli("ingest", "bvh", str(tmp_path / "walk.bvh"), "--store", str(tempo), "--bpm", "120",
            "-q")  # fmt: skip
    assert "wrote version v2" in run_cli("segment", str(tempo), "-q").stdout
    assert dancedata.open_store(tempo).measures.num_rows == 4


def test_segment_warns_for_the_sequences_without_a_bpm(full, tmp_path):
    """One sequence whose BPM is unknown: the others are segmented, one warning line."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    work = tmp_path / "store"
    shutil.copytree(full, work)
    table = pq.read_table(work / "versions" / "v3" / "sequences.parquet")
    original = table.to_pylist()
    bpm = table.column("bpm").to_pylist()
    bpm[0] = None
    seq0 = table.column("seq_id")[0].as_py()
    index = table.schema.get_field_index("bpm")
    table = table.set_column(
        index, table.schema.field(index), pa.array(bpm, table.schema.field(index).type)
    )
    from dancedata.featurize.segment import check_measures, measure_rows

    rows = measure_rows(table.to_pylist(), SegmentOptions(beats_per_measure=2))
    assert rows and all(r["seq_id"] != seq0 for r in rows)
    import io
    from contextlib import redirect_stderr

    err = io.StringIO()
    with redirect_stderr(err):
        check_measures(table.to_pylist(), rows, str(work))
    assert err.getvalue().strip() == (
        f"warning: segment: 1 of 2 sequences have no BPM and get no measures (e.g. {seq0})"
    )
    with pytest.raises(StoreError, match="2 sequences have a BPM but none is as long as one"):
        check_measures(original, [], str(work))  # both have a BPM, neither a whole measure


# -- item 7: a failed first ingest leaves nothing ----------------------------------------------
def test_a_failed_first_ingest_leaves_nothing_behind(raw, tmp_path):
    bad = tmp_path / "raw-bad"
    shutil.copytree(raw, bad)
    motion = sorted((bad / "motions").glob("*.pkl"))[0]
    motion.write_bytes(b"garbage")
    store = tmp_path / "store"
    _one_error_line(run_cli("ingest", "aist", str(bad), "--store", str(store), "-q", check=False),
                    "unreadable pickle")  # fmt: skip
    assert not store.exists()
    # an empty folder the user made stays, empty
    made = tmp_path / "made"
    made.mkdir()
    run_cli("ingest", "aist", str(bad), "--store", str(made), "-q", check=False)
    assert made.is_dir() and not any(made.iterdir())
    # BVH: a broken file
    (tmp_path / "bad.bvh").write_text("HIERARCHY\nROOT x\n")
    bvh_store = tmp_path / "bvh-store"
    _one_error_line(run_cli("ingest", "bvh", str(tmp_path / "bad.bvh"), "--store",
                            str(bvh_store), "-q", check=False), "bad.bvh")  # fmt: skip
    assert not bvh_store.exists()
    # an existing store is never touched by a failed ingest
    good = tmp_path / "good"
    ingest_aist(good, raw, AistIngestOptions())
    listing = sorted(p.name for p in good.iterdir())
    run_cli("ingest", "aist", str(bad), "--store", str(good), "-q", check=False)
    assert sorted(p.name for p in good.iterdir()) == listing
    assert StoreLayout(good).committed_versions() == ["v1"]
    assert run_cli("validate", str(good)).returncode == 0


def test_errors_keep_their_file_through_pickle() -> None:
    """An error raised in a worker process reaches the client pickled: it keeps its file and
    problem (``--json`` reports ``file``), whatever the subclass."""
    import pickle

    from dancedata.errors import InputError, StoreError
    from dancedata.exec.executors import ClusterError

    for error in (
        InputError("bad header", "/data/a.bvh"),
        StoreError("locked", "s3://b/x"),
        ClusterError("no workers left"),
    ):
        back = pickle.loads(pickle.dumps(error))
        assert type(back) is type(error)
        assert (back.problem, back.path, str(back)) == (error.problem, error.path, str(error))
