"""The fuzz harness (fuzz/run.py, `make fuzz`) works, and every target passes a few examples:
hostile pickles, OpenPose folders, split files, BVH and measure settings, in the normal suite."""

from __future__ import annotations

import pytest

from fuzz.run import Stats, main, run_chunk
from fuzz.targets import TARGETS


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(TARGETS))
def test_each_fuzz_target_passes_a_short_chunk(name):
    stats = Stats()
    failure = run_chunk(TARGETS[name], 30, chunk_seed=1234, stats=stats)
    assert failure is None, failure
    assert stats.examples >= 30


def test_runner_prints_statistics_and_exits_zero(capsys):
    assert main(["--seconds", "1", "--targets", "measures,split_list", "--chunk", "20"]) == 0
    out = capsys.readouterr().out
    assert "examples" in out and "failures" in out
    assert out.strip().splitlines()[-1].startswith("total")
