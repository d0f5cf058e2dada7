"""quatarray on Dask arrays: rotations that do not fit in memory.

The functions here take Dask arrays (NumPy input is accepted and wrapped) of
raw scalar-first quaternions, shape ``(..., 4)``, and return lazy Dask arrays
whose chunks are plain ndarrays.  They have the names and meanings of the
in-memory functions; every block is computed by the same raw kernels
(`quatarray._kernels`, `_convert`, `_euler`, `_interp_kernels`) through
`dask.array.blockwise`, so a block's result equals the in-memory result of
that block.

* algebra: `multiply`, `conjugate`, `inverse`, `normalize`, `exp`, `log`,
  `power`, `rotate`;
* conversions: `from_matrix` / `as_matrix`, `from_rotvec` / `as_rotvec`,
  `from_euler` / `as_euler`, `from_quat` / `as_quat`;
* interpolation: `lerp`, `nlerp`, `slerp`, `squad`, `bezier` (pairwise) and
  `unflip` along a chunked axis (a sign carried from chunk to chunk);
* `mean`: the chordal L2 mean as a blockwise reduction (a 4x4 sum per chunk,
  summed by Dask's tree reduction, one eigenvector at the end);
* keyframe tracks: `evaluate` an in-memory `Track` / `Slerp` /
  `RotationSpline` at chunked query times, or `Track` with Dask keys
  ``(K, *batch, 4)`` chunked along the batch axes (each chunk of tracks
  independent).

The component axis (the last; the last two for matrices) must be one chunk:
a `ValueError` says how to rechunk otherwise.

Threads
-------
quatarray's own thread pool runs one thread inside Dask's threaded and
distributed workers (`quatarray._blocks`: calls from a thread other than the
main thread use one thread unless ``quatarray.num_threads(n)`` asks for
more), so Dask owns the parallelism and nothing is oversubscribed.  With the
synchronous scheduler, tasks run on the main thread one at a time and use
quatarray's threads.

Pickling
--------
Tasks reference module-level kernels (pickled by name).  An interpolator
enters the graph once, as one `dask.delayed` object that every task of an
evaluation depends on, so it is shipped to a worker once, not once per
chunk; a `Track` pickles to its tables, keys and times (112 bytes per key
and track for squad in float32; the segment index is rebuilt on arrival).

Requires the ``dask`` extra (``pip install 'quatarray[dask]'``).
"""

from functools import partial

import numpy as np

try:
    import dask
    import dask.array as da
except ImportError as exc:  # pragma: no cover - exercised by a monkeypatched import
    raise ImportError("quatarray.dask needs the optional dependency dask[array]: "
                      "pip install 'quatarray[dask]'") from exc

from . import _convert, _euler, _interp_kernels, _kernels, _rotation_algorithms
from ._validate import all_finite, batch_axis
from .interpolate import Track as _MemoryTrack

__all__ = [
    "multiply", "conjugate", "inverse", "normalize", "exp", "log", "power", "rotate",
    "from_matrix", "as_matrix", "from_rotvec", "as_rotvec", "from_euler", "as_euler", "from_quat", "as_quat",
    "lerp", "nlerp", "slerp", "squad", "bezier", "unflip", "mean",
    "evaluate", "Track",
]

_LETTERS = "abcdefghijklmnopqrstuvwxyz"


# --------------------------------------------------------------------------- arguments

def _array(x, name, core=0, last=None):
    """`x` as a float32/float64 Dask array whose `core` trailing axes are one chunk each."""
    if not isinstance(x, da.Array):
        x = da.asarray(x)
    kind = x.dtype.kind
    if kind == "f" and x.dtype.itemsize in (4, 8):
        pass
    elif kind in "biuf":
        x = x.astype(np.float64)
    else:
        raise TypeError(f"expected {name} of real numbers (float, int or bool), got dtype {x.dtype}")
    if last is not None and (x.ndim < core or x.shape[x.ndim - len(last):] != last):
        want = "(..., " + ", ".join(map(str, last)) + ")"
        raise ValueError(f"expected {name} of shape {want}, got {x.shape}")
    split = [i for i in range(x.ndim - core, x.ndim) if len(x.chunks[i]) > 1]
    if split:
        how = ", ".join(f"{i - x.ndim}: -1" for i in range(x.ndim - core, x.ndim))
        raise ValueError(f"expected {name} with its component axis (the last {core}) in one chunk, got chunks "
                         f"{x.chunks[x.ndim - core:]}; rechunk it first: {name}.rechunk({{{how}}})")
    return x


