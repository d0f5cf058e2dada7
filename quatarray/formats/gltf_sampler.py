"""glTF 2.0 animation samplers evaluated as the specification requires, on raw arrays.

A sampler maps key times ``(K,)`` to output values; here the values of one
key are a row of ``n`` numbers: a rotation is 4 (x, y, z, w, scalar-last), a
translation or scale 3, morph-target weights one per target.  CUBICSPLINE
outputs hold three rows per key: in-tangent, value, out-tangent.

- **STEP** -- the value of the last key at or before t.
- **LINEAR** -- rotations: slerp on the short path; everything else: linear.
- **CUBICSPLINE** -- the cubic Hermite form of the spec (Appendix C), with
  the tangents scaled by the key interval; rotations are normalised.

Queries outside the keys are clamped, as the spec requires.  SLERP and the
rotation curves are quatarray's own (`quatarray._interp_kernels`,
`quatarray.interpolate.Track`): SLERP and normalisation do not depend on the
component order, squad and Bézier do, so those see scalar-first keys.
"""

import numpy as np

from .. import _interp_kernels
from .._interp_lookup import SegmentIndex
from ..interpolate import Track

__all__ = ["INTERPOLATIONS", "evaluate_sampler", "resample_sampler"]

INTERPOLATIONS = ("STEP", "LINEAR", "CUBICSPLINE")


def _normalise(q):
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def evaluate_sampler(times, values, interpolation, t, rotation=False):
    """Values of a glTF sampler at times `t`, as the spec defines them.

    Parameters
    ----------
    times : ndarray, shape (K,)
        Strictly increasing key times, K >= 1.
    values : ndarray, shape (K, n), or (3 K, n) for CUBICSPLINE
        One row per key (CUBICSPLINE: in-tangent, value, out-tangent per key).
    interpolation : {'STEP', 'LINEAR', 'CUBICSPLINE'}
    t : ndarray, shape (M,)
        Query times; those outside ``[times[0], times[-1]]`` are clamped.
    rotation : bool
        The rows are unit quaternions x, y, z, w (slerp, normalised output).

    Returns
    -------
    ndarray, shape (M, n), float64

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray.formats.gltf_sampler import evaluate_sampler
    >>> evaluate_sampler(np.array([0.0, 1.0]), np.array([[0.0], [2.0]]), "LINEAR", np.array([-1.0, 0.25, 5.0]))
    array([[0. ],
           [0.5],
           [2. ]])
    """
    times = np.asarray(times, np.float64)
    values = np.asarray(values, np.float64)
    K = len(times)
    t = np.clip(np.asarray(t, np.float64), times[0], times[-1])
    if interpolation == "CUBICSPLINE":
        triples = values.reshape(K, 3, -1)
        v, b_out, a_in = triples[:, 1], triples[:, 2], triples[:, 0]
    else:
        v = values
    i = SegmentIndex(times).find(t)          # last key at or before t
    if interpolation == "STEP" or K == 1:
        return v[np.clip(i, 0, K - 1)].copy()
    i = np.clip(i, 0, K - 2)
    td = times[i + 1] - times[i]
    u = (t - times[i]) / td
    if interpolation == "LINEAR":
        if rotation:
            return _interp_kernels.slerp(v[i], v[i + 1], u, shortest=True)
        return v[i] * (1 - u)[:, None] + v[i + 1] * u[:, None]
    u2, u3 = u * u, u * u * u
    h00 = 2 * u3 - 3 * u2 + 1
    h10 = (u3 - 2 * u2 + u) * td
    h01 = -2 * u3 + 3 * u2
    h11 = (u3 - u2) * td
    out = h00[:, None] * v[i] + h10[:, None] * b_out[i] + h01[:, None] * v[i + 1] + h11[:, None] * a_in[i + 1]
    return _normalise(out) if rotation else out


def resample_sampler(times, values, interpolation, t, rotation=False, method=None):
    """Values at `t` to store as the keys of a LINEAR sampler.

    With `method` None the sampler's own interpolation is evaluated at `t`
    (`evaluate_sampler`): a STEP sampler gives the value it holds at each
    query time, a CUBICSPLINE sampler the Hermite curve's value.  For a
    rotation sampler with LINEAR or CUBICSPLINE interpolation, `method`
    ('slerp', 'squad', 'bezier' or 'linear') instead draws
    `quatarray.interpolate.Track`'s curve through the key values
    (CUBICSPLINE tangents are then not used).  STEP samplers, and the other
    paths, keep their own interpolation.  Rotations come out normalised, with
    consecutive signs agreeing (``q · q_next >= 0``), so that slerp between
    written keys takes the short path the curve took.

    Returns
    -------
    ndarray, shape (M, n), float64

    Examples
    --------
    >>> import numpy as np
    >>> from quatarray.formats.gltf_sampler import resample_sampler
    >>> keys = np.array([[0, 0, 0, 1.0], [0, 0, 1.0, 0]])        # identity, 180 deg about z
    >>> resample_sampler(np.array([0.0, 1.0]), keys, "LINEAR", np.array([0.5]), rotation=True).round(4)
    array([[0.    , 0.    , 0.7071, 0.7071]])
    >>> resample_sampler(np.array([0.0, 1.0]), np.array([[0.0], [2.0]]), "STEP", np.array([0.0, 0.5, 1.0]))
    array([[0.],
           [0.],
           [2.]])
    """
    if method is None or not rotation or interpolation == "STEP" or len(times) < 2:
        out = evaluate_sampler(times, values, interpolation, t, rotation)
    else:
        keys = np.asarray(values, np.float64)
        if interpolation == "CUBICSPLINE":
            keys = keys.reshape(len(times), 3, -1)[:, 1]
        track = Track(times, np.roll(keys, 1, axis=-1), method=method, extrapolate="clamp")
        out = np.roll(np.asarray(track(np.asarray(t, np.float64))), -1, axis=-1)
    if rotation:
        out = _interp_kernels.unflip(_normalise(out), 0)
    return out
