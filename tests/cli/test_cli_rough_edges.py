"""Issue 14, item 7 (rough edges), through the real ``dancedata`` command (in subprocesses where
a signal or a terminal is involved): Ctrl-C, --json errors, progress in logs, --help,
store-version options and ``info`` labels."""

from __future__ import annotations

import fcntl
import json
import os
import pty
import re
import shlex
import signal
import struct
import subprocess
import sys
import termios
import time
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from dancedata.io.bvh import BvhClip, BvhSkeleton, write_bvh
from dancedata.store.layout import StoreLayout
from dancedata.synth.aist import synth_aist
from tests.helpers import run_cli

# slow: Ctrl-C and kills of CLI subprocesses mid-featurize
pytestmark = pytest.mark.slow

CLI = [sys.executable, "-m", "dancedata.cli"]


@pytest.fixture(scope="module")
def aist_store(tmp_path_factory) -> Path:
    """A 2-sequence synthetic AIST++ store with one version (ingest)."""
    root = tmp_path_factory.mktemp("rough")
    synth_aist(root / "raw", n_sequences=2, seed=0)
    run_cli("ingest", "aist", str(root / "raw"), "--store", str(root / "store"), "-q")
    return root / "store"


# ------------------------------------------------------------------------------------ Ctrl-C


def _default_sigint() -> None:
    # A child of a background shell job inherits SIGINT ignored; a user's Ctrl-C is not.
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_says_interrupted_cleans_up_and_a_rerun_resumes(aist_store, tmp_path):
    store = tmp_path / "store"
    subprocess.run(["cp", "-r", str(aist_store), str(store)], check=True)
    args = [*CLI, "featurize", str(store), "--stems", "none"]
    # An empty feature cache of its own: with the session's cache warm (other tests featurized
    # the same music) this featurize finished within the 0.5 s before the interrupt.
    env = {**os.environ, "DANCEDATA_CACHE": str(tmp_path / "empty-feature-cache")}
    proc = subprocess.Popen(
        args,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=_default_sigint,
        env=env,
    )
    lock = store / ".lock"
    deadline = time.monotonic() + 120
    # Interrupt mid-write: once the lock is held and the temporary version exists.
    while not (lock.exists() and list((store / "versions").glob(".tmp-*"))):
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.05)
    time.sleep(0.1)  # mid-write: the audio of two tracks takes about 1.5 s more
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, (out, err)
    assert err.strip().splitlines()[-1] == "interrupted; run again to resume"
    assert "Traceback" not in err and out == ""
    assert not lock.exists(), "the store lock was not released"
    layout = StoreLayout(store)
    assert layout.committed_versions() == ["v1"] and layout.latest() == "v1"
    # featurize builds are resumable: at most the one temporary version, named from the
    # fingerprint, is kept for the rerun, and readers never see it.
    assert len(list((store / "versions").glob(".tmp-*"))) <= 1
    run_cli("validate", str(store))
    rerun = json.loads(run_cli("featurize", str(store), "--stems", "none", "--json", "-q").stdout)
    assert rerun["version"] == "v2" and rerun["created"]
    assert not list((store / "versions").glob(".tmp-*"))


def test_ctrl_c_while_a_c_extension_imports_is_an_interrupt(tmp_path, monkeypatch, capsys):
    """Ctrl-C while a lazily imported C extension initialises reaches the command as
    ``ImportError: initialization failed`` raised from the KeyboardInterrupt (seen in a full
    run of the test above): still exit 130 and the one line, not a traceback and 1."""
    from dancedata.cli.main import exit_code

    import dancedata.featurize.featurize as featurize_module

    def interrupted_import(*args: object, **kwargs: object) -> None:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as exc:
            raise ImportError("initialization failed") from exc

    monkeypatch.setattr(featurize_module, "featurize", interrupted_import)
    monkeypatch.setattr(sys, "argv", ["dancedata", "featurize", str(tmp_path), "--json"])
    assert exit_code() == 130
    out, err = capsys.readouterr()
    assert json.loads(out) == {
        "error": "interrupted; run again to resume",
        "exit_code": 130,
        "kind": "interrupted",
        "file": None,
    }
    assert err.strip().splitlines()[-1] == "interrupted; run again to resume"
    assert "Traceback" not in err


