"""``dancedata export bvh``: write a stored sequence back to BVH."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from dancedata.cli.apps import export_app
from dancedata.cli.common import Json, VersionOpt, open_handle, report


@export_app.command("bvh")
def export_bvh_cmd(
    store: Annotated[Path, typer.Argument(help="Store directory.")],
    seq_id: Annotated[str, typer.Argument(help="Sequence id (sequences.seq_id).")],
    out: Annotated[Path, typer.Argument(help="BVH file to write.")],
    units: Annotated[
        str | None,
        typer.Option(
            help="Length unit of the file: m, cm, mm, in, ft, dm or metres per unit. Default: "
            "the source file's unit for BVH stores, else cm."
        ),
    ] = None,
    rotation_order: Annotated[
        str,
        typer.Option(
            help="Channel order of a generated layout (SMPL stores), intrinsic: ZYX, ZXY, ..."
        ),
    ] = "ZYX",
    smpl_model: Annotated[
        Path | None,
        typer.Option(
            help="SMPL model (.npz/.pkl) giving the rest skeleton of SMPL stores (default: "
            "$DANCEDATA_SMPL_MODEL; without one, an approximate rest skeleton)."
        ),
    ] = None,
    version: VersionOpt = None,
    as_json: Json = False,
) -> None:
    """Write sequence SEQ_ID to OUT.bvh: BVH stores in their original channel layout, other
    stores (SMPL) in a generated one."""
    from dancedata.export.bvh import BvhExportOptions, export_bvh

    options = BvhExportOptions(
        version=version, units=units, rotation_order=rotation_order, smpl_model=smpl_model
    )
    report(export_bvh(open_handle(store), seq_id, out, options), "export bvh", as_json)
