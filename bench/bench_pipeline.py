"""The whole pipeline on the full synthetic AIST++ twin, against what published scripts do.

1. The twin: ``dancedata synth aist bench/out/aist-full --full`` (1408 sequences, 60 songs),
   cached and rebuilt only when dancedata's synth code changes.
2. dancedata: ``ingest aist`` (``--workers 2``: the pool reads pickles while the command
   writes chunks), ``featurize`` (default feature set: rotations; fact, stems, nmfd audio)
   serially and with ``--workers 2``, ``segment``; and the baseline's work only
   (``ingest --annotations ''``, ``featurize --no-motion --audio-families fact``, ``segment``).
   Wall time, CPU time (the command and its worker processes) and peak RSS (summed over the
   process tree, sampled every 50 ms, and of the largest process). Every featurize starts from
   an empty per-track feature cache, so audio is computed, never loaded.
3. Baseline (bench/baseline_fact.py): per sequence, load the pickle, load and resample the
   music with librosa, compute the FACT 35-d features, np.save one file. It runs on a
   deterministic sample (every k-th sequence by name) and is extrapolated to all sequences:
   first sequence (imports, numba compile) + mean of the others × (N − 1).
4. Loader: random measure windows (fact_motion_225 + fact_audio_35) per second from the local
   store, in this one process.

Usage: .venv/bin/python bench/bench_pipeline.py [--sample 40] [--workers 2] [--json OUT.json]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import resource
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
OUT = HERE / "out"
TWIN = OUT / "aist-full"
STAMP = OUT / "aist-full.stamp"
DANCEDATA = [sys.executable, "-m", "dancedata.cli"]


# -- measuring a command -----------------------------------------------------------------------
def _tree_rss(pid: int) -> tuple[int, int]:
    """(sum, max) RSS in bytes of process ``pid`` and its descendants."""
    import psutil

    try:
        root = psutil.Process(pid)
        procs = [root, *root.children(recursive=True)]
    except psutil.Error:
        return 0, 0
    sizes = []
    for proc in procs:
        try:
            sizes.append(proc.memory_info().rss)
        except psutil.Error:
            continue
    return sum(sizes), max(sizes, default=0)


def measure(args: list[str], label: str, env: dict[str, str] | None = None) -> dict[str, Any]:
    """Run a command; wall s, CPU s of its whole process tree, peak RSS (sum and largest)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.Popen(
        args,
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env={**os.environ, **(env or {})},
    )
    peak = {"sum": 0, "max": 0}
    stop = threading.Event()

    def sample() -> None:
        while not stop.is_set():
            total, largest = _tree_rss(proc.pid)
            peak["sum"] = max(peak["sum"], total)
            peak["max"] = max(peak["max"], largest)
            stop.wait(0.05)

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    stdout, stderr = proc.communicate()
    stop.set()
    sampler.join()
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode:
        raise SystemExit(f"{label} failed ({proc.returncode}):\n{stderr.decode()[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    result = {
        "label": label,
        "wall_s": round(wall, 2),
        "cpu_s": round(cpu, 2),
        "peak_rss_mb": round(peak["sum"] / 2**20),
        "peak_rss_largest_mb": round(peak["max"] / 2**20),
        "stdout": stdout.decode(),
    }
    print(
        f"  {label:<28} wall {wall:7.1f} s   cpu {cpu:7.1f} s   "
        f"peak RSS {result['peak_rss_mb']:5d} MB (largest process "
        f"{result['peak_rss_largest_mb']} MB)",
        flush=True,
    )
    return result


# -- the twin ----------------------------------------------------------------------------------
def synth_stamp() -> str:
    """Changes whenever the synthetic data would: dancedata's version and its synth code."""
    from dancedata import __version__

    digest = hashlib.sha256(__version__.encode())
    for path in sorted((REPO / "dancedata" / "synth").glob("*.py")):
        digest.update(path.read_bytes())
    return digest.hexdigest()


def ensure_twin() -> None:
    stamp = synth_stamp()
    if TWIN.is_dir() and STAMP.is_file() and STAMP.read_text().strip() == stamp:
        print(f"twin: cached at {TWIN.relative_to(REPO)}")
        return
    print("twin: building (dancedata synth aist --full) ...", flush=True)
    measure(
        [*DANCEDATA, "synth", "aist", str(TWIN), "--full", "--force", "-q"], "synth aist --full"
    )
    STAMP.write_text(stamp + "\n")


# -- dancedata ---------------------------------------------------------------------------------
def cold_cache(name: str) -> dict[str, str]:
    """A fresh, empty per-track feature cache: every featurize run here computes its audio."""
    folder = OUT / "feature-cache" / name
    shutil.rmtree(folder, ignore_errors=True)
    return {"DANCEDATA_CACHE": str(folder)}