def _quat(x, name):
    return _array(x, name, 1, (4,))


def _batch(names, arrays, cores):
    """The broadcast batch shape.  Unknown sizes (NaN, after boolean indexing) are taken as they
    are when every batch shape is the same; they cannot be broadcast against known ones."""
    shapes = [a.shape[:a.ndim - c] for a, c in zip(arrays, cores)]
    unknown = [n for n, s in zip(names, shapes) if any(np.isnan(s))]
    if unknown:
        # arrays of ones (scalars included) broadcast against anything; the others must match
        full = [(a, s) for a, s in zip(arrays, shapes) if any(n != 1 for n in s)]
        rank = max(len(s) for s in shapes)
        a0, s0 = full[0]
        if len(s0) == rank and all(s == s0 and a.chunks[:rank] == a0.chunks[:rank] for a, s in full):
            return s0
        raise ValueError(f"expected {' and '.join(unknown)} with known chunk sizes to broadcast against "
                         f"{', '.join(n for n in names if n not in unknown) or 'each other'}, got shapes "
                         f"{', '.join(f'{n}: {s}' for n, s in zip(names, shapes))}; call "
                         f"{unknown[0]}.compute_chunk_sizes() first")
    try:
        return np.broadcast_shapes(*shapes)
    except ValueError:
        got = ", ".join(f"{n}: {s}" for n, s in zip(names, shapes))
        raise ValueError(f"expected broadcastable batch shapes for {', '.join(names)}, got {got}") from None


def _finite(block, name):
    """`block`, or a `ValueError` if it holds NaN or inf: the in-memory API's rule, checked per
    chunk when the chunk is computed."""
    if not all_finite(block):
        raise ValueError(f"expected finite values in {name}, got nan or inf")
    return block


def _checked(kernel, names, *blocks, **params):
    """``kernel(*blocks, **params)`` after checking that every block is finite."""
    return kernel(*(_finite(b, n) for b, n in zip(blocks, names)), **params)


def _apply(kernel, names, arrays, cores, out_core, dtype, **params):
    """``kernel(*blocks, **params)`` per block: batch axes broadcast and chunked
    alike, the `cores` trailing axes of each input whole, output core `out_core`."""
    batch = _batch(names, arrays, cores)
    nb = len(batch)
    letters = iter(_LETTERS[nb:])
    pairs = []
    for a, c in zip(arrays, cores):
        pairs += [a, _LETTERS[:nb][nb - (a.ndim - c):] + "".join(next(letters) for _ in range(c))]
    out_ix = "".join(next(letters) for _ in out_core)
    return da.blockwise(partial(_checked, kernel, tuple(names), **params), _LETTERS[:nb] + out_ix, *pairs,
                        new_axes=dict(zip(out_ix, out_core)), dtype=dtype, concatenate=True,
                        meta=np.empty((0,) * (nb + len(out_core)), dtype))


def _unary(kernel, q, name="q", out_core=(4,), **params):
    q = _quat(q, name)
    return _apply(kernel, (name,), [q], (1,), out_core, _kernels.result_dtype(q.dtype), **params)


# --------------------------------------------------------------------------- algebra

def multiply(p, q):
    """Hamilton product ``p q`` of Dask arrays of quaternions, blockwise.

    Parameters
    ----------
    p, q : dask.array.Array, shape (..., 4)
        Batch shapes broadcast; the last axis must be one chunk.

    Returns
    -------
    dask.array.Array, shape (broadcast batch, 4)

    Examples
    --------
    >>> import numpy as np
    >>> import dask.array as da
    >>> from quatarray import dask as qd
    >>> k = da.from_array(np.array([[0., 0, 0, 1]] * 4), chunks=(2, 4))
    >>> qd.multiply(k, k).compute()[0]
    array([-1.,  0.,  0.,  0.])
    """
    p, q = _quat(p, "p"), _quat(q, "q")
    return _apply(_kernels.multiply, ("p", "q"), [p, q], (1, 1), (4,), _kernels.result_dtype(p.dtype, q.dtype))


def conjugate(q):
    """Conjugate ``(w, -x, -y, -z)``, blockwise.

    >>> import numpy as np
    >>> import dask.array as da
    >>> from quatarray import dask as qd
    >>> qd.conjugate(da.from_array(np.array([[1., 2, 3, 4]]))).compute()
    array([[ 1., -2., -3., -4.]])
    """
    return _unary(_kernels.conjugate, q)


