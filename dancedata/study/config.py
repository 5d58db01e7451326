"""Experiment configs (docs/EXPERIMENTS.md §6): a TOML file → a validated, fully defaulted config.

A config names a matrix of rows (keyframe strategy + in-betweener, the row keys of §5.1, e.g.
``even+linear_slerp``) × keyframe counts N × metrics, the split to evaluate on, and every
[CHOICE] parameter of §2–4. Every key, defaults filled in, enters the run fingerprint
(:func:`run_fingerprint`), so two results with the same ``run_id`` come from the same settings.

File layout (every table and key optional except ``rows`` or ``[matrix]``)::

    id = "thesis-table-4.3"
    tables = ["4.3"]                      # seed tables this config regenerates
    store = "data/stores/aist"            # the CLI's --store overrides
    n_keyframes = [3, 5, 9]
    rows = ["even+linear_slerp", "dp+bezier_oracle"]
    [matrix]                              # alternative to rows: every keyframes × inbetween
    keyframes = ["even", "onset"] ; inbetween = ["linear_slerp", "bezier_oracle"]
    [split]    scheme = "crossmodal" ; eval = ["test", "val"] ; train = "train"
               exclude_genres = ["gJB"]
    [keyframes] n_counts_edges, G, peak_source, fill, stem_weights, nmfd_weights, normalize,
               audio_scope, dp_distance, combine, euler_branch
    [inbetween] bezier_group, bezier_param, bezier_trans, bezier_solver
    [metrics]  names = ["mse", "fid_g", "fid_k"] ; mse_space ; mse_wrap ; mse_reduce ;
               fid_unit ; fid_reference ; kinetic_mode ; geometric_frame_time ; normalize ;
               drop_constant_ref_columns ; fid_origin ; pfc_fps ; pfc_clip_frames (0: whole
               sequences) ; smpl_model
    [generated] "even+transformer_motion@9" = "path/to/outputs"   # class M rows

Unknown keys are refused (a typo would otherwise silently run the default).
"""

from __future__ import annotations

import copy
import os
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dancedata.errors import InputError
from dancedata.methods.keyframes import KeyframeParams, canonical_strategy
from dancedata.study.metric_registry import experiment_metric_names

# In-betweeners of §3 by row-key name; transformer:* rows need a trained model (class M).
INBETWEENERS: tuple[str, ...] = ("linear_slerp", "bezier_oracle", "bezier_train_mean")
TRANSFORMER_PREFIX = "transformer_"
GENRES_9: tuple[str, ...] = ("gBR", "gHO", "gJS", "gKR", "gLH", "gLO", "gMH", "gPO", "gWA")

DEFAULTS: dict[str, Any] = {
    "id": "experiment",
    "tables": [],
    "store": None,
    "n_keyframes": [3, 5, 9],
    "rows": [],
    "split": {
        "scheme": "crossmodal",
        "eval": ["test", "val"],
        "train": "train",
        "exclude_genres": ["gJB"],
    },
    "keyframes": {
        "n_counts_edges": True,
        "G": 6,
        "peak_source": "local_max",
        "fill": "adjacent_max_sum",
        "stem_weights": {"drums": 1.0, "bass": 1.0, "vocals": 1.0, "other": 1.0},
        "nmfd_weights": {"kick": 1.0, "snare": 1.0, "hihat": 1.0},
        "normalize": False,
        "audio_scope": "track",
        "dp_distance": "vertical",
        "combine": "max",
        "euler_branch": "principal",
    },
    "inbetween": {
        "bezier_group": "channel_slot",
        "bezier_param": "absolute",
        "bezier_trans": "bezier",
        "bezier_solver": "closed_form",
    },
    "metrics": {
        "names": ["mse"],
        "mse_space": "euler75",
        "mse_wrap": False,
        "mse_reduce": "pooled",
        "fid_unit": "sequence",
        "fid_reference": "paired_gt",
        "kinetic_mode": "parity",
        "geometric_frame_time": 1.0 / 120.0,
        "normalize": True,
        "drop_constant_ref_columns": False,
        "fid_origin": "world",
        "pfc_fps": 30.0,
        "pfc_clip_frames": 0,
        "smpl_model": "$DANCEDATA_SMPL_MODEL",
    },
    "generated": {},
}
_CHOICES = {
    ("inbetween", "bezier_group"): ("channel_slot", "channel"),
    ("inbetween", "bezier_param"): ("absolute", "chord_relative"),
    ("inbetween", "bezier_trans"): ("bezier", "linear"),
    ("inbetween", "bezier_solver"): ("closed_form", "lm"),
    ("metrics", "mse_space"): ("euler75", "euler72"),
    ("metrics", "mse_reduce"): ("pooled", "measure_mean", "sequence_mean"),
    ("metrics", "fid_unit"): ("sequence", "measure"),
    ("metrics", "fid_reference"): ("paired_gt",),
    ("metrics", "kinetic_mode"): ("parity", "corrected"),
    ("metrics", "fid_origin"): ("world", "first_frame_root"),
}

