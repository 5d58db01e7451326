"""Keyframe selection (docs/EXPERIMENTS.md §2, tests of §7.1) and the `dancedata keyframes` command.

References: closed-form index lists from the spec, ``scipy.signal.find_peaks``, a brute force
over every keyframe subset, and a per-measure loop against the batched functions.
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from scipy.signal import find_peaks

from dancedata.errors import InputError
from dancedata.methods.keyframes import (
    KeyframeParams,
    canonical_strategy,
    dp_keyframes,
    even_keyframes,
    peak_keyframes,
)
from dancedata.methods.keyframes_dp import (
    dp_keyframes_batch,
    segment_error_table,
    segment_errors,
)
from dancedata.methods.keyframes_peaks import local_maxima, peak_keyframes_batch

# ----------------------------------------------------------------------------------- even


@pytest.mark.parametrize(
    ("n", "expected"),
    [
        (3, [0, 72, 143]),
        (5, [0, 36, 72, 107, 143]),
        (9, [0, 18, 36, 54, 72, 89, 107, 125, 143]),
    ],
)
def test_even_keyframes_of_a_144_frame_measure(n: int, expected: list[int]) -> None:
    kf = even_keyframes(144, n)
    assert kf.indices.tolist() == expected
    assert kf.source == ("edge",) + ("even",) * (n - 2) + ("edge",)
    assert np.isnan(kf.score).all()


def test_even_keyframes_when_every_frame_is_one_and_when_too_short() -> None:
    assert even_keyframes(7, 7).indices.tolist() == list(range(7))
    with pytest.raises(InputError, match="cannot hold"):
        even_keyframes(4, 5)


# ---------------------------------------------------------------------------------- peaks


def bumps(length: int, centres: list[int], heights: list[float], width: float = 2.0) -> np.ndarray:
    t = np.arange(length, dtype=np.float64)
    return sum(
        h * np.exp(-0.5 * ((t - c) / width) ** 2) for c, h in zip(centres, heights, strict=True)
    )


def test_peaks_take_the_highest_maxima_first() -> None:
    centres, heights = [20, 45, 70, 95, 120], [1.0, 5.0, 3.0, 4.0, 2.0]
    curve = bumps(144, centres, heights)
    assert find_peaks(curve)[0].tolist() == centres
    for n, chosen in ((3, [45]), (4, [45, 95]), (5, [45, 70, 95]), (7, centres)):
        kf = peak_keyframes(curve, n, guard=6)
        assert kf.indices.tolist() == [0, *chosen, 143]
        assert kf.source == ("edge",) + ("peak",) * (n - 2) + ("edge",)
        np.testing.assert_array_equal(kf.score[1:-1], curve[chosen])
    # the ranking itself: each larger N adds the next-highest peak
    order = []
    for n in range(3, 8):
        new = set(peak_keyframes(curve, n).indices.tolist()) - set(order) - {0, 143}
        order += sorted(new)
    assert order == [45, 95, 70, 120, 20]  # heights 5, 4, 3, 2, 1


def test_equal_peaks_go_to_the_smaller_frame() -> None:
    curve = bumps(100, [30, 60], [2.0, 2.0])
    assert peak_keyframes(curve, 3).indices.tolist() == [0, 30, 99]


def test_edge_guard_drops_peaks_near_the_ends() -> None:
    curve = bumps(120, [3, 60, 116], [9.0, 1.0, 8.0], width=1.0)
    assert find_peaks(curve)[0].tolist() == [3, 60, 116]
    assert peak_keyframes(curve, 3, guard=6).indices.tolist() == [0, 60, 119]
    assert peak_keyframes(curve, 3, guard=3).indices.tolist() == [0, 3, 119]
    # 116 = L−1−3 is inside a guard of 4 but not of 3
    assert peak_keyframes(curve, 4, guard=3).indices.tolist() == [0, 3, 116, 119]
    # with G = 4 only 60 is left; the fill goes into (0, 60), whose c[0] + c[60] is larger
    assert peak_keyframes(curve, 4, guard=4).indices.tolist() == [0, 30, 60, 119]


def test_a_flat_curve_is_filled_deterministically() -> None:
    kf = peak_keyframes(np.zeros(20), 5)
    # (0,19) → 9; then the larger gap (9,19) → 14; then (0,9) → 4
    assert kf.indices.tolist() == [0, 4, 9, 14, 19]
    assert kf.source == ("edge", "fill", "fill", "fill", "edge")
    again = peak_keyframes(np.zeros(20), 5)
    assert again.indices.tolist() == kf.indices.tolist()


def test_fill_prefers_the_pair_with_the_largest_curve_sum() -> None:
    curve = np.zeros(40)
    curve[0], curve[39] = 1.0, 3.0
    curve[10:13] = [0.0, 2.0, 0.0]  # one peak at 11
    kf = peak_keyframes(curve, 4, guard=0)
    # pairs (0,11): 1+2, (11,39): 2+3 → fill between 11 and 39
    assert kf.indices.tolist() == [0, 11, 25, 39]
    assert kf.source == ("edge", "peak", "fill", "edge")


def test_top2_midpoint_fill_and_its_fallback() -> None:
    curve = np.zeros(41)
    curve[0], curve[40] = 5.0, 4.0
    kf = peak_keyframes(curve, 3, fill="top2_midpoint")
    assert kf.indices.tolist() == [0, 20, 40]
    # the two highest selected (0 and 20) have their midpoint 10 free; next: 0 and 10 → 5
    kf = peak_keyframes(curve, 5, fill="top2_midpoint")
    assert kf.indices.tolist() == [0, 5, 10, 20, 40]
    # when the two highest are adjacent frames the midpoint is taken: adjacent_max_sum instead
    curve = np.zeros(10)
    curve[4:6] = [3.0, 2.5]
    curve[3] = curve[6] = 0.0
    top2 = peak_keyframes(curve, 5, guard=0, fill="top2_midpoint")
    adj = peak_keyframes(curve, 5, guard=0, fill="adjacent_max_sum")
    assert top2.indices[0] == 0 and top2.indices[-1] == 9
    assert len(set(top2.indices.tolist())) == 5
    assert adj.indices.tolist() != [] and len(set(adj.indices.tolist())) == 5


def test_plateau_maximum_gives_its_middle_frame() -> None:
    curve = np.zeros(30)
    curve[10:14] = 1.0  # plateau 10..13 → floor(11.5) = 11
    curve[20:23] = 0.5  # plateau 20..22 → 21
    assert local_maxima(curve[None])[0].nonzero()[0].tolist() == [11, 21]
    assert peak_keyframes(curve, 4, guard=0).indices.tolist() == [0, 11, 21, 29]


def test_local_maxima_equal_scipy_find_peaks_on_random_curves() -> None:
    rng = np.random.default_rng(0)
    for _ in range(300):
        length = int(rng.integers(1, 50))
        curve = rng.integers(0, 4, size=length).astype(np.float64)  # many plateaus
        ours = local_maxima(curve[None])[0].nonzero()[0]
        np.testing.assert_array_equal(ours, find_peaks(curve)[0])


def test_candidate_mask_replaces_the_detector() -> None:
    curve = bumps(100, [20, 50, 80], [3.0, 2.0, 1.0])
    mask = np.zeros(100, dtype=bool)
    mask[[0, 50, 80, 99]] = True  # the stored onset peaks; the edges never count
    assert peak_keyframes(curve, 4, candidates=mask).indices.tolist() == [0, 50, 80, 99]


def test_peak_batch_equals_a_loop_over_measures() -> None:
    rng = np.random.default_rng(1)
    curves = np.abs(rng.normal(size=(40, 60))).round(1)  # ties and plateaus
    curves[5] = 0.0
    for fill in ("adjacent_max_sum", "top2_midpoint"):
        idx, _src, score = peak_keyframes_batch(curves, 9, 6, fill)
        for i, curve in enumerate(curves):
            one = peak_keyframes(curve, 9, 6, fill)
            assert idx[i].tolist() == one.indices.tolist()
            np.testing.assert_array_equal(score[i], one.score)
            assert (np.diff(idx[i]) > 0).all() and idx[i, 0] == 0 and idx[i, -1] == 59


def test_peak_curves_must_be_finite() -> None:
    curve = np.zeros(20)
    curve[3] = np.nan
    with pytest.raises(InputError, match="NaN"):
        peak_keyframes(curve, 3)


# ------------------------------------------------------------------------------------- dp


def direct_error(x: np.ndarray, a: int, b: int, distance: str) -> float:
    """e(a, b) straight from the definition (docs/EXPERIMENTS.md §2.4)."""
    if b - a < 2:
        return 0.0
    if distance == "perpendicular":
        y = np.concatenate([np.arange(len(x), dtype=np.float64)[:, None], x], axis=1)
        d = y[a : b + 1] - y[a]
        v = y[b] - y[a]
        r = d - np.outer(d @ v / (v @ v), v)
    else:
        s = (np.arange(a, b + 1) - a) / (b - a)
        r = x[a : b + 1] - x[a] - s[:, None] * (x[b] - x[a])
    return float(np.sqrt((r**2).sum(axis=1)).max())


def piecewise_linear(length: int, corners: list[int], dims: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    knots = [0, *corners, length - 1]
    values = rng.normal(size=(len(knots), dims)) * 2.0
    t = np.arange(length)
    return np.stack([np.interp(t, knots, values[:, d]) for d in range(dims)], axis=1)


@pytest.mark.slow
@pytest.mark.parametrize("distance", ["vertical", "perpendicular"])
@pytest.mark.parametrize("engine", ["numba", "numpy"])
def test_dp_finds_the_corners_of_a_piecewise_linear_curve(distance: str, engine: str) -> None:
    corners = [17, 40, 41, 77, 101, 130]
    x = piecewise_linear(144, corners, 75, seed=2)
    found = dp_keyframes_batch(x[None], [8], distance, "max", engine)[8]
    assert found[0][0].tolist() == [0, *corners, 143]
    assert found[1][0] < 1e-6  # Gram-expansion rounding only
    np.testing.assert_allclose(found[2][0, 1:], 0.0, atol=1e-6)  # table scores
    np.testing.assert_allclose(segment_errors(x[None], found[0], distance), 0.0, atol=1e-12)
    kf, cost = dp_keyframes(x, 8, distance)
    assert kf.indices.tolist() == [0, *corners, 143] and cost < 1e-6
    assert kf.source == ("dp",) * 8


@pytest.mark.parametrize("distance", ["vertical", "perpendicular"])
def test_error_table_matches_the_definition(distance: str) -> None:
    x = np.random.default_rng(3).normal(size=(30, 5)).cumsum(axis=0)
    table = {e: segment_error_table(x, distance, e) for e in ("numba", "numpy")}
    for a in range(30):
        for b in range(a + 1, 30):
            want = direct_error(x, a, b, distance)
            assert abs(table["numba"][a, b] - want) < 1e-9
            assert abs(table["numpy"][a, b] - want) < 1e-9
    assert np.isinf(table["numba"][np.tril_indices(30)]).all()


@pytest.mark.slow
@pytest.mark.parametrize("distance", ["vertical", "perpendicular"])
@pytest.mark.parametrize("combine", ["max", "sum"])
def test_dp_cost_equals_brute_force_over_every_subset(distance: str, combine: str) -> None:
    rng = np.random.default_rng(4)
    join = max if combine == "max" else sum
    for trial in range(12):
        length = int(rng.integers(4, 15))  # L ≤ 14
        x = rng.normal(size=(length, 3)).cumsum(axis=0)
        for n in range(2, min(length, 6) + 1):
            best = np.inf
            for inner in itertools.combinations(range(1, length - 1), n - 2):
                kf = [0, *inner, length - 1]
                cost = join(direct_error(x, a, b, distance) for a, b in itertools.pairwise(kf))
                best = min(best, cost)
            found, cost, scores = dp_keyframes_batch(x[None], [n], distance, combine)[n]
            assert abs(cost[0] - best) < 1e-9, (trial, length, n)
            # the keyframes found have that cost when scored directly
            direct = segment_errors(x[None], found, distance)[0]
            assert abs(join(direct.tolist()) - best) < 1e-9
            np.testing.assert_allclose(scores[0, 1:], direct, atol=1e-9)


@pytest.mark.parametrize("combine", ["max", "sum"])
def test_dp_engines_agree_with_ties(combine: str) -> None:
    from dancedata.methods.keyframes_dp import dp_tables

    x = np.random.default_rng(7).normal(size=(20, 40, 3)).cumsum(axis=1)
    x[:5, 10:25] = x[:5, 10:11]  # still stretches: many equal (zero) segment errors
    errors = segment_error_table(x)
    c1, b1 = dp_tables(errors, 9, combine, "numba")
    c2, b2 = dp_tables(errors, 9, combine, "numpy")
    np.testing.assert_array_equal(c1, c2)
    np.testing.assert_array_equal(b1, b2)


def test_dp_batch_serves_every_n_from_one_table() -> None:
    x = np.random.default_rng(5).normal(size=(6, 50, 4)).cumsum(axis=1)
    together = dp_keyframes_batch(x, [3, 5, 9])
    for n in (3, 5, 9):
        for i in range(6):
            alone, cost = dp_keyframes(x[i], n)
            assert together[n][0][i].tolist() == alone.indices.tolist()
            assert abs(together[n][1][i] - cost) < 1e-12


def test_dp_sum_spends_keyframes_on_free_one_frame_segments() -> None:
    """The spec's evidence for max over the seed's 'plus': with per-segment maximum errors a
    sum is lowered by zero-cost one-frame segments, which minimax has no use for."""
    x = np.random.default_rng(6).normal(size=(60, 4)).cumsum(axis=0)
    kf_sum, _ = dp_keyframes(x, 6, combine="sum")
    kf_max, _ = dp_keyframes(x, 6, combine="max")
    assert (np.diff(kf_sum.indices) == 1).sum() >= 2
    assert (np.diff(kf_max.indices) == 1).sum() == 0


def test_bad_parameters_are_one_line_errors() -> None:
    with pytest.raises(InputError, match="unknown keyframe strategy"):
        canonical_strategy("random")
    assert canonical_strategy("onset") == "peaks:onset"
    with pytest.raises(InputError, match="fill rule"):
        KeyframeParams(fill="nearest")
    with pytest.raises(InputError, match="stem"):
        KeyframeParams(stem_weights={"piano": 1.0})
    with pytest.raises(InputError, match="DP distance"):
        KeyframeParams(dp_distance="euclid")


# ------------------------------------------------------------------------- the command


@pytest.fixture(scope="module")
def small_store(tmp_path_factory) -> Path:
    from dancedata.featurize.featurize import FeaturizeOptions, featurize
    from dancedata.featurize.segment import SegmentOptions, segment
    from dancedata.ingest.aist import AistIngestOptions, ingest_aist
    from dancedata.synth.aist import synth_aist

    root = tmp_path_factory.mktemp("keyframes")
    synth_aist(root / "raw", n_sequences=2, seed=1)
    store = root / "store"
    ingest_aist(store, root / "raw", AistIngestOptions())
    featurize(store, FeaturizeOptions())
    segment(store, SegmentOptions())
    return store


@pytest.mark.slow
def test_keyframes_command_writes_a_version_with_every_strategy(small_store: Path) -> None:
    import dancedata
    from dancedata.store.validate import validate_store
    from dancedata.study.keyframes import KeyframesOptions, keyframes, read_keyframes

    options = KeyframesOptions(
        strategies=["even", "onset", "stems", "nmfd", "dp"], n_keyframes=[3, 5, 9]
    )
    result = keyframes(small_store, options)
    assert result.created
    table = read_keyframes(small_store)
    rows = table.to_pylist()
    store = dancedata.open_store(small_store)
    measures = store.measures.to_pylist()
    assert len(rows) == len(measures) * 5 * (3 + 5 + 9)
    assert validate_store(small_store) == []
    manifest = store.manifest
    assert manifest["command"] == "keyframes"
    assert manifest["config"]["params"]["guard"] == 6
    assert manifest["config"]["euler_order"] == "XYZ"
    assert manifest["stages"]["keyframes"] == manifest["fingerprint"]
    assert len(set(manifest["config"]["run_ids"].values())) == 15
    assert str(table.schema.field("measure").type) == "int32"
    assert str(table.schema.field("n_keyframes").type) == "int16"
    assert str(table.schema.field("score").type) == "float"

    by_measure = {(m["seq_id"], m["measure"]): m for m in measures}
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault((r["run_id"], r["seq_id"], r["measure"]), []).append(r)
    for (_run, seq_id, k), group in groups.items():
        m = by_measure[(seq_id, k)]
        length = m["frame_stop"] - m["frame_start"]
        frames = [r["frame"] for r in sorted(group, key=lambda r: r["k"])]
        assert frames[0] == 0 and frames[-1] == length - 1
        assert len(frames) == group[0]["n_keyframes"]
        assert all(r["frame_in_sequence"] == m["frame_start"] + r["frame"] for r in group)

    # each strategy's keyframes equal the pure function on the loader's own arrays
    seq_id = measures[1]["seq_id"]
    m = measures[1]
    a, b = m["frame_start"], m["frame_stop"]

    def picked(strategy: str, n: int) -> list[int]:
        chosen = [
            r
            for r in rows
            if r["strategy"] == strategy
            and r["n_keyframes"] == n
            and r["seq_id"] == seq_id
            and r["measure"] == m["measure"]
        ]
        return [r["frame"] for r in sorted(chosen, key=lambda r: r["k"])]

    assert picked("even", 9) == even_keyframes(b - a, 9).indices.tolist()
    onset = store.audio(seq_id, "onset_env")[a:b]
    assert picked("peaks:onset", 5) == peak_keyframes(onset, 5).indices.tolist()
    stems = store.weighted_stem_onsets(seq_id)[a:b]
    assert picked("peaks:stems", 9) == peak_keyframes(stems, 9).indices.tolist()
    nmfd = store.weighted_nmfd(seq_id)[a:b]
    assert picked("peaks:nmfd", 3) == peak_keyframes(nmfd, 3).indices.tolist()
    x = store.view(seq_id, "thesis_euler_75")[a:b]
    assert picked("dp", 9) == dp_keyframes(x, 9)[0].indices.tolist()

    again = keyframes(small_store, options)
    assert (again.created, again.version) == (False, result.version)


@pytest.mark.slow
def test_keyframes_cli_parameters_reach_the_manifest(small_store: Path) -> None:
    from helpers import run_cli

    done = run_cli(
        "keyframes", str(small_store), "--strategy", "stems", "-s", "dp", "--n", "4",
        "--stem-weights", "drums=2,bass=0.5", "--guard", "3", "--dp-distance", "perpendicular",
        "--json",
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    root = small_store / "versions" / summary["version"]
    config = json.loads((root / "manifest.json").read_text())["config"]
    assert config["strategies"] == ["peaks:stems", "dp"]
    assert config["params"]["stem_weights"] == {
        "drums": 2.0, "bass": 0.5, "vocals": 0.0, "other": 0.0
    }  # fmt: skip
    assert config["params"]["guard"] == 3 and config["params"]["dp_distance"] == "perpendicular"
    table = pq.read_table(root / "keyframes.parquet")
    assert set(table.column("n_keyframes").to_pylist()) == {4}

    bad = run_cli("keyframes", str(small_store), "--strategy", "random", check=False)
    assert bad.returncode == 1
    assert bad.stderr.strip().splitlines()[-1].startswith("error: unknown keyframe strategy")


@pytest.mark.slow
def test_measures_too_short_for_an_n_are_skipped_and_reported(small_store: Path) -> None:
    from dancedata.study.keyframes import KeyframesOptions, keyframes

    result = keyframes(small_store, KeyframesOptions(strategies=["even"], n_keyframes=[3, 10_000]))
    assert result.counts["runs"]["even@10000"] == 0
    assert result.counts["runs"]["even@3"] == result.counts["measures"] > 0
    assert result.skipped and all("too few for N = 10000" in s["error"] for s in result.skipped)
    with pytest.raises(InputError, match="every measure was left out"):
        keyframes(small_store, KeyframesOptions(strategies=["dp"], n_keyframes=[10_000]))


@pytest.mark.slow
def test_non_finite_motion_or_curves_are_one_line_errors(small_store: Path, tmp_path) -> None:
    import shutil

    import zarr

    from dancedata.store.reader import _VersionReader
    from dancedata.study.keyframes import KeyframesOptions, keyframes

    store = tmp_path / "damaged"
    shutil.copytree(small_store, store)  # a real copy: the fixture's files stay as they are
    reader = _VersionReader(store)
    seq = reader.table("sequences").to_pylist()[1]
    data = zarr.open_group(str(reader.path / "data.zarr"), mode="r+")
    euler = data["motion/euler"]
    euler[seq["frame_start"] + 7, 3, 1] = np.nan
    onset = data["audio/onset_env"]
    onset[5] = np.inf
    with pytest.raises(InputError, match=f"dp: motion of {seq['seq_id']} .* frame 7"):
        keyframes(store, KeyframesOptions(strategies=["dp"], n_keyframes=[3]))
    with pytest.raises(InputError, match="peaks:onset: the curve of .* holds NaN or Inf"):
        keyframes(store, KeyframesOptions(strategies=["onset"], n_keyframes=[3]))


@pytest.mark.slow
def test_a_keyframe_run_feeds_the_in_betweeners(small_store: Path) -> None:
    """Table → KeyframeRun → SegmentMap → linear_slerp equals even keyframes + SLERP computed
    measure by measure from the loader's views."""
    import dancedata
    from dancedata.methods.inbetween import linear_slerp
    from dancedata.metrics.reconstruction_error import mse_euler75
    from dancedata.study.keyframes import KeyframesOptions, keyframe_run, keyframes

    result = keyframes(small_store, KeyframesOptions(strategies=["even", "dp"], n_keyframes=[5]))
    run = keyframe_run(small_store, strategy="even", n_keyframes=5)
    assert run.run_id == dancedata.open_store(small_store).manifest["config"]["run_ids"]["even@5"]
    store = dancedata.open_store(small_store, result.version)
    measures = store.measures.to_pylist()
    assert run.keyframes.shape == (len(measures), 5)
    seg = run.segments()
    quat, trans = store.whole_array("motion/quat"), store.whole_array("motion/trans")
    euler = store.whole_array("motion/euler")
    rec = linear_slerp(quat, trans, seg, "XYZ", truth_euler=euler)
    truth = np.concatenate([trans, euler.reshape(len(euler), -1)], axis=1)[seg.frame]
    pooled = mse_euler75(truth, rec.euler75())
    # the same thing one measure at a time, from the views
    total, frames = 0.0, 0
    for m in measures:
        x = store.view(m["seq_id"], "thesis_euler_75")[m["frame_start"] : m["frame_stop"]]
        q = store.motion(m["seq_id"], "quat")[m["frame_start"] : m["frame_stop"]]
        from dancedata.methods.inbetween import segment_map

        one = segment_map([0], [len(x)], even_keyframes(len(x), 5).indices[None])
        r = linear_slerp(q, x[:, :3], one, "XYZ", truth_euler=x[:, 3:].reshape(len(x), 24, 3))
        total += mse_euler75(x, r.euler75()) * len(x)
        frames += len(x)
    assert pooled == pytest.approx(total / frames, rel=1e-9)
    with pytest.raises(InputError, match="no keyframes run"):
        keyframe_run(small_store, strategy="onset", n_keyframes=5)