def inverse(q):
    """Inverse ``q* / |q|²``, blockwise.

    >>> import numpy as np
    >>> import dask.array as da
    >>> from quatarray import dask as qd
    >>> qd.inverse(da.from_array(np.array([[2., 0, 0, 0]]))).compute() + 0.0
    array([[0.5, 0. , 0. , 0. ]])
    """
    return _unary(_kernels.inverse, q)


def normalize(q):
    """``q / |q|``, blockwise.

    >>> import numpy as np
    >>> import dask.array as da
    >>> from quatarray import dask as qd
    >>> qd.normalize(da.from_array(np.array([[0., 0, 3, 4]]))).compute()
    array([[0. , 0. , 0.6, 0.8]])
    """
    return _unary(_kernels.normalize, q)


def exp(q):
    """Quaternion exponential, blockwise.

    >>> import dask.array as da
    >>> from quatarray import dask as qd
    >>> qd.exp(da.zeros((3, 4), chunks=(2, 4))).compute()[2]
    array([1., 0., 0., 0.])
    """
    return _unary(_kernels.exp, q)


def log(q):
    """Quaternion logarithm, blockwise.

    >>> import numpy as np
    >>> import dask.array as da
    >>> from quatarray import dask as qd
    >>> qd.log(da.from_array(np.array([[1., 0, 0, 0]]))).compute()
    array([[0., 0., 0., 0.]])
    """
    return _unary(_kernels.log, q)


def power(q, t):
    """``exp(t log q)``; `t` a scalar or a (Dask) array broadcasting against the batch.

    >>> import numpy as np
    >>> import dask.array as da
    >>> from quatarray import dask as qd
    >>> k = da.from_array(np.array([[0., 0, 0, 1]]))
    >>> np.allclose(qd.power(k, 2).compute(), [[-1, 0, 0, 0]])
    True
    """
    q, t = _quat(q, "q"), _array(t, "t")
    return _apply(_kernels.power, ("q", "t"), [q, t], (1, 0), (4,), _kernels.result_dtype(q.dtype))


def rotate(q, v, inverse=False):
    """Rotate vectors `v` (..., 3) by the rotations `q` (..., 4) (by their inverse with `inverse`).

    >>> import numpy as np
    >>> import dask.array as da
    >>> from quatarray import dask as qd
    >>> z90 = da.from_array(np.array([[np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)]]))
    >>> np.round(qd.rotate(z90, np.array([[1., 0, 0]])).compute(), 12) + 0.0
    array([[0., 1., 0.]])
    """
    q, v = _quat(q, "q"), _array(v, "v", 1, (3,))
    return _apply(_kernels.rotate_nonzero, ("q", "v"), [q, v], (1, 1), (3,), _kernels.result_dtype(q.dtype, v.dtype),
                  inverse=bool(inverse))


# --------------------------------------------------------------------------- conversions

def from_matrix(matrix, assume_valid=False):
    """Quaternions of rotation matrices (..., 3, 3), as `Rotation.from_matrix`.

    >>> import numpy as np
    >>> import dask.array as da
    >>> from quatarray import dask as qd
    >>> qd.from_matrix(da.from_array(np.eye(3)[None])).compute()
    array([[1., 0., 0., 0.]])
    """
    m = _array(matrix, "matrix", 2, (3, 3))
    return _apply(_convert.from_matrix, ("matrix",), [m], (2,), (4,), m.dtype, assume_valid=bool(assume_valid))


def as_matrix(q):
    """Rotation matrices (..., 3, 3) of quaternions, as `Rotation.as_matrix`.

    >>> import numpy as np
    >>> import dask.array as da
    >>> from quatarray import dask as qd
    >>> qd.as_matrix(da.from_array(np.array([[1., 0, 0, 0]]))).compute()[0]
    array([[1., 0., 0.],
           [0., 1., 0.],
           [0., 0., 1.]])
    """
    return _unary(_convert.as_matrix, q, out_core=(3, 3))


def from_rotvec(rotvec, degrees=False):
    """Quaternions of rotation vectors (..., 3), as `Rotation.from_rotvec`.

    >>> import numpy as np
    >>> import dask.array as da
    >>> from quatarray import dask as qd
    >>> np.round(qd.from_rotvec(da.from_array(np.array([[0, 0, np.pi]]))).compute(), 12) + 0.0
    array([[0., 0., 0., 1.]])
    """
    v = _array(rotvec, "rotvec", 1, (3,))
    return _apply(_convert.from_rotvec, ("rotvec",), [v], (1,), (4,), v.dtype, degrees=bool(degrees))