def ingest(
    store: Path, *extra: str, workers: int = 1, label: str = "ingest aist"
) -> dict[str, Any]:
    shutil.rmtree(store, ignore_errors=True)
    step = measure(
        [*DANCEDATA, "ingest", "aist", str(TWIN), "--store", str(store), "-q", "--json"]
        + ["--workers", str(workers), *extra],
        label if workers == 1 else f"{label} --workers {workers}",
    )
    step["counts"] = json.loads(step.pop("stdout"))["counts"]
    return step


def featurize(store: Path, workers: int, *extra: str, label: str = "") -> dict[str, Any]:
    step = measure(
        [*DANCEDATA, "featurize", str(store), "-q", "--json", "--workers", str(workers), *extra],
        label or f"featurize --workers {workers}",
        env=cold_cache(f"{store.name}-{workers}-{len(extra)}"),
    )
    step["counts"] = json.loads(step.pop("stdout"))["counts"]
    return step


def segment(store: Path, *extra: str) -> dict[str, Any]:
    step = measure([*DANCEDATA, "segment", str(store), "-q", "--json", *extra], "segment")
    step.pop("stdout")
    return step


def totals(steps: dict[str, Any]) -> dict[str, float]:
    return {
        "wall_s": round(sum(s["wall_s"] for s in steps.values()), 2),
        "cpu_s": round(sum(s["cpu_s"] for s in steps.values()), 2),
        "peak_rss_mb": max(s["peak_rss_mb"] for s in steps.values()),
    }


