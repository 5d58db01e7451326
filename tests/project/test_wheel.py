"""What ``pip install .`` builds works: the wheel holds every module of the source tree, and a
clean virtual environment with only the wheel installed (the dependencies visible, but not the
source tree or its editable finder) runs synth → ingest → featurize --stems offline → open_store.

Editable installs hide a missing package: the editable finder serves any module from the source
folder. This test installs the built wheel into a fresh venv whose only link to the test
environment is a ``.pth`` line naming its site-packages, so third-party packages import but the
editable finder's own ``.pth`` there is never executed.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.slow


def _source_modules() -> set[str]:
    """Installed path of every .py of the source tree (cli/ and schemas/ under dancedata/)."""
    found: set[str] = set()
    for folder, prefix in (
        ("dancedata", "dancedata"),
        ("cli", "dancedata/cli"),
        ("schemas", "dancedata/schemas"),
    ):
        for path in (REPO / folder).rglob("*.py"):
            if "__pycache__" not in path.parts:
                found.add(f"{prefix}/{path.relative_to(REPO / folder).as_posix()}")
    return found


def _clean_copy(dest: Path) -> Path:
    """The files git tracks (plus new ones not ignored), copied to ``dest``: what a fresh clone
    holds, without the work tree's build/ and *.egg-info, whose stale file lists would let
    setuptools add a forgotten package as data and hide the bug."""
    listed = subprocess.run(
        ["git", "ls-files", "--cached", "--others", "--exclude-standard", "-z"],
        cwd=REPO,
        check=True,
        capture_output=True,
        text=True,
    ).stdout.split("\0")
    for name in filter(None, listed):
        source = REPO / name
        if source.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, dest / name)
    return dest


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    source = _clean_copy(tmp_path_factory.mktemp("source"))
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--no-deps",
            "--no-build-isolation",
            "--quiet",
            str(source),
            "-w",
            str(out),
        ],
        check=True,
        capture_output=True,
        text=True,
        timeout=600,
    )
    (built,) = out.glob("dancedata-*.whl")
    return built


def test_wheel_holds_every_module_and_data_file(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    missing = sorted(_source_modules() - names)
    assert not missing, f"modules missing from the wheel: {missing}"
    assert "dancedata/schemas/store.schema.json" in names
    assert "dancedata/study/seed_tables.json" in names


def test_clean_venv_with_the_wheel_runs_the_chain(wheel, tmp_path):
    venv = tmp_path / "venv"
    subprocess.run(
        [sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True, timeout=120
    )
    py = venv / "bin" / "python"
    site = Path(
        subprocess.run(
            [py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
            check=True,
            capture_output=True,
            text=True,
        ).stdout.strip()
    )
    # Third-party packages of the test environment, as a plain path: not a site dir, so the
    # editable install's .pth (which would serve dancedata from the source tree) never runs.
    (site / "test-env-deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "--python",
            str(py),
            "install",
            "--no-deps",
            "--quiet",
            str(wheel),
        ],
        check=True,
        capture_output=True,
        text=True,
        timeout=600,
    )
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    work = tmp_path / "work"
    work.mkdir()

    def run(*argv: str) -> str:
        proc = subprocess.run(argv, cwd=work, env=env, capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, f"{argv} exited {proc.returncode}:\n{proc.stderr[-3000:]}"
        return proc.stdout

    where = run(
        str(py),
        "-c",
        "import dancedata, dancedata.read.views, dancedata.compute.stems;"
        " print(dancedata.__file__)",
    )
    assert Path(where.strip()).is_relative_to(venv), where
    cli = str(venv / "bin" / "dancedata")
    run(cli, "synth", "aist", "raw", "--sequences", "2", "--seed", "0", "--quiet")
    run(cli, "ingest", "aist", "raw", "--store", "store", "--quiet")
    run(cli, "featurize", "store", "--stems", "offline", "--quiet")
    out = run(
        str(py),
        "-c",
        "import dancedata; s = dancedata.open_store('store'); "
        "ids = s.seq_ids(); print(len(ids), s.motion(ids[0], 'rotmat').shape[1:])",
    )
    assert out.split()[0] == "2", out