# ------------------------------------------------------------------------------ --json errors


def test_json_errors_are_one_json_object_on_stdout(tmp_path):
    missing = tmp_path / "nowhere"
    proc = run_cli("info", str(missing), "--json", check=False)
    assert proc.returncode == 1
    record = json.loads(proc.stdout)
    assert record["exit_code"] == 1 and record["kind"] == "StoreError"
    assert record["file"] == str(missing) and "store" in record["error"]
    assert proc.stderr.startswith("error: ")  # the human line stays on stderr

    usage = run_cli("info", str(missing), "--json", "--no-such-option", check=False)
    assert usage.returncode == 2
    assert json.loads(usage.stdout) == {
        "error": "No such option: --no-such-option",
        "file": None,
        "exit_code": 2,
        "kind": "usage",
    }
    plain = run_cli("info", str(missing), check=False)
    assert plain.returncode == 1 and plain.stdout == ""
    assert plain.stderr.strip() == f"error: {missing}: not a dancedata store (no such directory)"


# ------------------------------------------------------------------------- progress in logs

PLAIN_LINE = re.compile(r"^[\w ]+: \d+(/\d+)? \w+ \((\d+%, )?\d+\.\d s\)$")


def test_progress_is_plain_lines_when_stderr_is_not_a_terminal(tmp_path):
    synth_aist(tmp_path / "raw", n_sequences=2, seed=1)
    proc = run_cli("ingest", "aist", str(tmp_path / "raw"), "--store", str(tmp_path / "s"))
    assert "\r" not in proc.stderr and "\x1b" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert lines and all(PLAIN_LINE.match(line) for line in lines), lines
    assert "ingest sequences: 2/2 seq (100%" in proc.stderr