def as_rotvec(q, degrees=False):
    """Rotation vectors (..., 3) of quaternions, as `Rotation.as_rotvec`.

    >>> import numpy as np
    >>> import dask.array as da
    >>> from quatarray import dask as qd
    >>> np.round(qd.as_rotvec(da.from_array(np.array([[0., 0, 0, 1]]))).compute(), 12)
    array([[0.        , 0.        , 3.14159265]])
    """
    return _unary(_convert.as_rotvec, q, out_core=(3,), degrees=bool(degrees))


def from_euler(seq, angles, degrees=False):
    """Quaternions of Euler angles (..., len(seq)), as `Rotation.from_euler` (scipy's argument order).

    >>> import numpy as np
    >>> import dask.array as da
    >>> from quatarray import dask as qd
    >>> np.round(qd.from_euler("z", da.from_array(np.array([[90.]])), degrees=True).compute(), 6)
    array([[0.707107, 0.      , 0.      , 0.707107]])
    """
    _euler.check_seq(seq)
    a = _array(_euler.check_angles(seq, _array(angles, "angles")), "angles", 1)
    return _apply(_from_euler_block, ("angles",), [a], (1,), (4,), a.dtype, seq=seq, degrees=bool(degrees))


def _from_euler_block(angles, seq, degrees):
    return _euler.from_euler(seq, angles, degrees)


def as_euler(q, seq, degrees=False, suppress_warnings=False):
    """Euler angles (..., 3) of quaternions, as `Rotation.as_euler` (gimbal-lock warnings per chunk).

    >>> import numpy as np
    >>> import dask.array as da
    >>> from quatarray import dask as qd
    >>> q = qd.from_euler("zyx", da.from_array(np.array([[90., 30, 10]])), degrees=True)
    >>> np.round(qd.as_euler(q, "zyx", degrees=True).compute(), 9)
    array([[90., 30., 10.]])
    """
    _euler.check_seq(seq, 3)
    return _unary(_euler.as_euler, q, out_core=(3,), seq=seq, degrees=bool(degrees),
                  suppress_warnings=bool(suppress_warnings))


def from_quat(quat, scalar_first=False):
    """Unit scalar-first quaternions from ``(x, y, z, w)`` (or ``(w, x, y, z)`` with `scalar_first`).

    >>> import numpy as np
    >>> import dask.array as da
    >>> from quatarray import dask as qd
    >>> qd.from_quat(da.from_array(np.array([[0., 0, 3, 4]]))).compute()
    array([[0.8, 0. , 0. , 0.6]])
    """
    return _unary(_convert.from_quat, quat, "quat", scalar_first=bool(scalar_first))


def _as_quat_block(q, canonical, scalar_first):
    if canonical:
        q = _convert.canonical(q)
    return q.copy() if scalar_first else q[..., [1, 2, 3, 0]]


def as_quat(q, canonical=False, *, scalar_first=False):
    """The quaternions scalar-last (scipy's default) or scalar-first, optionally canonical (w >= 0).

    >>> import numpy as np
    >>> import dask.array as da
    >>> from quatarray import dask as qd
    >>> qd.as_quat(da.from_array(np.array([[-1., 0, 0, 0]])), canonical=True).compute()
    array([[0., 0., 0., 1.]])
    """
    return _unary(_as_quat_block, q, canonical=bool(canonical), scalar_first=bool(scalar_first))


# --------------------------------------------------------------------------- pairwise interpolation

def _pairwise(kernel, names, quats, t, **params):
    quats = [_quat(x, n) for x, n in zip(quats, names)]
    t = _array(t, "t")
    dtype = _kernels.result_dtype(*(q.dtype for q in quats))
    return _apply(kernel, names + ("t",), quats + [t], (1,) * len(quats) + (0,), (4,), dtype, **params)


def lerp(q0, q1, t):
    """``(1 - t) q0 + t q1``, blockwise (see `quatarray.interpolate.lerp`).

    >>> import numpy as np
    >>> from quatarray import dask as qd
    >>> qd.lerp(np.array([1., 0, 0, 0]), np.array([0., 0, 0, 1]), 0.5).compute()
    array([0.5, 0. , 0. , 0.5])
    """
    return _pairwise(_interp_kernels.lerp, ("q0", "q1"), [q0, q1], t)


