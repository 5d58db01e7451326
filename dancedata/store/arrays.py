"""Frame-concatenated zarr arrays written in whole chunks by one streaming writer.

Sequences (and audio tracks) are concatenated along axis 0. A :class:`FrameArrayWriter` buffers
appended rows and writes each chunk exactly once, when it is full, so memory stays bounded by one
chunk per array however large the dataset, and no chunk is ever rewritten.

Every array is created by :func:`create_checked_array`: its codec chain ends with zarr v3's
standard ``crc32c`` codec (a CRC-32C of each compressed chunk, checked by every zarr v3 reader),
and it is written with ``write_empty_chunks`` so that every chunk of its grid exists as a file
and a missing one can be told from a chunk of zeros (see :mod:`dancedata.store.chunks`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    import zarr
    from zarr.core.array_spec import ArrayConfigParams

# Rows (frames) per chunk for every frame-concatenated array. One value for all arrays keeps
# chunk boundaries aligned across arrays, so a work unit "chunk k" touches the same frames
# everywhere. 8192 frames of (24, 3) float32 is 2.4 MB; of (24, 3, 3) float32, 7 MB.
CHUNK_FRAMES = 8192

# Write every chunk, even one equal to the fill value: an absent chunk then always means damage.
WRITE_CONFIG: ArrayConfigParams = {"write_empty_chunks": True}


# Blosc's block, in bytes: each chunk is cut into blocks of this size, shuffled and compressed
# one by one. Against Blosc's own choice at clevel 1, on the real AIST++ keypoints2d (one core,
# bench/bench_codecs.py): 16.9 % of raw against 19.4 %, encoded 1.6× and decoded 2.4× faster.
BLOSC_BLOCK_BYTES = 1 << 20


def default_compressor() -> Any:
    """The compressor of every array dancedata writes: Blosc with zstd level 1, byte shuffle
    and 1 MiB blocks (a standard Zarr v3 codec). Against zarr's default (zstd level 3 over the
    whole chunk) on float32 rotations, measured on one core (bench/bench_codecs.py): about 3×
    faster to encode, 1.4-1.8× faster to decode, and smaller (rotation matrices 74-76 % of raw
    against 91-92 %)."""
    from zarr.codecs import BloscCodec

    return BloscCodec(cname="zstd", clevel=1, shuffle="shuffle", blocksize=BLOSC_BLOCK_BYTES)


def checked_compressors(compressors: Any = "auto") -> list[Any]:
    """``compressors`` as zarr's ``create_array`` takes them, followed by the crc32c codec.

    "auto" means :func:`default_compressor`, spelled out so that stores do not change when
    zarr's default does.
    """
    from zarr.codecs import Crc32cCodec

    if compressors == "auto":
        chain: list[Any] = [default_compressor()]
    elif compressors is None:
        chain = []
    elif isinstance(compressors, (list, tuple)):
        chain = list(compressors)
    else:
        chain = [compressors]
    if not any(isinstance(c, Crc32cCodec) for c in chain):
        chain.append(Crc32cCodec())
    return chain


def create_checked_array(
    group: zarr.Group,
    path: str,
    *,
    shape: tuple[int, ...],
    chunks: tuple[int, ...],
    dtype: Any,
    compressors: Any = "auto",
    fill_value: Any = 0,
) -> zarr.Array:
    """A new array under ``group`` with the crc32c codec last and ``write_empty_chunks`` on
    (the returned object; reopen later ones with :func:`for_writing`)."""
    return group.create_array(
        path,
        shape=shape,
        chunks=chunks,
        dtype=dtype,
        fill_value=fill_value,
        overwrite=False,
        compressors=checked_compressors(compressors),
        config=WRITE_CONFIG,
    )


def for_writing(array: zarr.Array) -> zarr.Array:
    """``array`` set to write every chunk, fill-valued ones included (see WRITE_CONFIG)."""
    return array.with_config(WRITE_CONFIG)


class FrameArrayWriter:
    """Stream rows into a new zarr array named ``path`` under ``group``."""

    def __init__(
        self,
        group: zarr.Group,
        path: str,
        row_shape: tuple[int, ...],
        dtype: Any,
        *,
        attrs: dict[str, Any] | None = None,
        chunk_frames: int = CHUNK_FRAMES,
        compressors: Any = "auto",
        chunks_per_write: int = 1,
    ) -> None:
        """``compressors`` as zarr's ``create_array`` takes them ("auto":
        :func:`default_compressor`), the crc32c codec appended (:func:`checked_compressors`).
        ``chunks_per_write`` whole chunks are buffered and written in one call, which zarr
        compresses in parallel threads (memory: that many chunks per array)."""
        self.row_shape = tuple(row_shape)
        self.dtype = np.dtype(dtype)
        self.chunk_frames = chunk_frames
        self.chunks_per_write = max(1, chunks_per_write)
        self.array = create_checked_array(
            group,
            path,
            shape=(0, *self.row_shape),
            chunks=(chunk_frames, *self.row_shape),
            dtype=self.dtype,
            compressors=compressors,
        )
        if attrs:
            self.array.attrs.update(attrs)
        # Rows wait in one buffer of ``chunks_per_write`` chunks, allocated once and reused for
        # every write: a fresh one per write (tens of MB for keypoints2d) cost the kernel a
        # page fault and a zeroed page per 4 kB, about as much CPU as compressing the rows.
        self._rows = chunk_frames * self.chunks_per_write
        self._buffer: np.ndarray | None = None
        self._buffered = 0
        self.n_rows = 0

    def append(self, block: np.ndarray) -> None:
        """Append rows; shape (n, *row_shape). Full chunks are written immediately."""
        block = np.asarray(block, dtype=self.dtype)
        if block.shape[1:] != self.row_shape:
            raise ValueError(
                f"{self.array.path}: rows of shape {block.shape[1:]}, expected {self.row_shape}"
            )
        if block.shape[0] == 0:
            return
        if self._buffer is None:
            self._buffer = np.empty((self._rows, *self.row_shape), dtype=self.dtype)
        buffer = self._buffer
        done = 0
        while done < block.shape[0]:
            take = min(block.shape[0] - done, self._rows - self._buffered)
            buffer[self._buffered : self._buffered + take] = block[done : done + take]
            self._buffered += take
            done += take
            if self._buffered == self._rows:
                self._flush()

    def _flush(self) -> None:
        """Write the buffered rows (whole chunks, or the last partial one at close)."""
        if not self._buffered or self._buffer is None:
            return
        start, n = self.n_rows, self._buffered
        self.array.resize((start + n, *self.row_shape))
        self.array[start : start + n] = self._buffer[:n]
        self.n_rows += n
        self._buffered = 0

    def close(self) -> int:
        """Write the last partial chunk; returns the number of rows written."""
        self._flush()
        self._buffer = None
        return self.n_rows
