"""The content hash of inputs and store files against hashlib over the whole bytes at once."""

from __future__ import annotations

import hashlib
import io

import numpy as np
import pytest

from dancedata.store.checksums import sha256_file, sha256_handle

BLOCK = 1 << 20


class ReadOnly:
    """A binary file object with ``read`` only (no ``readinto``), as some wrappers are."""

    def __init__(self, data: bytes) -> None:
        self._inner = io.BytesIO(data)

    def read(self, size: int = -1) -> bytes:
        return self._inner.read(size)


@pytest.mark.parametrize("size", [0, 1, BLOCK - 1, BLOCK, BLOCK + 1, 3 * BLOCK + 17])
def test_sha256_matches_hashlib_at_block_edges(tmp_path, size):
    data = np.random.default_rng(size).integers(0, 256, size, dtype=np.uint8).tobytes()
    expected = hashlib.sha256(data).hexdigest()
    path = tmp_path / "blob"
    path.write_bytes(data)
    assert sha256_file(path) == expected
    assert sha256_handle(ReadOnly(data)) == expected
    with open(path, "rb") as handle:  # the bytes left: after a header already read
        handle.read(min(size, 5))
        assert sha256_handle(handle) == hashlib.sha256(data[5:]).hexdigest()