# Every key's type and range (checked before any value is used; bool is never taken as a
# number nor a string as a bool). ``str``/``int`` lists accept one bare value too.
MAX_CONFIG_BYTES = 256 << 10  # a config is a few hundred bytes; 256 KiB is far above any real one
MAX_LINE_CHARS = 10_000  # tomllib is quadratic in the parts of one dotted key: keep lines short
MAX_CONFIG_DEPTH = 8  # tables and arrays inside each other (the layout above needs 3)
MAX_KEYFRAMES = 1000  # keyframes per measure: a measure at 60 fps has ~120 frames
MAX_LIST_ITEMS = 1000
_NAME = r"[A-Za-z0-9_][A-Za-z0-9_.+=@-]{0,127}"
_TYPES: dict[tuple[str, ...], tuple[str, Any]] = {
    ("id",): ("name", None),
    ("tables",): ("str_list", None),
    ("store",): ("str_or_none", None),
    ("n_keyframes",): ("int_list", (2, MAX_KEYFRAMES)),
    ("rows",): ("str_list", None),
    ("split", "scheme"): ("str", None),
    ("split", "eval"): ("str_list", None),
    ("split", "train"): ("str", None),
    ("split", "exclude_genres"): ("str_list", None),
    ("keyframes", "n_counts_edges"): ("bool", None),
    ("keyframes", "G"): ("int", (0, 10_000)),
    ("keyframes", "peak_source"): ("str", None),
    ("keyframes", "fill"): ("str", None),
    ("keyframes", "stem_weights"): ("weights", (0.0, 1e6)),
    ("keyframes", "nmfd_weights"): ("weights", (0.0, 1e6)),
    ("keyframes", "normalize"): ("bool", None),
    ("keyframes", "audio_scope"): ("str", None),
    ("keyframes", "dp_distance"): ("str", None),
    ("keyframes", "combine"): ("str", None),
    ("keyframes", "euler_branch"): ("str", None),
    ("inbetween", "bezier_group"): ("str", None),
    ("inbetween", "bezier_param"): ("str", None),
    ("inbetween", "bezier_trans"): ("str", None),
    ("inbetween", "bezier_solver"): ("str", None),
    ("metrics", "names"): ("str_list", None),
    ("metrics", "mse_space"): ("str", None),
    ("metrics", "mse_wrap"): ("bool", None),
    ("metrics", "mse_reduce"): ("str", None),
    ("metrics", "fid_unit"): ("str", None),
    ("metrics", "fid_reference"): ("str", None),
    ("metrics", "kinetic_mode"): ("str", None),
    ("metrics", "geometric_frame_time"): ("float", (1e-6, 10.0)),
    ("metrics", "normalize"): ("bool", None),
    ("metrics", "drop_constant_ref_columns"): ("bool", None),
    ("metrics", "smpl_model"): ("str_or_none", None),
    ("generated",): ("str_table", None),
}
_KINDS = {
    "name": "a plain name (letters, digits, _ . + = @ -; no / or ..)",
    "str": "a string",
    "str_or_none": "a string",
    "str_list": "a string or a list of strings",
    "int": "an integer",
    "int_list": "an integer or a list of integers",
    "float": "a number",
    "bool": "true or false",
    "weights": "a table of numbers",
    "str_table": "a table of strings",
}


