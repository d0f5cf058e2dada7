"""quatarray.dask at a size CI affords: the same work in memory, on Dask's threads, and Zarr to Zarr.

The 10⁹-query run (16 GB out) is `benchmarks/dask_big.py`, run by hand.
Ratios to read: ``dask / memory`` (the cost of chunking and scheduling) and
``zarr / memory`` (plus reading and writing the stores).
"""

import os
import shutil
import tempfile

import numpy as np

from ._common import rng
from .tracks import make_track

PATHS = ["memory", "dask", "zarr"]
QUERIES = [100_000, 2_000_000]
KEYS = 10_000
#: Query times per chunk (the Zarr path picks its own, 2**21 quaternions).
CHUNK = 1 << 18


def _dask():
    try:
        import dask.array as da  # noqa: F401
        import zarr  # noqa: F401
    except ImportError:
        raise NotImplementedError("the dask extra is not installed") from None


class ChunkedTrack:
    """A squad track of 10⁴ float32 keys evaluated at M sorted query times."""

    params = (QUERIES, PATHS)
    param_names = ["queries", "path"]

    def setup(self, m, path):
        from quatarray.interpolate import Track
        if path != "memory":
            _dask()
        times, keys, t = make_track(KEYS, m, "float32")
        self.track = Track(times, keys, method="squad")
        self.t = t.astype(np.float64)
        if path == "dask":
            import dask.array as da
            self.td = da.from_array(self.t, chunks=CHUNK)
        if path == "zarr":
            import zarr
            self.folder = tempfile.mkdtemp()
            g = zarr.open_group(os.path.join(self.folder, "in.zarr"), mode="w")
            g["times"], g["keys"] = times, keys
            self.fps = (m - 1) / (times[-1] - times[0])

    def teardown(self, m, path):
        if path == "zarr":
            shutil.rmtree(self.folder, ignore_errors=True)

    def time_squad_track(self, m, path):
        """Evaluate the track at every query time (Zarr: store in, store out, float32)."""
        if path == "memory":
            self.track(self.t)
        elif path == "dask":
            from quatarray import dask as qd
            qd.evaluate(self.track, self.td).compute(scheduler="threads")
        else:
            from quatarray.formats import resample_zarr
            resample_zarr(os.path.join(self.folder, "in.zarr"), os.path.join(self.folder, "out.zarr"),
                          fps=self.fps, method="squad", progress=False, force=True)


class ChunkedReductions:
    """The chordal mean and unflip of N quaternions, in memory and as Dask reductions / scans."""

    params = ([100_000, 2_000_000], ["memory", "dask"])
    param_names = ["n", "path"]

    def setup(self, n, path):
        q = rng(61).normal(size=(n, 4))
        self.q = q / np.linalg.norm(q, axis=-1, keepdims=True)
        if path == "dask":
            _dask()
            import dask.array as da
            self.qd = da.from_array(self.q, chunks=(CHUNK, 4))

    def time_mean(self, n, path):
        """Chordal L2 mean of all N rotations (Dask: a 4x4 sum per chunk, tree-reduced)."""
        if path == "memory":
            from quatarray import Rotation
            Rotation(self.q).mean()
        else:
            from quatarray import dask as qd
            qd.mean(self.qd).compute(scheduler="threads")

    def time_unflip(self, n, path):
        """Sign continuity along the N quaternions (Dask: per chunk, then a carry across chunks)."""
        if path == "memory":
            from quatarray.interpolate import unflip
            unflip(self.q)
        else:
            from quatarray import dask as qd
            qd.unflip(self.qd).compute(scheduler="threads")
