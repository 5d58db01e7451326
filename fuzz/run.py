"""Fuzz dancedata's readers with hypothesis for a time budget and print statistics.

    python fuzz/run.py --minutes 10                 # what `make fuzz` runs
    python fuzz/run.py --seconds 60 --targets bvh_mutated,pickle --seed 3

Targets (fuzz/targets.py) share the budget equally in time: the next chunk always goes to the
target that has had the least time so far, so a slow target (generated BVH, a few examples a
second) cannot starve the fast ones. A target's first chunk has at most 20 examples; later
chunks are sized from its measured rate to take about a third of its share of the budget (at
most ``--chunk`` examples). Each chunk has its own seed drawn from ``--seed``. A failing chunk
is shrunk by hypothesis to a minimal example, which is written to
``fuzz/failures/<target>-<seed>.txt`` together with the seed that reproduces it; the run goes
on with the other chunks. The exit code is 1 if anything failed.
"""

from __future__ import annotations

import argparse
import io
import random
import sys
import time
import traceback
from contextlib import redirect_stdout
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from hypothesis import HealthCheck, Phase, given, seed, settings  # noqa: E402

from fuzz.targets import TARGETS, Target  # noqa: E402

FAILURES = ROOT / "fuzz" / "failures"


@dataclass
class Stats:
    """Per-target counters."""

    examples: int = 0
    chunks: int = 0
    failures: int = 0
    seconds: float = 0.0


def run_chunk(target: Target, n_examples: int, chunk_seed: int, stats: Stats) -> str | None:
    """Run ``n_examples`` examples of ``target``; the failure report, or None."""

    def body(example: object) -> None:
        stats.examples += 1
        target.check(example)

    test = seed(chunk_seed)(
        settings(
            max_examples=n_examples,
            deadline=None,
            database=None,
            phases=[Phase.generate, Phase.shrink],
            suppress_health_check=list(HealthCheck),
            print_blob=True,
        )(given(target.strategy)(body))
    )
    report = io.StringIO()
    try:
        with redirect_stdout(report):
            test()
    except BaseException as exc:  # any failure of the target is a finding
        if isinstance(exc, KeyboardInterrupt):
            raise
        return f"target {target.name}, seed {chunk_seed}\n{report.getvalue()}\n" + "".join(
            traceback.format_exception(exc)
        )
    return None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    budget = parser.add_mutually_exclusive_group()
    budget.add_argument("--minutes", type=float, help="time budget in minutes")
    budget.add_argument("--seconds", type=float, help="time budget in seconds")
    parser.add_argument("--targets", default=",".join(TARGETS), help="comma-separated targets")
    parser.add_argument("--chunk", type=int, default=200, help="examples per chunk")
    parser.add_argument("--seed", type=int, default=0, help="master seed")
    args = parser.parse_args(argv)
    seconds = args.seconds if args.seconds is not None else 60 * (args.minutes or 10)
    names = [n.strip() for n in args.targets.split(",") if n.strip()]
    unknown = sorted(set(names) - set(TARGETS))
    if unknown:
        parser.error(f"unknown targets {unknown}; known: {sorted(TARGETS)}")

    rng = random.Random(args.seed)
    stats = {name: Stats() for name in names}
    start = time.monotonic()
    deadline = start + seconds
    slice_seconds = max(1.0, seconds / (3 * len(names)))
    print(f"fuzzing {', '.join(names)} for {seconds:.0f} s (seed {args.seed})", flush=True)
    last_report = start
    while time.monotonic() < deadline:
        if time.monotonic() - last_report >= 30:
            last_report = time.monotonic()
            done = sum(s.examples for s in stats.values())
            print(f"  {last_report - start:6.0f} s: {done} examples", flush=True)
        name = min(names, key=lambda n: (stats[n].seconds, names.index(n)))  # least time
        s = stats[name]
        if s.chunks == 0 or s.seconds <= 0:
            n_examples = min(args.chunk, 20)
        else:
            rate = s.examples / s.seconds
            n_examples = max(1, min(args.chunk, int(rate * slice_seconds)))
        chunk_seed = rng.randrange(2**32)
        began = time.monotonic()
        failure = run_chunk(TARGETS[name], n_examples, chunk_seed, stats[name])
        stats[name].seconds += time.monotonic() - began
        stats[name].chunks += 1
        if failure is not None:
            stats[name].failures += 1
            FAILURES.mkdir(parents=True, exist_ok=True)
            out = FAILURES / f"{name}-{chunk_seed}.txt"
            out.write_text(failure, encoding="utf-8")
            print(f"FAILURE in {name} (seed {chunk_seed}): see {out}", flush=True)
    elapsed = time.monotonic() - start
    print(
        f"\n{'target':<16} {'examples':>9} {'chunks':>7} {'failures':>9} {'seconds':>8} {'ex/s':>7}"
    )
    for name, s in stats.items():
        rate = s.examples / s.seconds if s.seconds else 0.0
        print(
            f"{name:<16} {s.examples:>9} {s.chunks:>7} {s.failures:>9} {s.seconds:>8.1f} "
            f"{rate:>7.0f}"
        )
    total = sum(s.examples for s in stats.values())
    failed = sum(s.failures for s in stats.values())
    print(f"{'total':<16} {total:>9} {'':>7} {failed:>9} {elapsed:>8.1f}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
