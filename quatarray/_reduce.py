"""Raw keyframe reduction: keep few samples of rotation tracks such that the curve
through them stays within an angular tolerance of every sample.

Samples are unit, unflipped quaternions at times (T,): ``Q`` of shape (T, B, 4)
when all tracks share their keys, and track-major (B, T, 4) when each track is
reduced on its own (its samples then lie next to each other in memory: the
gathers of a track's samples stay in cache).
The result is, per track (or for all tracks at once with `shared`), the
sorted indices of the samples kept as keys; `reduce` also returns the curve's
maximum angular error at every original time, measured on the very `Track`s
the caller gets back.

Algorithm.  Greedy farthest reach: from a key s, the next key is the farthest
sample c such that the segment [s, c], evaluated with the method's own
kernels at the samples in between, stays within the tolerance.  The search
starts at the previous segment's length and tests its neighbour next (lengths
change slowly: most reaches are bracketed by these two tests), then gallops
or bisects guided by the error's growth.  A candidate's curve is evaluated
by `Track`'s own table rows and kernel (`_track.frame_rows`,
`_track.rotation_block`), so the search and the final check run one
formula.  For 'linear' and
'slerp' a segment depends on its two keys only, so that test is exact.
squad's control points also depend on the neighbouring keys: the test takes
the previous key and guesses the next one (the sample after the candidate), and
the final check (on the returned tracks) repairs what the guess got wrong.

To run without a Python loop over samples, every track is cut into chunks of
`CHUNK` samples, and all (track, chunk) lanes advance in lock step: one
iteration tests one candidate segment per lane, all evaluated in one batch.
Chunk boundaries are forced keys at first; rounds of merges then drop those
the neighbouring segments do not need.

The check.  The kept keys are made into `Track`s, evaluated through their own
call at every original time (in blocks of `CHECK` times), and compared with
the samples; where a segment exceeds the tolerance its worst sample becomes a
key and the times whose segments changed are evaluated again, until none
exceeds it (keeping every sample reproduces every sample, so this ends).
"""

import numpy as np

from . import _blocks
from . import _convert
from . import _interp_curves
from . import _interp_kernels
from . import _kernels
from . import _track

__all__ = ["METHODS", "CHUNK", "angle_between", "greedy", "refine", "reduce"]

METHODS = ("linear", "slerp", "squad")
#: Samples per lane of the lock-step greedy search.
CHUNK = 2048
#: Interior samples evaluated per batch (bounds the temporaries).
BATCH = 1 << 14
#: Segments handled per call of `segment_errors` (bounds the per-segment tables and
#: control points when the check revisits every segment of every track at once).
SEGMENTS = 1 << 15
#: Samples per block of the final check (the returned tracks evaluated at the original times).
CHECK = 1 << 16


def angle_between(p, q):
    """Angle in [0, π] of the rotation from p to q, ``|q p*|``, for (..., 4) arrays (broadcasting)."""
    return _convert.magnitude(_kernels.multiply(q, _kernels.conjugate(p)))


def _unique(x):
    """Sorted distinct values of an int array (a sort: NumPy's hash-based unique is slower here)."""
    x = np.sort(x)
    return x[np.concatenate([[True], x[1:] != x[:-1]])] if x.size else x


def _without(x, drop):
    """Sorted x without the values `drop` (all of them in x)."""
    keep = np.ones(len(x), bool)
    keep[np.searchsorted(x, drop)] = False
    return x[keep]


def _chord2(p, q, work):
    """Squared distance from unit p to the nearer of ±q: the search's test, per sample.

    p, q of shape (4, *s), components first; the result (s) is a view into
    `work` (the caller's scratch frame).  A monotone function of the angle θ
    between the rotations (4 sin²(θ/4)), exact for small angles and cheaper
    than the angle itself, which is formed from it only once per segment.
    """
    s = p.shape[1:]
    D = work.rows(4, s, p.dtype)
    a = work.rows(1, s, p.dtype)[0]
    np.subtract(p, q, out=D)
    _interp_kernels.sqsum(D, a)
    # |p - q|² + |p + q|² = 4: only where |p - q|² > 1 can |p + q|² be the smaller
    far = np.flatnonzero(a > 1)
    if far.size:
        at = np.unravel_index(far, s)
        P, Q = p[(slice(None),) + at], q[(slice(None),) + at]
        np.add(P, Q, out=P)
        flat = a.reshape(-1)
        flat[far] = np.minimum(flat[far], _interp_kernels.sqsum(P, np.empty(far.size, p.dtype)))
    return a