# -- baseline ----------------------------------------------------------------------------------
def baseline(sample: int) -> dict[str, Any]:
    names = sorted(p.stem for p in (TWIN / "motions").glob("*.pkl"))
    step = max(1, len(names) // sample)
    chosen = names[::step][:sample]
    out = OUT / "baseline-npy"
    shutil.rmtree(out, ignore_errors=True)
    run = measure(
        [sys.executable, str(HERE / "baseline_fact.py"), str(TWIN), str(out), *chosen],
        f"baseline, {len(chosen)} sequences",
    )
    records = [json.loads(line) for line in run.pop("stdout").splitlines() if line.strip()]
    first, rest = records[0], records[1:]
    n = len(names)
    wall = first["seconds"] + float(np.mean([r["seconds"] for r in rest])) * (n - 1)
    cpu = first["cpu_seconds"] + float(np.mean([r["cpu_seconds"] for r in rest])) * (n - 1)
    shutil.rmtree(out, ignore_errors=True)
    return {
        "sample": len(chosen),
        "sequences": n,
        "every_kth": step,
        "measured": run,
        "per_sequence_s": round(float(np.mean([r["seconds"] for r in rest])), 3),
        "first_sequence_s": round(first["seconds"], 2),
        "extrapolated_wall_s": round(wall, 1),
        "extrapolated_cpu_s": round(cpu, 1),
    }


# -- first-call cost and loader ----------------------------------------------------------------
def first_call_cost() -> dict[str, float]:
    """librosa import + numba compile paid once per process: first vs second FACT call."""
    code = (
        "import time, numpy as np\n"
        "from dancedata.compute.audio_features import AudioFeatureConfig, fact_features\n"
        "cfg = AudioFeatureConfig(); y = np.random.default_rng(0).standard_normal(2 * cfg.sr)"
        ".astype(np.float32) * 0.1\n"
        "a = time.perf_counter(); fact_features(y, 120.0, cfg); b = time.perf_counter()\n"
        "fact_features(y, 120.0, cfg); c = time.perf_counter()\n"
        "print(b - a, c - b)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    first, second = map(float, out.stdout.split())
    return {"first_call_s": round(first, 2), "second_call_s": round(second, 3)}


def loader(store: Path, version: str, n: int = 20000) -> dict[str, float]:
    import dancedata

    opened = time.perf_counter()
    windows = dancedata.open_store(store, version).measure_windows()
    ready = time.perf_counter()
    rng_windows = 0
    start = time.perf_counter()
    for motion, audio in windows.sample(n, seed=0):
        rng_windows += motion.shape[0] > 0 and audio.shape[0] > 0
    seconds = time.perf_counter() - start
    return {
        "windows": len(windows),
        "open_s": round(ready - opened, 2),
        "windows_per_s": round(n / seconds),
        "sampled": n,
    }


def machine() -> dict[str, Any]:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "memory_gb": round(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30, 1),
        "python": platform.python_version(),
        "date": time.strftime("%Y-%m-%d %H:%M %Z"),
        "load_average_at_start": [round(x, 2) for x in os.getloadavg()],
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sample", type=int, default=40, help="baseline sequences to run")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--json", type=Path, default=OUT / "bench_pipeline.json")
    args = parser.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    info = machine()
    print(
        f"machine: {info['cpu']}, {info['cores']} cores, {info['memory_gb']} GB; "
        f"load average at start {info['load_average_at_start']}"
    )
    ensure_twin()
    w = args.workers
    print(f"dancedata, default feature set (fact + stems + nmfd), --workers {w}:")
    parallel_store = OUT / "store-parallel"
    parallel = {"ingest": ingest(parallel_store, workers=w)}
    parallel["featurize"] = featurize(parallel_store, w)
    parallel["segment"] = segment(parallel_store)
    print(f"dancedata, the baseline's work only (motion + FACT 35-d audio), --workers {w}:")
    lean_store = OUT / "store-lean"
    fact = {
        "ingest": ingest(
            lean_store, "--annotations", "", workers=w, label="ingest aist --annotations ''"
        ),
        "featurize": featurize(
            lean_store,
            w,
            "--no-motion",
            "--audio-families",
            "fact",
            label=f"featurize fact --workers {w}",
        ),
    }
    fact["segment"] = segment(lean_store)
    print("dancedata, default feature set, serial:")
    serial_store = OUT / "store-serial"
    serial = {"ingest": ingest(serial_store), "featurize": featurize(serial_store, 1)}
    print("baseline (published-script style):")
    base = baseline(args.sample)
    print("per-process first-call cost (librosa import + numba compile):")
    compile_cost = first_call_cost()
    print(
        f"  first FACT call {compile_cost['first_call_s']} s, "
        f"then {compile_cost['second_call_s']} s"
    )
    print("loader:")
    load = loader(OUT / "store-parallel", "v3")  # default featurize, then segment
    print(
        f"  {load['windows_per_s']} random measure windows/s (motion 225-d + audio 35-d), "
        f"{load['windows']} windows, opened in {load['open_s']} s"
    )

    end_to_end = totals(parallel)
    fact_end_to_end = totals(fact)
    serial_end_to_end = totals({**serial, "segment": parallel["segment"]})
    ratio = base["extrapolated_wall_s"] / fact_end_to_end["wall_s"]
    cpu_ratio = base["extrapolated_cpu_s"] / fact_end_to_end["cpu_s"]
    ratio_default = base["extrapolated_wall_s"] / end_to_end["wall_s"]
    speedup = serial["featurize"]["wall_s"] / parallel["featurize"]["wall_s"]
    print("\nsummary:")
    print(
        f"  featurize (default set): serial {serial['featurize']['wall_s']} s, "
        f"--workers {w} {parallel['featurize']['wall_s']} s (x{speedup:.2f})"
    )
    print(
        f"  end to end, default set (ingest + featurize --workers {w} + segment): "
        f"{end_to_end['wall_s']} s wall, {end_to_end['cpu_s']} s CPU, "
        f"peak RSS {end_to_end['peak_rss_mb']} MB   [goal: < 180 s, < 2048 MB]"
    )
    print(
        f"  end to end, the baseline's work (ingest motion + FACT audio + segment): "
        f"{fact_end_to_end['wall_s']} s wall, "
        f"{fact_end_to_end['cpu_s']} s CPU, peak RSS {fact_end_to_end['peak_rss_mb']} MB"
    )
    print(f"  end to end, default set, serial featurize: {serial_end_to_end['wall_s']} s wall")
    print(
        f"  baseline: {base['per_sequence_s']} s per sequence measured on {base['sample']} "
        f"sequences (every {base['every_kth']}th), extrapolated to {base['sequences']}: "
        f"{base['extrapolated_wall_s']} s wall, {base['extrapolated_cpu_s']} s CPU"
    )
    print(
        f"  ratio baseline / dancedata, same work: x{ratio:.1f} wall, "
        f"x{cpu_ratio:.1f} CPU   [goal: >= 20]"
    )
    print(
        f"  ratio baseline / dancedata default set (which also computes stems and NMFD): "
        f"x{ratio_default:.1f} wall"
    )
    print(f"  loader: {load['windows_per_s']} windows/s   [goal: >= 10000]")
    report = {
        "machine": info,
        "workers": w,
        "default_parallel": parallel,
        "baseline_work_parallel": fact,
        "default_serial": serial,
        "end_to_end_default": end_to_end,
        "end_to_end_fact": fact_end_to_end,
        "end_to_end_default_serial": serial_end_to_end,
        "featurize_speedup": round(speedup, 2),
        "baseline": base,
        "ratio_wall": round(ratio, 2),
        "ratio_cpu": round(cpu_ratio, 2),
        "ratio_wall_default_set": round(ratio_default, 2),
        "first_call": compile_cost,
        "loader": load,
    }
    args.json.write_text(json.dumps(report, indent=2))
    shown = args.json.resolve()
    print(f"\nwrote {shown.relative_to(REPO) if shown.is_relative_to(REPO) else shown}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
