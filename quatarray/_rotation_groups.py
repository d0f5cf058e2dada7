"""The finite rotation groups I, O, T, Dn and Cn as raw scalar-first quaternions.

`group_quats` returns one unit quaternion per group element (of the pair
±q, the one listed here); `Rotation.create_group` validates and wraps.
"""

from itertools import permutations, product

import numpy as np

from . import _convert as C

__all__ = ["group_quats"]

_PHI = (1 + 5 ** 0.5) / 2


def _one_per_pair(q):
    """Drop -q when q is already listed (unit quaternions, exact entries)."""
    q = C.canonical(np.asarray(q, np.float64))
    _, first = np.unique(np.round(q, 12), axis=0, return_index=True)
    return q[np.sort(first)]


def _tetrahedral():
    """±1, ±i, ±j, ±k and (±1 ± i ± j ± k) / 2: 12 rotations."""
    halves = np.array(list(product((0.5, -0.5), repeat=4)))
    return _one_per_pair(np.concatenate([np.eye(4), halves]))


def _octahedral():
    """T plus the 12 quarter and half turns (two components ±1/√2): 24 rotations."""
    c = np.sqrt(0.5)
    pairs = [np.eye(4)[i] * s + np.eye(4)[j] * t
             for i in range(4) for j in range(i + 1, 4) for s in (c, -c) for t in (c, -c)]
    return _one_per_pair(np.concatenate([_tetrahedral(), pairs]))


def _icosahedral():
    """T plus the even permutations of (0, ±1, ±1/φ, ±φ) / 2 (as w, x, y, z): 60 rotations."""
    even = [p for p in permutations(range(4))
            if sum(p[i] > p[j] for i in range(4) for j in range(i + 1, 4)) % 2 == 0]
    values = [(0.0, a * 0.5, b * 0.5 / _PHI, c * _PHI / 2) for a, b, c in product((1, -1), repeat=3)]
    extra = [[v[p.index(i)] for i in range(4)] for p in even for v in values]
    return _one_per_pair(np.concatenate([_tetrahedral(), extra]))


def _cyclic(n, axis):
    """n turns by 2πk/n about basis `axis` (0, 1, 2)."""
    rotvec = np.zeros((n, 3))
    rotvec[:, axis] = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return C.from_rotvec(rotvec)


def _dicyclic(n, axis):
    """Cn plus n half turns about axes perpendicular to `axis`, πk/n apart."""
    theta = np.linspace(0, np.pi, n, endpoint=False)
    rotvec = np.zeros((n, 3))
    rotvec[:, (axis + 1) % 3] = np.pi * np.cos(theta)
    rotvec[:, (axis + 2) % 3] = np.pi * np.sin(theta)
    return np.concatenate([_cyclic(n, axis), C.from_rotvec(rotvec)])


def group_quats(symbol, order=1, axis=2):
    """Unit quaternions (n, 4), scalar-first, of the group `symbol` in 'IOTCD'.

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