def nlerp(q0, q1, t, *, shortest=True):
    """Normalised linear interpolation, blockwise (see `quatarray.interpolate.nlerp`).

    >>> import numpy as np
    >>> from quatarray import dask as qd
    >>> np.round(qd.nlerp(np.array([1., 0, 0, 0]), np.array([0., 0, 0, 1]), 0.5).compute(), 6)
    array([0.707107, 0.      , 0.      , 0.707107])
    """
    return _pairwise(_interp_kernels.nlerp, ("q0", "q1"), [q0, q1], t, shortest=bool(shortest))


def slerp(q0, q1, t, *, shortest=True):
    """Spherical linear interpolation, blockwise (see `quatarray.interpolate.slerp`).

    >>> import numpy as np
    >>> import dask.array as da
    >>> from quatarray import dask as qd
    >>> t = da.linspace(0, 1, 5, chunks=2)
    >>> q = qd.slerp(np.array([1., 0, 0, 0]), np.array([0., 0, 0, 1]), t)
    >>> q.chunks
    ((2, 2, 1), (4,))
    >>> np.round(q.compute()[2], 6)
    array([0.707107, 0.      , 0.      , 0.707107])
    """
    return _pairwise(_interp_kernels.slerp, ("q0", "q1"), [q0, q1], t, shortest=bool(shortest))


def squad(q0, a, b, q1, t):
    """Shoemake's squad segment, blockwise (see `quatarray.interpolate.squad`).

    >>> import numpy as np
    >>> from quatarray import dask as qd
    >>> q0, q1 = np.array([1., 0, 0, 0]), np.array([np.cos(0.3), np.sin(0.3), 0, 0])
    >>> np.allclose(qd.squad(q0, q0, q1, q1, 0.25).compute(), qd.slerp(q0, q1, 0.25).compute())
    True
    """
    return _pairwise(_interp_kernels.squad, ("q0", "a", "b", "q1"), [q0, a, b, q1], t)


def bezier(q0, a, b, q1, t):
    """Spherical cubic Bézier segment, blockwise (see `quatarray.interpolate.bezier`).

    >>> import numpy as np
    >>> from quatarray import dask as qd
    >>> q0 = np.array([1., 0, 0, 0])
    >>> qd.bezier(q0, q0, q0, q0, 0.3).compute()
    array([1., 0., 0., 0.])
    """
    return _pairwise(_interp_kernels.bezier, ("q0", "a", "b", "q1"), [q0, a, b, q1], t)


# --------------------------------------------------------------------------- unflip along a chunked axis

def _unflip_summary(q, axis):
    """Per chunk along `axis` (kept, length 1): first and last quaternion (4 + 4),
    the sign of the last one in the chunk's own unflip (1) and whether a zero
    dot product restarts the signs inside the chunk (1)."""
    qa = np.moveaxis(_finite(q, "q"), axis, 0)
    dtype = _kernels.result_dtype(q)
    out = np.empty((1,) + qa.shape[1:-1] + (10,), dtype)
    out[0, ..., 0:4] = qa[0]
    out[0, ..., 4:8] = qa[-1]
    u_last = np.moveaxis(_interp_kernels.unflip(q, axis), axis, 0)[-1]
    out[0, ..., 8] = np.where((u_last != qa[-1]).any(axis=-1), -1, 1)   # (exact: u_last is ±qa[-1])
    out[0, ..., 9] = (_interp_kernels.unflip_dots(qa[1:], qa[:-1]) == 0).any(axis=0) if len(qa) > 1 else False
    return np.moveaxis(out, 0, axis)


def _unflip_carries(s, axis):
    """Sign g_j applied to chunk j's elements before its first restart, from the
    chunk summaries (all chunks along `axis` in one block): the in-memory rule
    (sign = product of the step signs since the last zero dot product) with
    the chunks' own unflips as the steps."""
    sa = np.moveaxis(s, axis, 0)
    g = np.ones(sa.shape[:-1], s.dtype)
    last_sign = sa[0, ..., 8]                 # final sign of chunk 0's last quaternion
    for j in range(1, len(sa)):                # a loop over chunks, not elements
        d = _interp_kernels.unflip_dots(sa[j, ..., 0:4], sa[j - 1, ..., 4:8])
        g[j] = np.where(d == 0, 1, np.where(d < 0, -last_sign, last_sign))
        last_sign = np.where(sa[j, ..., 9] != 0, sa[j, ..., 8], g[j] * sa[j, ..., 8])
    return np.moveaxis(g, 0, axis)


