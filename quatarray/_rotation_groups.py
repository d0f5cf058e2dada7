"""The finite rotation groups I, O, T, Dn and Cn as raw scalar-first quaternions.

`group_quats` returns one unit quaternion per group element (of the pair
±q, the one listed here); `Rotation.create_group` validates and wraps.
"""

from itertools import permutations, product

import numpy as np

from . import _convert
__all__ = ["group_quats"]

_PHI = (1 + 5 ** 0.5) / 2


def _scalar_first(q_xyzw):
    return np.asarray(q_xyzw, np.float64)[:, [3, 0, 1, 2]] + 0.0


# I, O and T list their elements in scipy's order and with scipy's signs, so that
# ``create_group(g)[k]`` and the indices `reduce` returns are scipy's.

def _tetrahedral():
    """±1, ±i, ±j, ±k and (±1 ± i ± j ± k) / 2: 12 rotations (listed as x, y, z, w)."""
    halves = [(0.5, y, z, w) for w in (0.5, -0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]
    return _scalar_first(np.concatenate([np.eye(4), halves]))


def _octahedral():
    """T plus the 6 quarter turns and 6 half turns with two components ±1/√2: 24 rotations."""
    pairs = np.array([[1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 1, 1], [0, 0, -1, 1], [0, -1, 0, 1], [-1, 0, 0, 1],
                      [0, 1, 1, 0], [0, -1, 1, 0], [1, 0, 1, 0], [-1, 0, 1, 0], [1, 1, 0, 0], [-1, 1, 0, 0]])
    return np.concatenate([_tetrahedral(), _scalar_first(pairs * np.sqrt(0.5))])


def _icosahedral():
    """T plus the even permutations of (±1/2, ±1/(2φ), ±φ/2, 0) (as x, y, z, w): 60 rotations.

    Of each pair ±q the one whose first non-zero component is positive, in
    lexicographic order of the symbols +1/2 < +1/(2φ) < +φ/2 < -1/2 < ... < 0.
    """
    base = (0.5, 0.5 / _PHI, _PHI / 2, 0.0)
    rank = {v: k for k, v in enumerate(base[:3] + tuple(-v for v in base[:3]) + (0.0,))}
    even = [p for p in permutations(range(4))
            if sum(p[i] > p[j] for i in range(4) for j in range(i + 1, 4)) % 2 == 0]
    rows = {tuple(base[i] * s + 0.0 for i, s in zip(p, signs))
            for p in even for signs in product((1, -1), repeat=4)}
    rows = sorted((r for r in rows if next(v for v in r if v) > 0), key=lambda r: [rank[v] for v in r])
    return np.concatenate([_tetrahedral(), _scalar_first(rows)])


def _cyclic(n, axis):
    """n turns by 2πk/n about basis `axis` (0, 1, 2)."""
    rotvec = np.zeros((n, 3))
    rotvec[:, axis] = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return _convert.from_rotvec(rotvec)


def _dicyclic(n, axis):
    """Cn plus n half turns about axes perpendicular to `axis`, πk/n apart."""
    theta = np.linspace(0, np.pi, n, endpoint=False)
    rotvec = np.zeros((n, 3))
    rotvec[:, (axis + 1) % 3] = np.pi * np.cos(theta)
    rotvec[:, (axis + 2) % 3] = np.pi * np.sin(theta)
    # scipy round-trips Cn through rotation vectors here: turns above π come out with w > 0
    return _convert.from_rotvec(np.concatenate([_convert.as_rotvec(_cyclic(n, axis)), rotvec]))


def group_quats(symbol, order=1, axis=2):
    """Unit quaternions (n, 4), scalar-first, of the group `symbol` in 'IOTCD'.

    >>> from quatarray._rotation_groups import group_quats
    >>> group_quats("T").shape, group_quats("D", 3).shape
    ((12, 4), (6, 4))
    """
    if symbol == "I":
        return _icosahedral()
    if symbol == "O":
        return _octahedral()
    if symbol == "T":
        return _tetrahedral()
    if symbol == "C":
        return _cyclic(order, axis)
    return _dicyclic(order, axis)