@pytest.mark.real_data
def test_dp_on_a_real_measure_matches_the_spec_sanity_check(real_data: Path) -> None:
    """docs/EXPERIMENTS.md §8: gJS_sFM_cAll_d02_mJS4_ch09, measure 3 (L = 120 at 120 BPM), euler75
    rows (XYZ, float32 as stored): the keyframes the spec's independent script found."""
    from dancedata.compute.measures import measure_bounds
    from dancedata.compute.motion_representations import representations_from_axis_angle
    from dancedata.io.aist import read_motion
    from dancedata.io.aist_names import music_bpm, parse_sequence_name

    path = real_data / "aist" / "motions" / "gJS_sFM_cAll_d02_mJS4_ch09.pkl"
    motion = read_motion(path)
    euler = representations_from_axis_angle(motion.axis_angle, ("euler",), "XYZ")["euler"]
    x = np.concatenate([motion.trans_m, euler.reshape(len(euler), -1).astype(np.float32)], 1)
    bpm = music_bpm(parse_sequence_name(path.stem).music_id)
    start, stop = measure_bounds(motion.n_frames, bpm, 60.0)[3]
    assert stop - start == 120
    measure = x[start:stop]
    expected = {
        ("vertical", "max", 3): [0, 21, 119],
        ("vertical", "max", 5): [0, 6, 12, 15, 119],
        ("vertical", "max", 9): [0, 5, 7, 8, 13, 18, 97, 101, 119],
        ("vertical", "sum", 3): [0, 118, 119],
        ("vertical", "sum", 5): [0, 116, 117, 118, 119],
        ("vertical", "sum", 9): [0, *range(112, 120)],
        ("perpendicular", "max", 9): [0, 6, 7, 8, 14, 18, 87, 110, 119],
    }
    for (distance, combine, n), frames in expected.items():
        found, _ = dp_keyframes(measure, n, distance, combine)
        assert found.indices.tolist() == frames, (distance, combine, n)