def _unflip_apply(q, g, axis):
    u = _interp_kernels.unflip(q, axis)
    if (g > 0).all():   # nothing to carry into this chunk
        return u
    qa = np.moveaxis(q, axis, 0)
    n = qa.shape[0]
    carried = np.ones(qa.shape[:-1], bool)   # before the chunk's first zero dot product
    if n > 1:
        carried[1:] = np.logical_and.accumulate(_interp_kernels.unflip_dots(qa[1:], qa[:-1]) != 0, axis=0)
    factor = np.where(carried, np.moveaxis(g, axis, 0), 1).astype(u.dtype)
    return u * np.moveaxis(factor, 0, axis)[..., None]


def unflip(q, axis=0):
    """Flip signs so that consecutive quaternions along a (chunked) batch `axis` have a non-negative dot product.

    Equal to `quatarray.interpolate.unflip` whatever the chunks: each chunk
    is unflipped on its own, then a sign is carried across the chunk
    borders by a scan over small per-chunk summaries (first and last
    quaternion of each chunk), so no chunk waits for the data of another.

    Parameters
    ----------
    q : dask.array.Array, shape (..., 4)
    axis : int, default 0
        A batch axis, chunked in any way.

    Returns
    -------
    dask.array.Array, same shape and chunks as `q`

    Examples
    --------
    >>> import numpy as np
    >>> import dask.array as da
    >>> from quatarray import dask as qd
    >>> q = da.from_array(np.array([[1., 0, 0, 0], [-1, 0, 0, 0], [-1, 0, 0, 0]]), chunks=(1, 4))
    >>> qd.unflip(q).compute()[:, 0]
    array([1., 1., 1.])
    """
    q = _quat(q, "q")
    nb = q.ndim - 1
    axis = batch_axis(axis, q.shape[:-1])
    if any(np.isnan(q.chunks[axis])):
        raise ValueError(f"expected q with known chunk sizes along axis {axis}, got {q.shape}; "
                         "call q.compute_chunk_sizes() first")
    dtype = _kernels.result_dtype(q.dtype)
    nblocks = len(q.chunks[axis])
    if nblocks == 1 or 0 in q.shape:
        return q.map_blocks(partial(_checked, _interp_kernels.unflip, ("q",), axis=axis), dtype=dtype,
                            meta=np.empty((0,) * q.ndim, dtype))
    chunks = q.chunks[:axis] + ((1,) * nblocks,) + q.chunks[axis + 1:-1]
    summary = q.map_blocks(_unflip_summary, axis, dtype=dtype, chunks=chunks + ((10,),),
                           meta=np.empty((0,) * q.ndim, dtype))
    carries = summary.rechunk({axis: -1}).map_blocks(_unflip_carries, axis, dtype=dtype, drop_axis=nb,
                                                     meta=np.empty((0,) * nb, dtype))
    carries = carries.rechunk(chunks)
    ix = _LETTERS[:nb]
    # carries has one element per chunk along `axis`: block j of q meets block j of carries
    return da.blockwise(_unflip_apply, ix + "z", q, ix + "z", carries, ix, dtype=dtype, align_arrays=False,
                        adjust_chunks={ix[axis]: q.chunks[axis]}, axis=axis, meta=np.empty((0,) * q.ndim, dtype))


# --------------------------------------------------------------------------- mean

def _chordal_sum(q, w, wmax, n):
    """Σ w q qᵀ over a whole block of rows normalised as `Rotation.mean`'s (at any magnitude;
    NaN and inf raise the module's ValueError, zero rows its), the weights scaled as its (by
    the largest of all, `wmax`, over `n` rotations): float64, shape (1, ..., 1, 4, 4)."""
    c = _convert.from_quat(_finite(q, "q").astype(np.float64, copy=False).reshape(-1, 4), scalar_first=True, name="q")
    w = np.broadcast_to(w, q.shape[:-1]).reshape(-1).astype(np.float64, copy=False)
    e = _rotation_algorithms.weight_exponents(np.asarray(wmax, np.float64), n)
    if e is not None:
        w = np.ldexp(w, -e)
    k = (c * w[:, None]).T @ c
    return k.reshape((1,) * (q.ndim - 1) + (4, 4))


