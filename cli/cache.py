"""``dancedata cache list`` and ``dancedata cache clear``: the per-track audio feature cache;
``dancedata cache warm``: the compiled numba kernels, once per machine."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from dancedata.cli.audio_options import CacheDir
from dancedata.cli.common import Json, Quiet
from dancedata.cli.main import app

if TYPE_CHECKING:
    from dancedata.featurize.feature_cache import FeatureCache

cache_app = typer.Typer(
    help="The caches every store shares: per-track audio features by content (list, clear) and "
    "the compiled numba kernels (warm).",
    no_args_is_help=True,
)
app.add_typer(cache_app, name="cache")


def _open(cache_dir: Path | None) -> FeatureCache:
    from dancedata.featurize.feature_cache import FeatureCache, default_cache_dir

    return FeatureCache(cache_dir or default_cache_dir())


def _age(seconds: float) -> str:
    if seconds < 3600:
        return f"{seconds / 60:.0f} min"
    if seconds < 86400:
        return f"{seconds / 3600:.1f} h"
    return f"{seconds / 86400:.1f} d"


@cache_app.command("list")
def list_entries(
    cache_dir: CacheDir = None,
    as_json: Json = False,
) -> None:
    """Every cache entry (one per track and audio family): key, family, music, size, last use;
    then the totals per family and overall."""
    from dancedata.featurize.feature_cache import format_bytes

    cache = _open(cache_dir)
    entries = cache.entries()
    totals: dict[str, dict[str, int]] = {}
    for entry in entries:
        total = totals.setdefault(entry.family, {"entries": 0, "bytes": 0})
        total["entries"] += 1
        total["bytes"] += entry.bytes
    summary = {
        "cache_dir": str(cache.root),
        "entries": len(entries),
        "bytes": sum(e.bytes for e in entries),
        "families": totals,
    }
    if as_json:
        rows = [
            {
                "key": e.key,
                "family": e.family,
                "music": e.source,
                "audio_sha256": e.meta.get("audio_sha256"),
                "bytes": e.bytes,
                "last_used": e.last_used,
                "path": str(e.path),
            }
            for e in entries
        ]
        typer.echo(json.dumps({**summary, "items": rows}, indent=2))
        return
    now = time.time()
    typer.echo(f"feature cache {cache.root}")
    for e in entries:
        typer.echo(
            f"  {e.key[:16]}  {e.family:<12} {e.source:<24} {format_bytes(e.bytes):>9}  "
            f"used {_age(now - e.last_used)} ago"
        )
    for family, total in sorted(totals.items()):
        typer.echo(f"  {family}: {total['entries']} entries, {format_bytes(total['bytes'])}")
    typer.echo(f"total: {len(entries)} entries, {format_bytes(summary['bytes'])}")


@cache_app.command("clear")
def clear(
    older_than: Annotated[
        float | None,
        typer.Option(
            min=0,
            help="Remove only entries not used for more than this many days (default: all).",
        ),
    ] = None,
    cache_dir: CacheDir = None,
    as_json: Json = False,
) -> None:
    """Remove cache entries (all, or those unused for --older-than DAYS) and temporary files
    left by writers that died. Stores are never touched; the next featurize recomputes."""
    from dancedata.featurize.feature_cache import format_bytes

    cache = _open(cache_dir)
    result = cache.clear(older_than)
    if as_json:
        typer.echo(
            json.dumps(
                {
                    "cache_dir": str(cache.root),
                    "removed": result.entries,
                    "bytes": result.bytes,
                    "temp_files": result.temp_files,
                },
                indent=2,
            )
        )
        return
    typer.echo(
        f"removed {result.entries} entries ({format_bytes(result.bytes)}) from {cache.root}"
        + (f" and {result.temp_files} stale temporary files" if result.temp_files else "")
    )


@cache_app.command("warm")
def warm(quiet: Quiet = False, as_json: Json = False) -> None:
    """Compile the numba kernels featurize runs into this machine's cache
    (``~/.cache/dancedata/numba``, or ``$NUMBA_CACHE_DIR``) by running a one-sequence synthetic
    sample through synth, ingest and featurize in a temporary folder: on a new machine about
    25 CPU s, once, instead of in the first featurize and in each of its workers; about 4 s
    when the cache is warm already."""
    from dancedata.progress import set_quiet
    from dancedata.synth.warmup import warm_kernels

    set_quiet(quiet or as_json)
    report = warm_kernels()
    if as_json:
        typer.echo(json.dumps(report, indent=2))
        return
    typer.echo(
        f"numba cache {report['numba_cache_dir']}: {report['compiled_files_after']} compiled "
        f"files ({report['compiled_files_before']} before), {report['seconds']:.1f} s"
    )