def test_progress_is_a_bar_in_a_terminal(tmp_path):
    synth_aist(tmp_path / "raw", n_sequences=2, seed=1)
    main, child = pty.openpty()
    fcntl.ioctl(child, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # 100 columns
    proc = subprocess.Popen(
        [*CLI, "ingest", "aist", str(tmp_path / "raw"), "--store", str(tmp_path / "s")],
        stdout=subprocess.PIPE,
        stderr=child,
    )
    os.close(child)
    chunks = []
    while True:
        try:
            chunk = os.read(main, 4096)
        except OSError:  # the child closed the terminal
            break
        if not chunk:
            break
        chunks.append(chunk)
    proc.wait(timeout=120)
    os.close(main)
    shown = b"".join(chunks).decode(errors="replace")
    assert proc.returncode == 0 and "\r" in shown and "ingest sequences" in shown


# ------------------------------------------------------------------------------------ --help


def _command_paths() -> dict[str, set[str]]:
    """Every leaf command below ``dancedata`` with its option names."""
    from dancedata.cli.main import build_command

    def walk(cmd, path):
        subs = getattr(cmd, "commands", None)
        if subs:
            for name, sub in subs.items():
                yield from walk(sub, (path + " " + name).strip())
        else:
            yield path, {o for p in cmd.params for o in [*p.opts, *p.secondary_opts] if o[0] == "-"}

    return dict(walk(build_command(), ""))


def test_every_command_help_has_an_example_and_plain_flag_names(monkeypatch):
    """Each command's --help in this interpreter (click reads COLUMNS when it formats help)."""
    from dancedata.cli.examples import EXAMPLES

    commands = _command_paths()
    for expected in ("featurize", "ingest aist", "experiment run", "checkout", "info"):
        assert expected in commands
    monkeypatch.setenv("COLUMNS", "60")  # narrow: nothing may be cut
    for path, options in commands.items():
        text = run_cli(*path.split(), "--help").stdout
        assert "<bool>" not in text and "--no-no-" not in text and "╭" not in text, path
        for option in options:
            assert re.search(rf"(^|[\s,/]){re.escape(option)}($|[\s,=])", text, re.M), (
                f"{path}: {option} missing from --help"
            )
        example = re.search(r"^\s*Example:?\s*\n?\s*(dancedata .+)$", text, re.M)
        assert example, f"dancedata {path} --help shows no example"
        if path in EXAMPLES:  # the example uses only options the command has
            words = shlex.split(EXAMPLES[path])
            assert words[: 1 + len(path.split())] == ["dancedata", *path.split()]
            used = {w for w in words if w.startswith("--")}
            assert used <= options, f"{path}: example uses {used - options}"
    root = run_cli("--help").stdout
    assert "..." not in root.split("Commands:")[1]  # command summaries are whole sentences


def test_no_music_is_a_plain_flag():
    text = run_cli("ingest", "video", "--help").stdout
    assert re.search(r"^\s+--no-music\s", text, re.M) and "--no-no-music" not in text


# ------------------------------------------------------------------------ store versions


def test_store_version_accepts_3_and_v3_and_has_no_short_letter(aist_store):
    for spelling in ("1", "v1", "V1", " 1"):
        info = json.loads(run_cli("info", str(aist_store), "--version", spelling, "--json").stdout)
        assert info["version"] == "v1"
    bad = run_cli("info", str(aist_store), "--version", "vx", check=False)
    assert bad.returncode == 2 and "give it as v3 or 3" in bad.stderr
    short = run_cli("info", str(aist_store), "-V", "1", check=False)
    assert short.returncode == 2 and "No such option: -V" in short.stderr
    import dancedata

    assert run_cli("--version").stdout.strip() == f"dancedata {dancedata.__version__}"


# ------------------------------------------------------------------------------------ info


def _click_track(path: Path, bpm: float, seconds: float = 20.0, sr: int = 22050) -> Path:
    """Clicks (10 ms, 1 kHz) on every beat at ``bpm``: a tempo librosa finds."""
    y = np.zeros(int(seconds * sr), np.float32)
    click = np.sin(2 * np.pi * 1000 * np.arange(int(0.01 * sr)) / sr).astype(np.float32)
    for t in np.arange(0.0, seconds - 0.02, 60.0 / bpm):
        start = int(t * sr)
        y[start : start + click.size] += 0.8 * click
    sf.write(path, y, sr)
    return path


def _chain_bvh(path: Path, frames: int = 300, fps: float = 30.0) -> Path:
    skeleton = BvhSkeleton(
        ("hips", "spine", "head"),
        (-1, 0, 1),
        np.array([[0.0, 90.0, 0.0], [0.0, 40.0, 0.0], [0.0, 40.0, 0.0]]),
        (
            ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"),
            ("Zrotation", "Xrotation", "Yrotation"),
            ("Zrotation", "Xrotation", "Yrotation"),
        ),
        end_sites=(np.zeros((0, 3)), np.zeros((0, 3)), np.array([[0.0, 20.0, 0.0]])),
    )
    t = np.arange(frames) / fps
    swing = 20.0 * np.sin(2 * np.pi * t)[:, None] * np.ones((1, 3))
    values = np.concatenate([np.tile([0.0, 90.0, 0.0], (frames, 1)), swing, swing, swing], axis=1)
    write_bvh(BvhClip(skeleton, 1.0 / fps, values), path)
    return path


def test_info_labels_estimated_tempi_and_shows_no_none_genres(tmp_path, aist_store):
    bvh = _chain_bvh(tmp_path / "take.bvh")
    music = _click_track(tmp_path / "clicks.wav", bpm=120.0)
    store = tmp_path / "store"
    run_cli(
        "ingest",
        "bvh",
        str(bvh),
        "--store",
        str(store),
        "--units",
        "cm",
        "--music",
        str(music),
        "-q",
    )  # fmt: skip  (no --bpm, no --genre)
    text = run_cli("info", str(store)).stdout
    assert "None" not in text
    genres = next(line for line in text.splitlines() if line.startswith("genres"))
    assert "none recorded" in genres
    tempi = next(line for line in text.splitlines() if line.startswith("tempi"))
    assert "estimated from the audio (librosa beat_track)" in tempi and "given" not in tempi
    info = json.loads(run_cli("info", str(store), "--json").stdout)
    assert info["genres"] == {} and info["genre_missing"] == 1
    assert len(info["bpms_estimated"]) == 1 and info["bpms_given"] == []
    assert info["bpms_estimated"][0] == pytest.approx(120.0, rel=0.05)

    aist = run_cli("info", str(aist_store)).stdout
    tempi = next(line for line in aist.splitlines() if line.startswith("tempi"))
    assert "BPM given" in tempi and "estimated" not in tempi