def _hemisphere(ref, q):
    """q with its sign flipped where it points away from `ref` (shape (..., 4) both)."""
    flip = _interp_kernels.vdot(ref, q) < 0
    q = q.copy()
    q[flip] *= -1   # the few flipped ones (a select over every component costs more)
    return q


def _controls(Q, times, p, s, c, n, b, first, last):
    """squad control points at keys s and c of segments whose neighbouring keys are p
    (before s) and n (after c), each -1 where not known yet (then the neighbouring
    sample stands in: a short chord is the better guess of the tangent): the keys
    and control points (m, X, 4).  `b` is the track (None: all)."""
    T = len(times)
    n = np.where(n < 0, np.minimum(c + 1, T - 1), n)
    pp = np.where(p < 0, np.maximum(s - 1, 0), p)
    qp, qs, qc, qn = (_take(Q, k, b) for k in (pp, s, c, n))
    qp, qc = _hemisphere(qs, qp), _hemisphere(qs, qc)
    qn = _hemisphere(qc, qn)
    tp = np.where(pp == s, times[s] - (times[c] - times[s]), times[pp])
    tn = np.where(n == c, times[c] + (times[c] - times[s]), times[n])
    ts, tc = times[s], times[c]
    # one call for both: a key's control point depends on its two neighbours only
    a_s, a_c = _interp_curves.squad_controls(np.stack([qp, qs, qc, qn]), np.stack([tp, ts, tc, tn]), ends=False)
    # the track's ends: the control point is the key itself (squad_controls' reflection)
    a_s[s == first] = qs[s == first]
    a_c[c == last] = qc[c == last]
    return qs, qc, a_s.astype(Q.dtype, copy=False), a_c.astype(Q.dtype, copy=False)


def _back_controls(Q, p, ctl, rows, a_p, b):
    """The keys and control points of the segments [p, s] (`_controls` with neighbours
    p's predecessor and c) from those of the segments [s, c] `ctl` (their `rows`) and
    the control points a_p at p: s's control point depends on p, s and c only; taken on
    the side of p's key, its neighbours flip with it, which negates it exactly."""
    qp, qs = _take(Q, p, b), ctl[0][rows]
    a_s = ctl[2][rows]
    a_s[_interp_kernels.vdot(qp, qs) < 0] *= -1
    return qp, qs, a_p, a_s


def _take(Q, k, b):
    """Samples k of tracks b (m, 1, 4) from track-major Q (B, T, 4), or of all tracks
    (m, B, 4) from Q (T, B, 4) when b is None."""
    # np.take: several times faster than fancy indexing for gathering rows
    if b is None:
        return np.take(Q, k, axis=0)
    return np.take(Q.reshape(-1, 4), b * Q.shape[1] + k, axis=0)[:, None]


def _components(x):
    """(m, b, 4) -> C-contiguous float64 (4, m, b)."""
    return np.ascontiguousarray(np.moveaxis(x, -1, 0), dtype=np.float64)


def _segment_table(method, qs, qc, a_s=None, a_c=None, dtype=np.float64):
    """The `Track` table rows (R, m + 1, b) of the segments from keys qs to qc (m, b, 4)
    (squad: with control points a_s, a_c), qc taken on the side of qs as a `Track`
    through them takes it: the curve is evaluated by `Track`'s own kernel."""
    k0, k1 = _components(qs), _components(_hemisphere(qs, qc))
    if method == "linear":
        table = np.concatenate([k0, k1])
        table = np.concatenate([table, table[:, -1:]], axis=1)
    elif method == "slerp":
        table = _track.frame_rows([(k0, k1)], k1[:, -1])
    else:
        table = _track.frame_rows([(k0, k1), (_components(a_s), _components(a_c))], k1[:, -1])
    return np.ascontiguousarray(table, dtype=dtype)


def _table_errors(method, G, u, X):
    """Per sample (n,), the squared chord (`_chord2`, max over tracks) between samples
    X (n, b, 4) and the curve of their segments' table rows G (R, n, b) (overwritten)
    at parameters u (n,)."""
    n, b = X.shape[:2]
    with _blocks.scratch().frame() as work:
        O = work.rows(4, (n, b), G.dtype)
        _track.rotation_block(method, G, u[:, None], O)
        err = _chord2(O, np.moveaxis(X, -1, 0), work)
        # (one track: a copy out of the scratch; NumPy's max over an axis of length 1 is slow)
        return err[:, 0].copy() if b == 1 else err.max(axis=1)


