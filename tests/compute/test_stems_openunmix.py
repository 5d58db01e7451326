"""The ``openunmix`` backend end to end: real OpenUnmix models and Separator, weights on disk.

No pretrained weights exist offline, so the tests save small OpenUnmix models whose outputs are
known: with ``output_scale = 0`` the network's spectrogram for stem j is c_j · |X| whatever the
input. Without EM (niter 0) the Wiener stage then returns c_j · X, so stem j = c_j · y; with one EM
step it re-weights by power, stem j = c_j² / Σ c² · y. Any mix-up of file → stem, chunk blending,
resampling or channel handling breaks these equalities.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dancedata.compute.stems import STEM_NAMES
from dancedata.compute.stems import openunmix as umx
from dancedata.errors import DancedataError, InputError
from dancedata.featurize.stem_separation import separate
from dancedata.io import openunmix_model as umxio
from dancedata.io import openunmix_weights as umxw
from tests.helpers import importorskip_unless_ci

# slow: OpenUnmix (torch) source separation
pytestmark = pytest.mark.slow

torch = importorskip_unless_ci("torch")
importorskip_unless_ci("openunmix")

SR = 30720
SCALE = {"drums": 0.4, "bass": 0.3, "vocals": 0.2, "other": 0.1}


def _save_models(folder: Path, names: dict[str, str], scale: dict[str, float]) -> None:
    from openunmix.model import OpenUnmix

    folder.mkdir(parents=True, exist_ok=True)
    for stem, file_name in names.items():
        model = OpenUnmix(nb_bins=257, nb_channels=2, hidden_size=16, nb_layers=1, max_bin=128)
        with torch.no_grad():
            model.output_scale.zero_()
            model.output_mean.fill_(scale[stem])
        torch.save(model.state_dict(), folder / file_name)


@pytest.fixture(scope="module")
def weights_dir(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("umx_weights")
    _save_models(root / "umxhq", umxw.MODELS["umxhq"]["files"], SCALE)
    return root


def _music(seconds: float, sr: int = SR) -> np.ndarray:
    """Band-limited test signal (< 4 kHz), so resampling to 44.1 kHz and back is near lossless."""
    t = np.arange(int(seconds * sr)) / sr
    y = (
        0.3 * np.sin(2 * np.pi * 220 * t) * np.sin(2 * np.pi * 1.3 * t)
        + 0.2 * np.sin(2 * np.pi * 3100 * t + 3 * np.sin(2 * np.pi * 2 * t))
        + 0.1 * np.sin(2 * np.pi * 90 * t) * (np.sin(2 * np.pi * 2 * t) > 0)
    )
    return y.astype(np.float32)


@pytest.mark.parametrize("chunk_seconds", [30.0, 1.0])
def test_ratio_masks_give_known_stems(weights_dir, chunk_seconds) -> None:
    y = _music(3.0)
    stems = separate(
        y,
        SR,
        backend="openunmix",
        weights_dir=weights_dir,
        niter=0,
        chunk_seconds=chunk_seconds,
        overlap_seconds=0.25,
    )
    assert tuple(stems) == STEM_NAMES
    for name, stem in stems.items():
        assert stem.shape == y.shape and stem.dtype == np.float32
        np.testing.assert_allclose(stem, SCALE[name] * y, atol=0.01 * SCALE[name])


def test_one_em_step_reweights_by_power(weights_dir) -> None:
    y = _music(2.0)
    stems = separate(y, SR, backend="openunmix", weights_dir=weights_dir, niter=1)
    power = sum(c * c for c in SCALE.values())
    for name, stem in stems.items():
        gain = float(np.dot(stem, y) / np.dot(y, y))
        assert gain == pytest.approx(SCALE[name] ** 2 / power, rel=0.02)
    # The EM step's regulariser loses a little where the duplicated-mono spatial covariance is
    # singular (about 3 % RMS here); the mixture is otherwise preserved.
    residual = np.sum(list(stems.values()), axis=0) - y
    assert np.sqrt(np.mean(residual**2)) < 0.05 * np.sqrt(np.mean(y**2))


def test_stereo_input_is_separated_and_averaged(weights_dir) -> None:
    y = _music(1.5)
    stereo = np.stack([y, 0.5 * y])
    stems = separate(stereo, SR, backend="openunmix", weights_dir=weights_dir, niter=0)
    np.testing.assert_allclose(stems["drums"], 0.4 * 0.75 * y, atol=0.005)


def test_very_short_input_still_separates(weights_dir) -> None:
    y = _music(0.01)  # 307 samples: shorter than the model's n_fft at 44.1 kHz
    stems = separate(y, SR, backend="openunmix", weights_dir=weights_dir, niter=0)
    assert all(s.shape == y.shape for s in stems.values())


def test_flat_and_per_stem_file_layouts_are_found(tmp_path) -> None:
    flat = tmp_path / "flat"
    _save_models(flat, umxw.MODELS["umxl"]["files"], SCALE)
    assert umxw.find_weights("umxl", flat) == {
        stem: flat / umxw.MODELS["umxl"]["files"][stem] for stem in STEM_NAMES
    }
    named = tmp_path / "named"
    _save_models(named / "umxhq", {stem: f"{stem}.pth" for stem in STEM_NAMES}, SCALE)
    found = umxw.find_weights("umxhq", named)
    assert found["vocals"] == named / "umxhq" / "vocals.pth"


def test_torch_hub_cache_is_searched(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("TORCH_HOME", str(tmp_path))
    checkpoints = tmp_path / "hub" / "checkpoints"
    _save_models(checkpoints, umxw.MODELS["umxhq"]["files"], SCALE)
    assert umxw.hub_checkpoint_dir() == checkpoints
    found = umxw.find_weights("umxhq", None)
    assert found["bass"] == checkpoints / umxw.MODELS["umxhq"]["files"]["bass"]


def test_missing_weights_name_every_file_url_and_folder(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("TORCH_HOME", str(tmp_path / "torch"))
    (tmp_path / "w" / "umxhq").mkdir(parents=True)
    _save_models(tmp_path / "w" / "umxhq", {"drums": "drums-9619578f.pth"}, SCALE)
    with pytest.raises(InputError) as err:
        separate(np.zeros(1000), SR, backend="openunmix", weights_dir=tmp_path / "w")
    text = str(err.value)
    listed = text.split("missing: ")[1].split(". Nothing")[0].split(", ")
    files = umxw.MODELS["umxhq"]["files"]
    assert sorted(listed) == sorted(files[stem] for stem in ("bass", "other", "vocals"))
    assert "https://zenodo.org/records/3370489/files/" in text
    assert str(tmp_path / "w" / "umxhq") in text
    assert str(tmp_path / "torch" / "hub" / "checkpoints") in text


def test_unknown_model_missing_folder_and_bad_weight_file(tmp_path) -> None:
    with pytest.raises(InputError, match="unknown OpenUnmix model"):
        umxw.find_weights("umx-huge", tmp_path)
    with pytest.raises(InputError, match="folder does not exist"):
        umxw.find_weights("umxhq", tmp_path / "nowhere")
    folder = tmp_path / "umxhq"
    _save_models(folder, umxw.MODELS["umxhq"]["files"], SCALE)
    torch.save({"just": torch.zeros(3)}, folder / umxw.MODELS["umxhq"]["files"]["other"])
    with pytest.raises(InputError, match="not an OpenUnmix state dict") as err:
        umxio.load_separator("umxhq", tmp_path)
    assert err.value.path.endswith(umxw.MODELS["umxhq"]["files"]["other"])


def test_missing_extra_is_one_clear_error(monkeypatch) -> None:
    import sys

    monkeypatch.setitem(sys.modules, "openunmix.model", None)
    with pytest.raises(DancedataError, match=r"dancedata\[stems\]"):
        umxw.hub_checkpoint_dir()


@settings(max_examples=200, deadline=None)
@given(
    n=st.integers(1, 5000),
    chunk=st.integers(2, 800),
    overlap_frac=st.floats(0.0, 0.95),
)
def test_chunks_cover_the_signal_with_the_overlap(n, chunk, overlap_frac) -> None:
    overlap = int(overlap_frac * (chunk - 1))
    bounds = umx.chunk_bounds(n, chunk, overlap)
    assert bounds[0][0] == 0 and bounds[-1][1] == n
    for (s0, e0), (s1, e1) in zip(bounds, bounds[1:], strict=False):
        assert e0 - s0 == chunk and e1 - s1 == chunk
        assert s0 < s1 and e0 - s1 >= overlap
    weights = np.zeros(n)
    for i, (start, stop) in enumerate(bounds):
        w = umx.crossfade_weights(stop - start, overlap, i == 0, i == len(bounds) - 1)
        assert np.all(w > 0)
        weights[start:stop] += w
    assert np.all(weights > 0)


def test_non_finite_em_step_falls_back_to_ratio_masks(tmp_path) -> None:
    """Duplicated-mono input with channel-symmetric estimates makes the EM step's covariances
    singular; where that gives inf/NaN the chunk is redone without EM, with a warning."""
    scale = {**SCALE, "drums": 0.9}
    _save_models(tmp_path / "umxhq", umxw.MODELS["umxhq"]["files"], scale)
    t = np.arange(int(1.5 * SR)) / SR
    rng = np.random.default_rng(4)
    y = (0.5 * np.sin(2 * np.pi * 60 * t) + 0.3 * rng.standard_normal(t.size)).astype(np.float32)
    y[: SR // 2] = 0.0  # digital silence: zero mixture power in every bin
    with pytest.warns(RuntimeWarning, match="non-finite"):
        stems = separate(y, SR, backend="openunmix", weights_dir=tmp_path, niter=1)
    plain = separate(y, SR, backend="openunmix", weights_dir=tmp_path, niter=0)
    for name in STEM_NAMES:
        assert np.all(np.isfinite(stems[name]))
        np.testing.assert_array_equal(stems[name], plain[name])


def test_compute_runs_a_separator_loaded_by_io_once(weights_dir) -> None:
    """compute does no IO: the dispatcher takes a separator loaded by io (cached per process per
    weight files and settings) and refuses the options that would load one."""
    from dancedata.compute import stems

    first = umxio.load_separator("umxhq", weights_dir, niter=0)
    assert umxio.load_separator("umxhq", weights_dir, niter=0) is first
    y = _music(2.0)
    direct = stems.separate(y, SR, backend="openunmix", separator=first)
    loaded = separate(y, SR, backend="openunmix", weights_dir=weights_dir, niter=0)
    for name in STEM_NAMES:
        np.testing.assert_array_equal(direct[name], loaded[name])
    with pytest.raises(InputError, match=r"loaded separator.*\(not niter, weights_dir\)"):
        stems.separate(y, SR, backend="openunmix", weights_dir=weights_dir, niter=0)
    with pytest.raises(InputError, match="takes no separator"):
        stems.separate(y, SR, backend="offline", separator=first)
