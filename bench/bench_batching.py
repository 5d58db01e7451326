"""Batches for training: dancedata's batching against the plain per-item loop (issue 14.1).

On a featurized, segmented store (``--store``; default ``bench/out/batching-gBR-gPO``, built
here when absent: the full synthetic twin ``synth aist --full --seed 0`` (1408 sequences; the
demo subset stops at 40), of which ``ingest aist --genres gBR,gPO --annotations ''`` keeps two
genres' ~280 sequences, then ``featurize`` and ``segment``: a part of the twin, to keep the run
short on the shared machine), over the crossmodal train split's measure windows
(fact_motion_225 + fact_audio_35), it times batches of 64 windows per second:

* baseline — the plain per-item loop a training script writes when ``batch_size=8`` fails:
  ``DataLoader(MeasureDataset(...), batch_size=1, shuffle=True)`` in one process, 64 items
  padded into a batch by hand (``torch.nn.utils.rnn.pad_sequence``);
* dancedata — ``training_loader(ds, 64, bucket=True, num_workers=2)`` (length buckets, whole
  padded batches with mask and lengths read by ``dataset.batch``, persistent workers), the same
  with ``num_workers=0``, and with items + ``pad_collate`` instead of batch reads;
* fixed-length windows (``window_frames=128, fit="resample"``: SLERP on rotations), 2 and 0
  workers, and 4 s sliding windows with a 1 s hop (``SecondsDataset``), 2 workers;
* the transport floor: a DataLoader whose workers only return ready-made zero tensors of a
  bucketed batch's shape, i.e. the cost of handing a batch between processes.

Besides wall rates it reports the training process's own CPU per batch: what workers take off
the process that runs the model.

Each loader runs ``--epochs`` passes; the first includes opening the store in each worker
(reported separately), the rate is over the later passes. The machine is shared: wall rates
move with its load, which is printed.

Usage: .venv/bin/python bench/bench_batching.py [--store PATH] [--epochs 3]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

HERE = Path(__file__).resolve().parent
DEFAULT_STORE = HERE / "out" / "batching-gBR-gPO"
GENRES = ["gBR", "gPO"]
BATCH = 64


def build_store(path: Path) -> None:
    """Full twin → two genres → featurize → segment into ``path`` (skipped when it exists)."""
    if (path / "store.json").exists():
        return
    from dancedata.featurize.featurize import FeaturizeOptions, featurize
    from dancedata.featurize.segment import SegmentOptions, segment
    from dancedata.ingest.aist import AistIngestOptions, ingest_aist
    from dancedata.synth.aist import synth_aist

    raw = path.with_name("batching-twin-raw")
    print(f"building {path} from the twin's {', '.join(GENRES)} (several minutes)", flush=True)
    if not raw.exists():  # synth writes a temporary folder and renames it when complete
        synth_aist(raw, full=True, seed=0, overwrite=True)
    ingest_aist(path, raw, AistIngestOptions(genres=GENRES, annotations=[]))
    featurize(path, FeaturizeOptions())
    segment(path, SegmentOptions())


def run_epochs(make_batches, epochs: int) -> tuple[float, float, float, int]:
    """(first pass seconds, later passes' batches / s, this process's CPU ms per batch over
    the later passes, windows per pass)."""
    times, cpu, windows = [], [], 0
    for _ in range(epochs):
        start, cpu0 = time.perf_counter(), time.process_time()
        windows = sum(n for n in make_batches())
        times.append(time.perf_counter() - start)
        cpu.append(time.process_time() - cpu0)
    later, later_cpu = (sum(times[1:]), sum(cpu[1:])) if epochs > 1 else (times[0], cpu[0])
    batches = max(1, epochs - 1) * windows / BATCH
    return times[0], batches / later, 1000 * later_cpu / batches, windows


def baseline(store: Path, epochs: int):
    import torch
    from torch.nn.utils.rnn import pad_sequence
    from torch.utils.data import DataLoader

    from dancedata.read.torch_data import MeasureDataset

    ds = MeasureDataset(store, split="train")
    loader = DataLoader(ds, batch_size=1, shuffle=True, collate_fn=lambda items: items[0])
    torch.manual_seed(0)

    def batches():
        pending = []
        for item in loader:
            pending.append(item)
            if len(pending) == BATCH:
                motion = pad_sequence([p["motion"] for p in pending], batch_first=True)
                audio = pad_sequence([p["audio"] for p in pending], batch_first=True)
                assert audio.shape[:2] == motion.shape[:2]
                yield motion.shape[0]
                pending = []
        if pending:
            yield len(pending)

    return run_epochs(batches, epochs), len(ds)


def dancedata_loader(ds, epochs: int, workers: int, bucket: bool = True, collate=None):
    from dancedata.read.torch_batching import training_loader

    loader = training_loader(
        ds, BATCH, seed=0, bucket=bucket, num_workers=workers, collate_fn=collate
    )

    def batches():
        for batch in loader:
            yield int(batch["motion"].shape[0])

    return run_epochs(batches, epochs)


class _Indices:
    """A dataset of bare indices, for the transport floor."""

    def __init__(self, n: int) -> None:
        self.n = n

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, i: int) -> int:
        return i


class _ZeroBatch:
    """A collate returning ready-made zero tensors of one batch's shape (no reading at all)."""

    def __init__(self, frames: int, widths: tuple[int, int]) -> None:
        self.frames, self.widths = frames, widths

    def __call__(self, items: list[int]) -> dict:
        import torch

        return {
            "motion": torch.zeros(len(items), self.frames, self.widths[0]),
            "audio": torch.zeros(len(items), self.frames, self.widths[1]),
        }