def segment_errors(method, times, Q, s, c, p=None, n=None, b=None, locate=True, controls=None):
    """Largest angular error, shape (m,), of the segments [s, c] (m,) at the samples
    strictly inside them, of track b (m,) or of all tracks (b None: max over tracks),
    and the sample where it occurs (s where there is none, or everywhere if not
    `locate`: the search needs the errors only).  p, n (m,) are the keys before s
    and after c (-1: not known) for 'squad'; or `controls`, the keys and control
    points (qs, qc, a_s, a_c) of `_controls` already at hand."""
    m = len(s)
    if m > SEGMENTS:   # in groups: each segment's error is its own, whatever the group
        def part(x, i):
            return None if x is None else x[i:i + SEGMENTS]

        parts = [segment_errors(method, times, Q, s[i:i + SEGMENTS], c[i:i + SEGMENTS], part(p, i), part(n, i),
                                part(b, i), locate, None if controls is None else [part(x, i) for x in controls])
                 for i in range(0, m, SEGMENTS)]
        return np.concatenate([e for e, _ in parts]), np.concatenate([w for _, w in parts])
    inner = c - s - 1
    out = np.zeros(m)
    where = s.copy()
    if m == 0 or inner.sum() == 0:
        return out, where
    if controls is not None:
        qs, qc, a_s, a_c = controls
    elif method == "squad":
        first, last = 0, len(times) - 1
        unknown = np.full(m, -1)
        qs, qc, a_s, a_c = _controls(Q, times, unknown if p is None else p, s, c, unknown if n is None else n,
                                     b, first, last)
    else:
        qs, qc = _take(Q, s, b), _take(Q, c, b)
    table = _segment_table(method, qs, qc, *((a_s, a_c) if method == "squad" else ()), dtype=Q.dtype)
    # the segments in batches of about BATCH interior samples (whole segments per batch)
    per = inner * (1 if b is not None else Q.shape[1])   # (shared: B tracks per sample)
    ends = np.cumsum(per)
    if ends[-1] <= BATCH:
        bounds = [0, m]
    else:
        cuts = np.searchsorted(ends, np.arange(BATCH, ends[-1], BATCH), side="left") + 1
        bounds = np.concatenate([[0], cuts[cuts < m], [m]])
        bounds = bounds[np.concatenate([[True], np.diff(bounds) > 0])]
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        lo, hi = int(lo), int(hi)
        n_in = inner[lo:hi]
        tot = int(n_in.sum())
        if tot == 0:
            continue
        starts = np.cumsum(n_in) - n_in
        base = s[lo:hi] + 1 - starts                 # k = base + position in the batch
        k = np.arange(tot) + np.repeat(base, n_in)
        t0 = times[s[lo:hi]]
        u = np.take(times, k) - np.repeat(t0, n_in)
        u /= np.repeat(times[c[lo:hi]] - t0, n_in)
        if b is None:
            X = np.take(Q, k, axis=0)
        else:   # the samples' rows in the track-major array, gathered at once
            X = np.take(Q.reshape(-1, 4), np.arange(tot) + np.repeat(base + b[lo:hi] * Q.shape[1], n_in), axis=0)
            X = X[:, None]
        # each segment's rows repeated for its samples (a repeat along rows: faster than a take)
        G = np.repeat(table[:, lo:hi], n_in, axis=1)
        err = _table_errors(method, G, u.astype(Q.dtype, copy=False), X)
        nz = n_in > 0
        worst = np.maximum.reduceat(err, starts[nz])
        out[lo:hi][nz] = 4 * np.arcsin(np.sqrt(worst) / 2)
        if not locate:
            continue
        hit = np.flatnonzero(err == np.repeat(worst, n_in[nz]))
        seg = np.repeat(np.arange(lo, hi), n_in)
        first_hit = hit[np.concatenate([[True], seg[hit][1:] != seg[hit][:-1]])]
        where[seg[first_hit]] = k[first_hit]
    return out, where