def _depth(value: Any, limit: int) -> int:
    """Nesting depth of tables and arrays, without recursion (a hostile file can nest deeply)."""
    deepest, stack = 0, [(value, 1)]
    while stack:
        node, level = stack.pop()
        if isinstance(node, dict | list):
            deepest = max(deepest, level)
            if deepest > limit:
                return deepest
            children = node.values() if isinstance(node, dict) else node
            stack.extend((child, level + 1) for child in children)
    return deepest


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _shown(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _type_ok(kind: str, value: Any, items: list[Any]) -> bool:
    """Whether ``value`` (``items``: it as a list) has the type of ``kind`` (ranges apart)."""
    import math
    import re

    if kind == "name":
        return isinstance(value, str) and bool(re.fullmatch(_NAME, value)) and ".." not in value
    if kind == "str":
        return isinstance(value, str)
    if kind == "str_or_none":
        return value is None or isinstance(value, str)
    if kind == "str_list":
        return all(isinstance(v, str) for v in items)
    if kind == "bool":
        return isinstance(value, bool)
    if kind in ("int", "int_list"):
        return all(_is_int(v) for v in items)
    if kind == "float":
        return _is_number(value) and math.isfinite(value)
    if kind == "weights":
        return isinstance(value, dict) and all(
            isinstance(k, str) and _is_number(v) and math.isfinite(v) for k, v in value.items()
        )
    if kind == "str_table":
        return isinstance(value, dict) and all(
            isinstance(k, str) and isinstance(v, str) for k, v in value.items()
        )
    raise AssertionError(kind)  # pragma: no cover - every kind of _TYPES is above


def _check_types(data: dict[str, Any], source: str) -> None:
    """Refuse any value of the wrong type or out of range: one line naming the key."""
    for keys, (kind, bounds) in _TYPES.items():
        value: Any = data
        for key in keys:
            value = value[key]
        where = ".".join(keys)
        items = value if isinstance(value, list) else [value]
        if kind in ("str_list", "int_list") and len(items) > MAX_LIST_ITEMS:
            raise InputError(f"{where} has {len(items)} items (at most {MAX_LIST_ITEMS})", source)
        if not _type_ok(kind, value, items):
            raise InputError(f"{where} = {_shown(value)}: must be {_KINDS[kind]}", source)
        if bounds is None:
            continue
        lo, hi = bounds
        named = value.items() if kind == "weights" else ((where, v) for v in items)
        for name, number in named:
            if not lo <= number <= hi:
                label = f"{where}.{name}" if kind == "weights" else where
                raise InputError(f"{label} = {_shown(number)}: must be in [{lo}, {hi}]", source)


@dataclass(frozen=True)
class RowKey:
    """One (keyframe strategy, in-betweener) pair, e.g. ``dp+bezier_oracle``."""

    key: str
    strategy: str  # canonical keyframe strategy: even, peaks:onset, ..., dp
    inbetween: str  # linear_slerp, bezier_oracle, bezier_train_mean or transformer_*

    @property
    def learned(self) -> bool:
        """Class M: the in-betweens come from a trained model's outputs."""
        return self.inbetween.startswith(TRANSFORMER_PREFIX)


def parse_row_key(key: str) -> RowKey:
    """``"onset+linear_slerp"`` → RowKey; one clear line for an unknown part."""
    kf, sep, ib = key.partition("+")
    if not sep:
        raise InputError(
            f"row key {key!r} must read <keyframes>+<inbetween>, e.g. even+linear_slerp"
        )
    strategy = canonical_strategy(kf)
    if ib not in INBETWEENERS and not (ib.startswith(TRANSFORMER_PREFIX) and len(ib) > 12):
        known = ", ".join([*INBETWEENERS, "transformer_<variant>"])
        raise InputError(f"unknown in-betweener {ib!r} in row key {key!r}; known: {known}")
    return RowKey(key, strategy, ib)


@dataclass(frozen=True)
class ExperimentConfig:
    """A validated config: ``data`` is the full dict (defaults filled) that is fingerprinted."""

    data: dict[str, Any]
    path: Path | None = None

    @property
    def id(self) -> str:
        return str(self.data["id"])

    @property
    def rows(self) -> list[RowKey]:
        return [parse_row_key(k) for k in self.data["rows"]]

    @property
    def n_keyframes(self) -> list[int]:
        return list(self.data["n_keyframes"])

    @property
    def metrics(self) -> list[str]:
        return list(self.data["metrics"]["names"])

    @property
    def split(self) -> dict[str, Any]:
        return self.data["split"]

    @property
    def split_label(self) -> str:
        """``crossmodal:test+val`` (docs/EXPERIMENTS.md §5.5 ``split`` column)."""
        return f"{self.split['scheme']}:{'+'.join(self.split['eval'])}"

    def keyframe_params(self) -> KeyframeParams:
        k = self.data["keyframes"]
        return KeyframeParams(
            n_counts_edges=k["n_counts_edges"],
            guard=k["G"],
            peak_source=k["peak_source"],
            fill=k["fill"],
            stem_weights=dict(k["stem_weights"]),
            nmfd_weights=dict(k["nmfd_weights"]),
            normalize=k["normalize"],
            audio_scope=k["audio_scope"],
            dp_distance=k["dp_distance"],
            combine=k["combine"],
            euler_branch=k["euler_branch"],
        )

    def smpl_model_path(self) -> Path | None:
        """The SMPL model file the FID metrics use, ``$VAR`` expanded; None when unset."""
        value = self.data["metrics"]["smpl_model"]
        if not value:
            return None
        expanded = os.path.expandvars(str(value))
        if not expanded or expanded.startswith("$"):
            return None
        return Path(expanded).expanduser()


def _merge(defaults: dict[str, Any], given: dict[str, Any], where: str, source: str) -> dict:
    out = copy.deepcopy(defaults)
    for key, value in given.items():
        if key not in defaults:
            known = ", ".join(sorted(defaults))
            raise InputError(f"unknown key '{where}{key}' (known: {known})", source)
        if isinstance(defaults[key], dict) and key not in ("stem_weights", "nmfd_weights",
                                                         "generated"):  # fmt: skip
            if not isinstance(value, dict):
                raise InputError(f"{where}{key} must be a table", source)
            out[key] = _merge(defaults[key], value, f"{where}{key}.", source)
        else:
            out[key] = value
    return out


def _as_list(value: Any) -> list[Any]:
    return list(value) if isinstance(value, list | tuple) else [value]


def build_config(raw: dict[str, Any], source: str = "<config>",
                 path: Path | None = None) -> ExperimentConfig:  # fmt: skip
    """Validate ``raw`` (a parsed TOML document), fill the defaults, expand ``[matrix]``."""
    if _depth(raw, MAX_CONFIG_DEPTH) > MAX_CONFIG_DEPTH:
        raise InputError(f"tables or arrays nested deeper than {MAX_CONFIG_DEPTH} levels", source)
    raw = dict(raw)
    matrix = raw.pop("matrix", None)
    if matrix is not None and not isinstance(matrix, dict):
        raise InputError("matrix must be a table", source)
    data = _merge(DEFAULTS, raw, "", source)
    _check_types(data, source)
    for part in ("keyframes", "inbetween"):
        values = matrix.get(part) if matrix is not None else None
        if values is not None and not all(isinstance(v, str) for v in _as_list(values)):
            raise InputError(f"matrix.{part} must be a string or a list of strings", source)
    rows = [str(r) for r in _as_list(data["rows"])]
    if matrix is not None:
        unknown = sorted(set(matrix) - {"keyframes", "inbetween"})
        if unknown:
            raise InputError(
                f"unknown key(s) matrix.{unknown}: use keyframes and inbetween", source
            )
        for kf in _as_list(matrix.get("keyframes", ["even"])):
            for ib in _as_list(matrix.get("inbetween", ["linear_slerp"])):
                rows.append(f"{kf}+{ib}")
    if not rows:
        raise InputError("the config names no rows (give rows = [...] or a [matrix])", source)
    data["rows"] = list(dict.fromkeys(rows))
    for key in data["rows"]:
        parse_row_key(key)
    try:
        counts = sorted({int(n) for n in _as_list(data["n_keyframes"])})
    except (TypeError, ValueError):
        raise InputError(
            f"n_keyframes must be whole numbers: {data['n_keyframes']!r}", source
        ) from None
    if not counts or counts[0] < 2:
        raise InputError(f"n_keyframes must be ≥ 2 (first and last frame): {counts}", source)
    data["n_keyframes"] = counts
    split = data["split"]
    split["eval"] = [str(s) for s in _as_list(split["eval"])]
    split["exclude_genres"] = sorted(str(g) for g in _as_list(split["exclude_genres"]))
    names = [str(m) for m in _as_list(data["metrics"]["names"])]
    known = experiment_metric_names()
    bad = [m for m in names if m not in known]
    if bad:
        raise InputError(f"unknown metric(s) {bad}; the runner computes {list(known)}", source)
    data["metrics"]["names"] = names
    pfc_fps, clip = data["metrics"]["pfc_fps"], data["metrics"]["pfc_clip_frames"]
    if not isinstance(pfc_fps, int | float) or pfc_fps <= 0 or abs(60.0 / pfc_fps % 1) > 1e-9:
        raise InputError(f"metrics.pfc_fps = {pfc_fps!r} must divide 60 (EDGE: 30)", source)
    if not isinstance(clip, int) or isinstance(clip, bool) or clip < 0 or 0 < clip < 3:
        raise InputError(f"metrics.pfc_clip_frames = {clip!r}: 0 (whole) or >= 3 frames", source)
    for (table, key), known in _CHOICES.items():
        if data[table][key] not in known:
            raise InputError(
                f"{table}.{key} = {data[table][key]!r}; known: {', '.join(known)}", source
            )
    data["tables"] = [str(t) for t in _as_list(data["tables"])]
    data["generated"] = {str(k): str(v) for k, v in data["generated"].items()}
    config = ExperimentConfig(data, path)
    config.keyframe_params()  # validates the keyframe [CHOICE]s with their own messages
    return config


def apply_override(raw: dict[str, Any], assignment: str) -> None:
    """``"split.eval=train"`` / ``"n_keyframes=[3,9]"`` / ``"metrics.mse_wrap=true"``: set a
    dotted key of ``raw``; the value is read as TOML (bare words as strings)."""
    key, sep, text = assignment.partition("=")
    if not sep or not key.strip():
        raise InputError(f"--set takes key=value, got {assignment!r}")
    try:
        value = tomllib.loads(f"v = {text.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = text.strip()
    except RecursionError:
        raise InputError(f"--set {key.strip()}: the value is nested too deeply") from None
    parts = key.strip().split(".")
    if len(parts) > MAX_CONFIG_DEPTH:
        raise InputError(f"--set {key.strip()[:80]}: more than {MAX_CONFIG_DEPTH} levels")
    node = raw
    for part in parts[:-1]:
        node = node.setdefault(part, {})
        if not isinstance(node, dict):
            raise InputError(f"--set {key}: {part} is not a table")
    node[parts[-1]] = value


def load_config(path: str | Path, overrides: list[str] | None = None) -> ExperimentConfig:
    """Read and validate a TOML experiment config; InputError naming the file otherwise."""
    path = Path(path)
    try:
        with path.open("rb") as fh:
            data = fh.read(MAX_CONFIG_BYTES + 1)
        text = data.decode("utf-8")
    except FileNotFoundError:
        raise InputError("experiment config not found", path) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read experiment config: {exc}", path) from None
    if len(data) > MAX_CONFIG_BYTES:
        raise InputError(f"experiment config is larger than {MAX_CONFIG_BYTES} bytes", path)
    longest = max((len(line) for line in text.splitlines()), default=0)
    if longest > MAX_LINE_CHARS:
        raise InputError(f"a line of {longest} characters (at most {MAX_LINE_CHARS})", path)
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"not valid TOML: {exc}", path) from None
    except RecursionError:
        raise InputError("not valid TOML: arrays or tables nested too deeply", path) from None
    for assignment in overrides or []:
        apply_override(raw, assignment)
    return build_config(raw, str(path), path)
