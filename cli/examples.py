"""One worked example per command, shown at the end of ``dancedata COMMAND --help``.

Keyed by the command's path below ``dancedata`` ("featurize", "ingest aist"). The paths are the
demo's (``make pipeline``): data/raw/aist-demo and data/stores/aist-demo. A command whose own
help already holds a line starting "Example" keeps it; every other command needs an entry here
(tests/cli/test_cli_rough_edges.py checks every command's --help).
"""

from __future__ import annotations

S = "data/stores/aist-demo"
SEQ = "gBR_sBM_cAll_d04_mBR0_ch01"

EXAMPLES: dict[str, str] = {
    "synth aist": "dancedata synth aist data/raw/aist-demo --sequences 24 --seed 0",
    "ingest aist": f"dancedata ingest aist data/raw/aist-demo --store {S}",
    "ingest bvh": "dancedata ingest bvh mocap/*.bvh --store data/stores/mocap --units cm "
    "--music song.wav --bpm 120",
    "ingest video": "dancedata ingest video clips/*.mp4 --poses openpose_json/ "
    "--store data/stores/clips",
    "featurize": f"dancedata featurize {S} --workers 2",
    "segment": f"dancedata segment {S} --beats-per-measure 4",
    "resample": f"dancedata resample {S} --fps 20",
    "keyframes": f"dancedata keyframes {S} --strategy even,onset --n 3,5",
    "evaluate": f"dancedata evaluate {S} --generated outputs/ --split test --out results/",
    "experiment run": f"dancedata experiment run experiments/demo.toml --store {S} "
    "--out data/stores/aist-demo-experiment",
    "experiment table": "dancedata experiment table demo --results "
    "data/stores/aist-demo-experiment --format md",
    "export bvh": f"dancedata export bvh {S} {SEQ} out.bvh",
    "info": f"dancedata info {S} --version v2 --json",
    "versions": f"dancedata versions {S}",
    "validate": f"dancedata validate {S} --deep",
    "checkout": f"dancedata checkout {S} v3",
    "unlock": f"dancedata unlock {S}",
    "plot": f"dancedata plot {S} {SEQ} plot.png",
    "render": f"dancedata render {S} {SEQ} dance.mp4",
    "report": f"dancedata report {S} report.html",
    "cache list": "dancedata cache list",
    "cache clear": "dancedata cache clear --older-than 30",
    "cache warm": "dancedata cache warm",
}
