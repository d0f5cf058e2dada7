"""The arithmetic formulas are written in (`quatarray._ops`): a formula compiled for Python
floats gives the bits of the same formula run operation by operation on `FLOATS`."""

import math

import numpy as np
import pytest

from quatarray import _convert, _kernels, _ops


def _every_operation(op, stack, a, b, c):
    s = op.add(a, b, None)
    d = op.div(op.sub(s, c, None), op.max(op.abs(c, None), 1e-300, None), None)
    t = op.copysign(op.sqrt(op.mul(s, s, None), None), d, None)
    u = op.arctan(op.rint(op.mul(t, 10.0, None), None), None)
    return [op.copy(u, None), d, *stack.scale([a, b, c], t, None), *stack.sub([a, b], [c, s], None)]


def test_compiled_formula_gives_the_floats_bits():
    rng = np.random.default_rng(5)
    f = _ops.compiled(_every_operation, 3)
    for a, b, c in rng.standard_normal((500, 3)) * 10.0 ** rng.integers(-100, 100, (500, 1)):
        got, want = f(a.item(), b.item(), c.item()), _every_operation(_ops.FLOATS, _ops.FLOAT_STACKS,
                                                                     a.item(), b.item(), c.item())
        assert [math.copysign(1, x) for x in got] == [math.copysign(1, x) for x in want]
        assert got == want


def test_compiled_rotvec_is_the_formula_on_floats():
    rng = np.random.default_rng(6)
    for q in rng.standard_normal((500, 4)):
        w, x, y, z, t, nv = _convert._half_turn_floats(q / np.linalg.norm(q))
        want = _convert._rotvec(w, [x, y, z], t, nv, 2.0, _ops.FLOATS, _ops.FLOAT_STACKS, None, _ops.NONE)
        assert _convert._rotvec_floats(w, x, y, z, t, nv, 2.0) == want


def test_compiled_rows_of_three_are_float_rows():
    """A formula on rows of three (lists, a float applying to every element, cyclic shifts)
    compiled gives `FLOAT_ROWS`' bits: the rotation of a vector, with signed zeros."""
    rng = np.random.default_rng(7)
    for i, c in enumerate(rng.standard_normal((2000, 8)) * 10.0 ** rng.integers(-20, 20, (2000, 1))):
        w, x, y, z, ux, uy, uz, s = c.tolist()
        if i % 4 == 0:
            x, uy = -0.0, 0.0
        want = _kernels._rotated(w, [y, z, x], [z, x, y], [ux, uy, uz], [uy, uz, ux], [uz, ux, uy], s,
                                 _ops.FLOAT_ROWS, None, _ops.NONE, None, None)
        got = _kernels._rotated_floats(w, x, y, z, ux, uy, uz, s)
        assert [math.copysign(1, v) for v in got] == [math.copysign(1, v) for v in want]
        assert got == want


def test_a_branch_on_values_cannot_be_compiled():
    with pytest.raises(TypeError, match="may not branch on values"):
        _ops.compiled(lambda op, stack, a: op.where(a, a, a), 1)
