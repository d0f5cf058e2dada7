"""Segment lookup for keyframe tracks: ``searchsorted(times, t, 'right') - 1``
without a binary search over all K keys per query.

np.searchsorted's binary search mispredicts its branches on random queries;
the grid below answers with one multiply and a step or two (measured costs
in benchmarks/README.md).
"""

import numpy as np

__all__ = ["SegmentIndex"]


class SegmentIndex:
    """``find(t) == np.searchsorted(times, t, side='right') - 1`` for finite t.

    A uniform grid of cells over [t0, t_end] stores, per cell, the segment of
    its left edge; a query computes its cell with one multiply, then does at
    most `steps` (usually 1-2) vectorised bisection steps inside the cell's
    bracket.  The cell of a key and of a query are computed by the same
    float expression, and the function is monotone, so the brackets are
    exact (no tolerance).  Falls back to `np.searchsorted` when keys are so
    clustered that a bracket would need more than 4 steps.
    """

    MAX_STEPS = 4
    MIN_KEYS = 32   # below this a binary search is as cheap as the grid

    def __init__(self, times, min_keys=MIN_KEYS):
        self.times = times
        self.grid = None
        K = len(times)
        if K < min_keys:
            return
        span = float(times[-1] - times[0])
        best = None
        for cells in (2 * K, 4 * K, 8 * K, 16 * K):   # finer grids: fewer bisection steps
            if cells > 1 << 24:
                break
            with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
                scale = cells / span
                if not (np.isfinite(scale) and scale > 0):
                    break
                kc = np.floor((times - times[0]) * scale)
            if not np.isfinite(kc).all():
                break
            cmax = kc[-1]
            counts = np.bincount(kc.astype(np.intp), minlength=int(cmax) + 1)   # keys per cell
            steps = int(counts.max()).bit_length()
            if best is None or steps < best[3]:
                best = (scale, float(cmax), counts, steps)
            if steps <= 2:
                break
        if best is not None and best[3] <= self.MAX_STEPS:
            scale, cmax, counts, steps = best
            # lo[c] = (number of keys in cells before c) - 1: the segment of the
            # cell's left edge; the answer lies in [lo[c], lo[c] + counts[c]]
            lo = np.cumsum(counts) - counts - 1
            pad = np.full(K + (1 << steps) + 1, np.inf)
            pad[:K] = times
            self.grid = (float(times[0]), scale, cmax, lo.astype(np.intp), steps, pad)

    def find(self, t, out=None):
        if self.grid is None or t.size <= 64:
            return np.subtract(self.times.searchsorted(t, side="right"), 1, out=out)
        t0, scale, cmax, lo, steps, pad = self.grid
        c = np.subtract(t, t0)
        with np.errstate(over="ignore", invalid="ignore"):
            c *= scale
        np.clip(c, 0, cmax, out=c)
        i = np.take(lo, c.astype(np.intp), mode="clip", out=out)
        if steps:
            cand = np.empty_like(i)
            tv = np.empty(t.shape, np.float64)
            ok = np.empty(t.shape, bool)
            for k in range(steps - 1, -1, -1):  # bisection steps, not keys
                np.add(i, 1 << k, out=cand)
                np.take(pad, cand, mode="clip", out=tv)
                np.less_equal(tv, t, out=ok)
                if k:
                    i += ok * (1 << k)
                else:
                    i += ok
        return i

    def find_sorted(self, t):
        """`find` of all of `t` at once when `t` is non-decreasing, else None.

        For sorted queries the answer is a run of equal segments per key
        interval: the first query of each run is a binary search of the K
        key times into `t` (K log M), and the runs are written with one
        ``np.repeat`` (no per-query search).  Checking the order costs one
        comparison per query.
        """
        if t.ndim != 1 or t.size < 2 or not bool(np.all(t[1:] >= t[:-1])):
            return None
        starts = np.searchsorted(t, self.times, side="left")        # first query at or after each key
        counts = np.diff(starts, prepend=0, append=t.size)
        # int32 segment numbers where they fit: half the memory of a long query array's index
        kind = np.int32 if len(self.times) < 2 ** 31 - 1 else np.intp
        return np.repeat(np.arange(-1, len(self.times), dtype=kind), counts)