def mean(q, weights=None):
    """Chordal L2 mean of all the rotations `q`: the dominant eigenvector of Σ wᵢ q̂ᵢ q̂ᵢᵀ.

    A blockwise reduction: each chunk gives its 4x4 sum, Dask sums those in a
    tree, and one 4x4 eigenvector problem gives the mean (canonical sign,
    w >= 0), as `Rotation.mean`.  Nothing but 4x4 matrices leaves a worker.
    NaN or inf in `q` or `weights` raises a `ValueError` when its chunk is computed.

    Parameters
    ----------
    q : dask.array.Array, shape (..., 4)
    weights : array_like or dask.array.Array, optional
        Non-negative, broadcasting against the batch shape (checked per chunk
        when computed).

    Returns
    -------
    dask.array.Array, shape (4,)

    Examples
    --------
    >>> import numpy as np
    >>> import dask.array as da
    >>> from quatarray import dask as qd
    >>> q = qd.from_euler("z", da.from_array(np.array([[0.], [10], [20]]), chunks=(2, 1)), degrees=True)
    >>> np.round(qd.as_euler(qd.mean(q)[None], "zyx", degrees=True).compute(), 9) + 0.0
    array([[10.,  0.,  0.]])
    """
    q = _quat(q, "q")
    if 0 in q.shape[:-1]:
        raise ValueError(f"Mean of an empty rotation set is undefined: expected at least one rotation, "
                         f"got shape {q.shape[:-1]}")
    w = _array(1.0 if weights is None else weights, "weights")
    if weights is not None:
        w = w.map_blocks(_check_weights, dtype=w.dtype, meta=np.empty((0,) * w.ndim, w.dtype))
    nb = q.ndim - 1
    batch = _batch(("q", "weights"), [q, w], (1, 0))
    if batch != q.shape[:-1]:
        raise ValueError(f"Expected `weights` to be broadcastable to rotation shape: got weights of shape "
                         f"{w.shape} for rotations of shape {q.shape[:-1]}")
    ix = _LETTERS[:nb]
    n = np.prod(q.shape[:-1])
    n = int(n) if np.isfinite(n) else 2 ** 62    # unknown chunk sizes: as many as may be summed
    wmax = w.max() if weights is not None else 1.0    # (one more pass over the weights, not the rotations)
    parts = da.blockwise(_chordal_sum, ix + "yz", q, ix + "x", w, ix[nb - w.ndim:], wmax, None, n, None,
                         new_axes={"y": 4, "z": 4}, adjust_chunks={c: 1 for c in ix}, concatenate=True,
                         dtype=np.float64, meta=np.empty((0,) * (nb + 2)))
    k = parts.sum(axis=tuple(range(nb)))
    return k.map_blocks(partial(_rotation_algorithms.dominant, dtype=q.dtype), drop_axis=1, dtype=q.dtype,
                        meta=np.empty((0,), q.dtype))


def _check_weights(w):
    if not np.isfinite(w).all():
        raise ValueError("expected finite weights, got nan or inf")
    if (w < 0).any():
        raise ValueError("`weights` must be non-negative.")
    return w


# --------------------------------------------------------------------------- keyframe tracks

def _quats(x):
    """Raw scalar-first quaternions of an interpolator's result (QuatArray, Rotation or ndarray)."""
    if not isinstance(x, np.ndarray) and hasattr(x, "as_quat"):
        return x.as_quat(scalar_first=True)
    return np.asarray(x)


def _evaluate_block(interp, t):
    out = _quats(interp(t.ravel()))
    return out.reshape(t.shape + out.shape[1:])


