"""A store is opened once and its handle handed down (issue 22, item 3): a command resolves its
path to a backend once, a version already open is handed on rather than reopened, one reader
class is public, and the stem backend is an object chosen once by name."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from tests.helpers import run_cli

ROOT = Path(__file__).resolve().parents[2]


def _resolutions(call: Callable[[], Any]) -> tuple[Any, int]:
    """``call()``'s result and how many times it turned a path or URL (not a backend) into a
    backend: calls of the real ``make_backend`` seen by a profiler, nothing replaced."""
    from dancedata.store.backend import StoreBackend

    seen = 0

    def profile(frame: Any, event: str, arg: Any) -> None:
        nonlocal seen
        code = frame.f_code
        ours = code.co_name == "make_backend" and code.co_filename.endswith("backend_open.py")
        if event == "call" and ours:
            seen += not isinstance(frame.f_locals.get("store"), StoreBackend)

    sys.setprofile(profile)
    try:
        result = call()
    finally:
        sys.setprofile(None)
    return result, seen


@pytest.fixture(scope="module")
def ingested(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("handle")
    run_cli("synth", "aist", str(root / "raw"), "--sequences", "2", "--seed", "0", "-q")
    run_cli("ingest", "aist", str(root / "raw"), "--store", str(root / "store"), "-q")
    return root / "store"


def test_a_derived_version_resolves_its_store_once(ingested: Path, tmp_path: Path) -> None:
    import shutil

    from dancedata.featurize.segment import SegmentOptions, segment

    store = tmp_path / "store"
    shutil.copytree(ingested, store)
    # lock, parent, reader and writer share the one handle (before: 5 resolutions)
    result, seen = _resolutions(lambda: segment(str(store), SegmentOptions()))
    assert result.created and result.version == "v2"
    assert seen == 1
    # the "already done" path too
    again, seen = _resolutions(lambda: segment(str(store), SegmentOptions()))
    assert not again.created and again.version == "v2"
    assert seen == 1


def test_info_and_validate_resolve_once(ingested: Path) -> None:
    from dancedata.store.summary import summarize
    from dancedata.store.validate import validate_store

    info, seen = _resolutions(lambda: summarize(str(ingested)))
    assert info["version"] == "v1" and seen == 1
    problems, seen = _resolutions(lambda: validate_store(str(ingested)))
    assert problems == [] and seen == 1


def test_an_open_version_is_handed_on_not_reopened(ingested: Path) -> None:
    import dancedata
    from dancedata.errors import StoreError
    from dancedata.read.loader import DanceStore
    from dancedata.store.backend_open import make_backend
    from dancedata.store.reader import _VersionReader

    handle = make_backend(ingested)
    reader = _VersionReader(handle, "v1")
    store, seen = _resolutions(lambda: DanceStore(reader))
    assert seen == 0 and store.backend is handle and store.version == "v1"
    by_path = dancedata.open_store(str(ingested))
    assert store.seq_ids() == by_path.seq_ids()
    assert store.locator == handle.locator() and by_path.locator == str(ingested)
    with pytest.raises(StoreError, match="version v2 asked of an open v1"):
        DanceStore(reader, "v2")


def test_one_public_reader_class() -> None:
    import dancedata
    import dancedata.read.sequence_reader as sequence_reader
    import dancedata.store.reader as store_reader
    from dancedata.read.loader import DanceStore

    assert dancedata.open_store.__annotations__["return"] in ("DanceStore", DanceStore)
    assert not hasattr(sequence_reader, "SequenceReader")
    assert not hasattr(store_reader, "VersionReader")
    named = []
    for path in [
        ROOT / "README.md",
        *(ROOT / "docs").glob("*.md"),
        *(ROOT / "examples").rglob("*.py"),
    ]:
        text = path.read_text(encoding="utf-8")
        for old in ("SequenceReader", "VersionReader"):
            if old in text.replace(f"_{old}", ""):
                named.append(f"{path.relative_to(ROOT)}: {old}")
    assert not named, f"the private readers named to users: {named}"


def test_the_stem_backend_is_an_object_chosen_once() -> None:
    from dancedata.compute.stems import STEM_BACKENDS, backend_config, stem_backend
    from dancedata.errors import InputError
    from dancedata.featurize.family_settings import AudioSettings

    offline, umx = stem_backend("offline"), stem_backend("openunmix")
    assert stem_backend("offline") is offline and stem_backend(offline) is offline
    assert [b.name for b in (offline, umx)] == list(STEM_BACKENDS)
    assert (offline.needs_weights, offline.takes_stft, offline.load_options) == (False, True, ())
    assert umx.needs_weights and not umx.takes_stft
    assert set(umx.load_options) == {"model", "weights_dir", "device", "niter", "wiener_win_len"}
    assert "torch" in umx.libraries and offline.libraries == ()
    assert AudioSettings().stem_backend is offline
    assert AudioSettings(stems="openunmix").stem_backend is umx
    assert (
        backend_config("offline") == offline.config() == {"backend": "offline", **offline.defaults}
    )
    with pytest.raises(InputError, match="unknown stem backend 'none'; choose one of offline"):
        _ = AudioSettings(stems="none").stem_backend
    with pytest.raises(InputError, match=r"unknown option\(s\) for stem backend 'offline': bogus"):
        offline.config(bogus=1)


def test_an_ingest_resolves_its_store_once(ingested: Path, tmp_path: Path) -> None:
    """ingest aist --fps: the ingest (lock, engine, writer) and the resample after it share the
    handle made from the path; the only other resolution is the build area's, the plain-data
    locator the read workers reopen (in this process too: the serial executor runs them here).
    A repeat (nothing to do) resolves the path once."""
    from dancedata.ingest.aist import Options
    from dancedata.store.backend import StoreBackend

    raw = ingested.parent / "raw"
    store = tmp_path / "store"
    paths: list[str] = []

    def profile(frame: Any, event: str, arg: Any) -> None:
        code = frame.f_code
        ours = code.co_name == "make_backend" and code.co_filename.endswith("backend_open.py")
        if event == "call" and ours and not isinstance(frame.f_locals["store"], StoreBackend):
            paths.append(str(frame.f_locals["store"]))

    sys.setprofile(profile)
    try:
        result = Options(raw=raw, store=str(store), fps=20.0).run()
        first = list(paths)
        again = Options(raw=raw, store=str(store)).run()
    finally:
        sys.setprofile(None)
    assert result.created and result.version == "v2" and result.counts["ingest_version"] == "v1"
    assert first.count(str(store)) == 1  # before: 7 (measured at 9112cc3)
    assert all(Path(p).parent == store / "versions" for p in first if p != str(store))
    assert all(Path(p).name.startswith(".tmp-") for p in first if p != str(store))
    assert not again.created and again.version == "v1"
    assert paths[len(first) :] == [str(store)]