def greedy(method, times, Q, tol, shared, chunk=CHUNK):
    """Kept sample indices: a list of B sorted index arrays, or one with `shared`."""
    T, B = (Q.shape[0], Q.shape[1]) if shared else (Q.shape[1], Q.shape[0])
    tracks = [None] if shared else list(range(B))
    nch = max(1, -(-(T - 1) // chunk))
    bounds = np.minimum(np.arange(nch + 1) * chunk, T - 1)
    lane_b = np.repeat(np.arange(len(tracks)), nch)
    a = np.tile(bounds[:-1], len(tracks))
    e = np.tile(bounds[1:], len(tracks))
    s = a.copy()
    lo = s + 1
    hi = np.full_like(s, -1)
    guess = np.full_like(s, 8)
    prev = np.full_like(s, -1)
    pprev = np.full_like(s, -1)
    last_len = np.ones(len(s))
    last_err = np.zeros(len(s))
    bisect = np.zeros(len(s), bool)
    tests = np.zeros_like(s)
    order = 4 if method == "squad" else 2
    found = [a, e]
    active = s < e
    if method == "squad":
        # per lane, the control point at `prev` of the segment [prev, s] (fixed while the lane
        # searches for s's successor: its back tests need no control points of their own), and
        # that at s of the last passing candidate (the former once that candidate is committed)
        a_prev = np.zeros((len(s), 1 if not shared else Q.shape[1], 4), Q.dtype)
        a_lo = np.zeros_like(a_prev)
        have_lo = np.zeros(len(s), bool)
    while True:
        # the lanes' state is updated with masks over all lanes (elementwise: most lanes
        # take part in every step, where fancy indexing per array costs several times more)
        commit = active & (((hi < 0) & (lo >= e)) | ((hi >= 0) & (hi - lo <= 1)))
        if commit.any():
            done = np.flatnonzero(commit)
            found.append(lane_b[done] * T + lo[done] if not shared else lo[done])
            np.copyto(guess, lo - s, where=commit)
            np.copyto(pprev, prev, where=commit)
            np.copyto(prev, s, where=commit)
            np.copyto(s, lo, where=commit)
            np.copyto(lo, s + 1, where=commit)
            np.copyto(hi, -1, where=commit)
            bisect &= ~commit
            np.copyto(tests, 0, where=commit)
            active &= s < e
            if method == "squad":
                kept_a = np.flatnonzero(commit & have_lo)
                a_prev[kept_a] = a_lo[kept_a]
                # (a reach of one sample, committed untested: its control point computed here)
                miss = np.flatnonzero(commit & ~have_lo & active & (prev >= 0))
                if miss.size:
                    a_prev[miss] = _controls(Q, times, pprev[miss], prev[miss], s[miss], np.full(miss.size, -1),
                                             None if shared else lane_b[miss], 0, T - 1)[2]
                have_lo &= ~commit
        if not active.any():
            break
        # next candidate end: the error of the last test predicts the length where it
        # reaches tol (it grows like length^order); in a bracket, every other step bisects
        with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
            pred = np.floor(last_len * (tol / last_err) ** (1 / order) * 0.98)
        pred = np.nan_to_num(pred, nan=0, posinf=1e18).astype(np.int64, copy=False)
        fresh = lo == s + 1
        gallop = np.minimum(np.clip(s + pred, lo + 1, 4 * lo - 3 * s), e)
        gallop = np.where(fresh, np.minimum(np.maximum(s + guess, lo + 1), e), gallop)
        bracket = np.where(bisect, (lo + hi) // 2, np.clip(s + pred, lo + 1, hi - 1))
        cand = np.where(hi < 0, gallop, bracket)
        # the second test sits next to the first (the previous segment's length):
        # lengths change slowly, so it mostly brackets the reach at once
        cand = np.where(tests == 1, np.where(hi < 0, np.minimum(lo + 1, e), hi - 1), cand)
        tested = active & (cand > lo)
        test = np.flatnonzero(tested)
        if test.size == 0:
            continue
        c = cand[test]
        tb = None if shared else lane_b[test]
        if method != "squad":   # (the keys around a segment matter to squad only)
            err, _ = segment_errors(method, times, Q, s[test], c, None, None, tb, False)
        else:
            # squad: the candidate also sets the previous segment's end control point, so
            # that segment is tested again with it (and its own previous key) where the
            # candidate's own segment passes (where it fails, the candidate does anyway)
            P, S = prev[test], s[test]
            ctl = _controls(Q, times, P, S, c, np.full(c.size, -1), tb, 0, T - 1)
            err, _ = segment_errors(method, times, Q, S, c, b=tb, locate=False, controls=ctl)
            ok = err <= tol
            a_lo[test[ok]] = ctl[2][ok]
            have_lo[test[ok]] = True
            back = np.flatnonzero((P >= 0) & ok)
            if back.size:
                # [prev, s]'s control points: the lane's a_prev, and the candidate's at s, on the
                # side of prev's key as `_controls` puts it there (its neighbours flipped with
                # it: the same control point negated, exactly)
                tbb = None if shared else tb[back]
                e_back, _ = segment_errors(method, times, Q, P[back], S[back], b=tbb, locate=False,
                                           controls=_back_controls(Q, P[back], ctl, back, a_prev[test[back]], tbb))
                err[back] = np.maximum(err[back], e_back)
        passed = np.zeros(len(s), bool)
        passed[test] = err <= tol
        np.copyto(lo, cand, where=passed)
        np.copyto(hi, cand, where=tested & ~passed)
        np.copyto(last_len, cand - s, where=tested)
        last_err[test] = err
        np.copyto(bisect, ~bisect & (hi >= 0), where=tested)
        tests += tested
    if shared:
        kept = [_unique(np.concatenate([found[0], found[1]] + found[2:]))]
    else:
        first = [lane_b * T + found[0], lane_b * T + found[1]]
        flat = _unique(np.concatenate(first + found[2:]))
        kept = np.split(flat % T, np.searchsorted(flat, np.arange(1, B) * T))
    kept = [_merge(method, times, Q, k, tol, None if shared else j, bounds[1:-1]) for j, k in enumerate(kept)]
    # (squad's segments, searched with guessed neighbours, are checked with their actual ones by
    # `refine`, on the returned tracks: a check here first added the same keys, one more pass)
    return kept


def _merge(method, times, Q, kept, tol, b, forced):
    """Drop the forced chunk boundaries that the segments around them do not need."""
    at = np.minimum(np.searchsorted(kept, forced), len(kept) - 1)
    forced = forced[kept[at] == forced]
    for _ in range(64):
        changed = False
        for parity in (0, 1):
            pos = np.searchsorted(kept, forced)
            pos = pos[(np.arange(len(pos)) % 2 == parity)]
            pos = pos[(pos > 0) & (pos < len(kept) - 1)]
            if pos.size == 0:
                continue
            prev = np.where(pos >= 2, kept[np.maximum(pos - 2, 0)], -1)
            nxt = np.where(pos + 2 < len(kept), kept[np.minimum(pos + 2, len(kept) - 1)], -1)
            err, _ = segment_errors(method, times, Q, kept[pos - 1], kept[pos + 1], prev, nxt,
                                    None if b is None else np.full(len(pos), b), False)
            drop = kept[pos[err <= tol]]
            if drop.size:
                kept = _without(kept, drop)
                forced = _without(forced, drop)
                changed = True
        if not changed:
            break
    return kept


def _chord_to_angle(c2):
    """The angle 4 arcsin(|p - q| / 2) of a squared chord `_chord2` (float64)."""
    return 4 * np.arcsin(np.sqrt(c2) / 2)


def _track_chords(track, times, ref, at=None):
    """Blocks (m, X) of squared chords (`_chord2`, float64) between `track` at the times
    `times[at]` (default: all) and the samples `ref` (T, X, 4) there: the track's own
    call, in blocks of `CHECK` samples (no output of the whole length)."""
    rows = max(1, CHECK // ref.shape[1])
    for lo in range(0, len(times) if at is None else len(at), rows):
        k = slice(lo, lo + rows) if at is None else at[lo:lo + rows]
        tk = times[k]
        q = np.asarray(track(tk)).reshape(len(tk), -1, 4).astype(np.float64, copy=False)
        r = (ref[k] if at is None else np.take(ref, k, axis=0)).astype(np.float64, copy=False)
        d = q - r
        c2 = _interp_kernels.vdot(d, d)
        far = np.nonzero(c2 > 1)   # the other sign can be nearer only there (see `_chord2`)
        if far[0].size:
            d = q[far] + r[far]
            c2[far] = np.minimum(c2[far], _interp_kernels.vdot(d, d))
        yield c2


def check_errors(track, times, ref, at=None):
    """Per time (max over tracks), the squared chords of `_track_chords`."""
    blocks = [c2.max(axis=1) if c2.shape[1] > 1 else c2[:, 0] for c2 in _track_chords(track, times, ref, at)]
    return np.concatenate(blocks) if blocks else np.zeros(0)


def track_errors(track, times, ref):
    """Largest angle per track (X,) between `track` at `times` and the samples `ref` (T, X, 4)."""
    worst = np.zeros(ref.shape[1])
    for c2 in _track_chords(track, times, ref):
        np.maximum(worst, c2.max(axis=0), out=worst)
    return _chord_to_angle(worst)


def refine(method, times, kept, tol, make_track, ref):
    """Add keys until the track of `kept` is within `tol` of `ref` (T, X, 4) at every time.

    Per segment over tolerance its worst sample becomes a key; then only the
    times whose segment may have changed are evaluated again (squad: two
    segments on either side of a new key, whose control points moved).
    Returns the kept indices, their track and its largest error (angle).
    """
    T = len(times)
    track = make_track(kept)
    c2 = check_errors(track, times, ref)
    reach = 2 if method == "squad" else 1
    while True:
        worst = np.maximum.reduceat(c2, kept[:-1])   # per segment (the last key joins the last one)
        err = _chord_to_angle(worst)
        bad = np.flatnonzero(err > tol)
        if bad.size == 0 or len(kept) == T:
            return kept, track, float(err.max())
        # the first worst sample of each bad segment (the samples of bad segments only)
        start, n = kept[bad], np.append(kept[1:-1], T)[bad] - kept[bad]
        first = np.cumsum(n) - n
        k = np.arange(n.sum()) - np.repeat(first - start, n)
        hit = np.flatnonzero(c2[k] == np.repeat(worst[bad], n))
        seg = np.searchsorted(first, hit, side="right")
        add = k[hit[np.concatenate([[True], seg[1:] != seg[:-1]])]]
        kept = _unique(np.concatenate([kept, add]))
        track = make_track(kept)
        pos = np.searchsorted(kept, add)
        lo = kept[np.maximum(pos - reach, 0)]
        hi = kept[np.minimum(pos + reach, len(kept) - 1)]
        dirty = np.zeros(T + 1, np.int64)
        np.add.at(dirty, lo, 1)
        np.add.at(dirty, hi + 1, -1)
        at = np.flatnonzero(np.cumsum(dirty[:-1]) > 0)
        c2[at] = check_errors(track, times, ref, at)


def _track_groups(B, T):
    """Slices (b0, b1) of tracks reduced together, one per thread of the pool (more
    slices are slower: every slice's search pays the lock-step's per-step costs)."""
    threads = _blocks.get_num_threads() if B * T >= _blocks.PARALLEL_MIN else 1
    n = min(B, threads)
    edges = (np.arange(n + 1) * B) // n
    return [(int(b0), int(b1)) for b0, b1 in zip(edges[:-1], edges[1:])]


def reduce(method, times, Q, tol, shared, make_track):
    """Greedy reduction, then the check: ``(kept indices, Tracks, max errors)``.

    `make_track(idx, b)` builds the `Track` of samples idx of track b (None:
    all); `Q` holds the reference samples, (T, B, 4) with `shared`, else
    track-major (B, T, 4) (C-contiguous: a track's samples lie together).
    Returns a list per track (one entry with `shared`) and the errors per
    track (B,): the errors of the returned Tracks at every original time.

    Tracks reduced on their own are independent: groups of them are searched
    and checked on the threads of `_blocks.run` (each track's keys are the same
    whatever group it falls in: every segment's error is its own).
    """
    if shared:
        (k,) = greedy(method, times, Q, tol, True)
        k, track, _ = refine(method, times, k, tol, lambda idx: make_track(idx, None), Q)
        # the largest error of each track: one more pass (the check above keeps the max over tracks)
        return [k], [track], track_errors(track, times, Q)

    def group(bounds):
        b0, b1 = bounds
        kept = greedy(method, times, Q[b0:b1], tol, False)
        return [refine(method, times, k, tol, lambda idx, b=b: make_track(idx, b), Q[b][:, None])
                for b, k in enumerate(kept, b0)]

    B, T = Q.shape[:2]
    done = [r for part in _blocks.run(group, _track_groups(B, T), B * T) for r in part]
    return [k for k, _, _ in done], [tr for _, tr, _ in done], np.array([e for _, _, e in done])