def evaluate(interpolator, t):
    """Evaluate an in-memory interpolator at chunked query times: keys in memory, queries chunked.

    Parameters
    ----------
    interpolator : Track, Slerp or RotationSpline
        Built in memory (`quatarray.interpolate.Track` and its tables enter
        the task graph once and are shipped to each worker once).
    t : dask.array.Array or array_like
        Query times of any shape, chunked any way.  With
        ``extrapolate='raise'``, a time outside the keys raises when its
        chunk is computed.

    Returns
    -------
    dask.array.Array, shape ``t.shape + batch_shape + (4,)``
        Chunked like `t` along its axes; batch and component axes whole.

    Examples
    --------
    >>> import numpy as np
    >>> import dask.array as da
    >>> from quatarray import dask as qd
    >>> from quatarray.interpolate import Track
    >>> track = Track([0, 1, 2], [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]], method="squad")
    >>> q = qd.evaluate(track, da.linspace(0, 2, 1001, chunks=250))
    >>> q.shape, q.chunks[0]
    ((1001, 4), (250, 250, 250, 250, 1))
    >>> np.allclose(q[500].compute(), [0, 1, 0, 0])
    True
    """
    t = _array(t, "t")
    t0 = np.asarray(interpolator.times[:1], np.float64)
    probe = _quats(interpolator(t0))                      # batch shape and dtype of the output
    tail = probe.shape[1:]
    handle = dask.delayed(interpolator, pure=True)
    tix = _LETTERS[:t.ndim]
    out_ix = _LETTERS[t.ndim:t.ndim + len(tail)]
    return da.blockwise(_evaluate_block, tix + out_ix, handle, None, t, tix, new_axes=dict(zip(out_ix, tail)),
                        dtype=probe.dtype, meta=np.empty((0,) * (t.ndim + len(tail)), probe.dtype))


def _track_block(times, keys, t, method, extrapolate):
    return np.asarray(_MemoryTrack(times, keys, method=method, extrapolate=extrapolate)(t))


class Track:
    """Keyframe tracks whose keys are a Dask array ``(K, *batch, 4)`` chunked along the batch axes.

    Each chunk of tracks is an independent set of tracks: its `Track` is
    built and evaluated inside the task, so no chunk of keys meets another.
    With keys in memory, this is `evaluate` of one in-memory `Track`.  With
    Dask keys, the times, options and the first track's keys are checked
    here (computing those K keys); the other tracks when their chunk is.

    Parameters
    ----------
    times : array_like, shape (K,)
        Key times (in memory).
    keys : dask.array.Array or array_like, shape (K, *batch, 4)
        The key axis and the component axis must each be one chunk.
    method, extrapolate : str
        As `quatarray.interpolate.Track`.

    Examples
    --------
    >>> import numpy as np
    >>> import dask.array as da
    >>> from quatarray import dask as qd
    >>> keys = da.from_array(np.tile([[[1., 0, 0, 0]], [[0, 0, 0, 1]]], (1, 6, 1)), chunks=(2, 4, 4))
    >>> track = qd.Track([0.0, 1.0], keys)
    >>> q = track(np.array([0.0, 0.5]))
    >>> q.shape, q.chunks[1]
    ((2, 6, 4), (4, 2))
    >>> np.round(q[1, 5].compute(), 6)
    array([0.707107, 0.      , 0.      , 0.707107])
    """

    def __init__(self, times, keys, *, method="slerp", extrapolate="raise"):
        if not isinstance(keys, da.Array):
            self._memory = _MemoryTrack(times, keys, method=method, extrapolate=extrapolate)
            self._keys = None
            return
        self._memory = None
        keys = _quat(keys, "keys")
        if keys.ndim < 2:
            raise ValueError(f"expected keys of shape (K, ..., 4), got {keys.shape}")
        if len(keys.chunks[0]) > 1:
            raise ValueError(f"expected keys with the key axis (axis 0) in one chunk, got chunks {keys.chunks[0]}; "
                             "rechunk it first: keys.rechunk({0: -1}) (chunk along the batch axes instead)")
        # validate times, keys and options once on a small sample (the first track of each chunk is built in its task)
        first = keys[(slice(None),) + (slice(0, 1),) * (keys.ndim - 2)].compute()
        probe = _MemoryTrack(times, first, method=method, extrapolate=extrapolate)
        self._times = probe.times
        self._keys = keys
        self._method = method
        self._extrapolate = extrapolate
        self._dtype = probe.dtype

    def __call__(self, t):
        """Rotations at the query times `t`: shape ``t.shape + batch_shape + (4,)``."""
        if self._memory is not None:
            return evaluate(self._memory, t)
        t = _array(t, "t")
        nt, nb = t.ndim, self._keys.ndim - 2
        tix, bix = _LETTERS[:nt], _LETTERS[nt:nt + nb]
        dtype = self._dtype
        return da.blockwise(_track_block, tix + bix + "z", dask.delayed(self._times, pure=True), None, self._keys, "k" + bix + "z",
                            t, tix, concatenate=True, dtype=dtype, method=self._method,
                            extrapolate=self._extrapolate, meta=np.empty((0,) * (nt + nb + 1), dtype))