def transport_floor(n: int, frames: int, epochs: int, workers: int):
    """Batches / s when workers only hand over zero tensors of the batch's shape: the cost of
    moving a batch between processes (shared memory), which no dataset code can go below."""
    from torch.utils.data import DataLoader

    loader = DataLoader(
        _Indices(n),
        batch_size=BATCH,
        collate_fn=_ZeroBatch(frames, (225, 35)),
        num_workers=workers,
        persistent_workers=workers > 0,
    )

    def batches():
        for batch in loader:
            yield int(batch["motion"].shape[0])

    return run_epochs(batches, epochs)


class Repeated:
    """A window dataset read ``k`` times per pass (index ``i`` is window ``i % n``): more
    batches per pass from a small store, so a pass is not dominated by starting it."""

    def __init__(self, dataset, k: int) -> None:
        import numpy as np

        self.dataset, self.k = dataset, k
        self.lengths = np.tile(dataset.lengths, k)

    def __len__(self) -> int:
        return len(self.dataset) * self.k

    def batch(self, indices, multiple_of: int = 1, **extra):
        """``extra``: what the sampler passes on (the ``epoch`` of augmenting datasets)."""
        n = len(self.dataset)
        return self.dataset.batch([i % n for i in indices], multiple_of, **extra)

    def batch_parcel(self, indices, multiple_of: int = 1, **extra):
        n = len(self.dataset)
        return self.dataset.batch_parcel([i % n for i in indices], multiple_of, **extra)


class RepeatedPerTensor(Repeated):
    """:class:`Repeated` without ``batch_parcel``: workers hand over each tensor of a batch
    separately (one shared-memory handle each), as before batch parcels."""

    batch_parcel = None


def workers_only(store: Path, epochs: int, repeat: int) -> int:
    """Issue 24 item 4: ``training_loader`` with 2 workers against 0, batch reads and
    SLERP-resampled windows, with this process's CPU per batch and the load average."""
    from dancedata.read.torch_data import MeasureDataset

    load0 = os.getloadavg()
    rows = []
    for name, options in (
        ("measures, batch reads", {}),
        ("window_frames=128 resample", {"window_frames": 128}),
    ):
        windows = MeasureDataset(store, split="train", **options).preload()
        for workers, wrap in ((0, Repeated), (2, Repeated), (2, RepeatedPerTensor)):
            first, rate, cpu_ms, n = dancedata_loader(wrap(windows, repeat), epochs, workers)
            label = f"{workers}" + (" (per tensor)" if wrap is RepeatedPerTensor else "")
            rows.append((name, label, rate, cpu_ms, n))
    print(
        f"load average at start {load0[0]:.1f} / {load0[1]:.1f} / {load0[2]:.1f} "
        f"on {os.cpu_count()} CPUs; end {os.getloadavg()[0]:.1f}"
    )
    print(
        f"| windows | workers | windows / pass | batches of {BATCH} / s | × 0 workers "
        "| training-process CPU ms / batch |"
    )
    print("|---|---:|---:|---:|---:|---:|")
    for name, workers, rate, cpu_ms, n in rows:
        base = next(r[2] for r in rows if r[0] == name and r[1] == "0")
        print(f"| {name} | {workers} | {n} | {rate:.1f} | ×{rate / base:.2f} | {cpu_ms:.1f} |")
    return 0


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--store", type=Path, default=None)
    parser.add_argument("--epochs", type=int, default=3)
    parser.add_argument(
        "--workers-only", action="store_true", help="only training_loader, 2 workers against 0"
    )
    parser.add_argument("--repeat", type=int, default=1, help="read each window k times a pass")
    args = parser.parse_args(argv)
    store = args.store or DEFAULT_STORE
    if args.store is None:
        build_store(store)
    if args.workers_only:
        import torch

        torch.set_num_threads(1)
        return workers_only(store, args.epochs, args.repeat)

    import numpy as np
    import torch

    from dancedata.read.batching import bucket_batches, epoch_permutation
    from dancedata.read.torch_data import MeasureDataset, SecondsDataset

    torch.set_num_threads(1)
    print(f"store {store}; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    rows = []
    result, n_windows = baseline(store, args.epochs)
    rows.append(("baseline: per-item DataLoader(batch_size=1) + pad_sequence", *result))
    ds = MeasureDataset(store, split="train")
    lengths = ds.lengths
    print(
        f"{n_windows} train measure windows, {len(set(ds.source.spans.seq_ids))} sequences, "
        f"{lengths.min()}–{lengths.max()} frames (mean {lengths.mean():.1f})"
    )
    for workers in (2, 0):
        result = dancedata_loader(ds, args.epochs, workers)
        rows.append((f"dancedata: bucketed, batch reads, {workers} workers", *result))
    from dancedata.read.torch_batching import pad_collate

    result = dancedata_loader(ds, args.epochs, 2, collate=pad_collate)
    rows.append(("dancedata: bucketed, items + pad_collate (no batch reads), 2 workers", *result))
    result = dancedata_loader(ds, args.epochs, 2, bucket=False)
    rows.append(("dancedata: seeded shuffle, 2 workers", *result))
    fixed = MeasureDataset(store, split="train", window_frames=128, fit="resample")
    for workers in (2, 0):
        result = dancedata_loader(fixed, args.epochs, workers, bucket=False)
        rows.append((f"dancedata: window_frames=128 resample (SLERP), {workers} workers", *result))
    sliding = SecondsDataset(store, split="train", seconds=4.0, hop_seconds=1.0)
    result = dancedata_loader(sliding, args.epochs, 2, bucket=False)
    rows.append(("dancedata: 4 s windows, 1 s hop, 2 workers", *result))

    frames = int(np.mean([lengths[b].max() for b in bucket_batches(lengths, BATCH)]))
    for workers in (2, 0):
        result = transport_floor(len(ds), frames, args.epochs, workers)
        rows.append(
            (f"floor: ready-made zero batches (B, {frames}, 225 + 35), {workers} workers", *result)
        )

    base = rows[0][2]
    print(
        f"\n| loader | windows / pass | first pass s | batches of {BATCH} / s | × baseline "
        "| main-process CPU ms / batch |"
    )
    print("|---|---:|---:|---:|---:|---:|")
    for name, first, rate, cpu_ms, n in rows:
        print(f"| {name} | {n} | {first:.2f} | {rate:.1f} | ×{rate / base:.2f} | {cpu_ms:.1f} |")

    def overhead(batches) -> float:
        padded = sum(int(lengths[b].max()) * len(b) for b in batches)
        return 100 * (padded / int(lengths.sum()) - 1)

    shuffled = np.array_split(epoch_permutation(len(lengths), 0), -(-len(lengths) // BATCH))
    print(
        f"\npadded frames beyond the real ones: {overhead(bucket_batches(lengths, BATCH)):.1f} % "
        f"with length buckets, {overhead(shuffled):.1f} % with a plain shuffle"
    )
    print(f"load average at the end {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
