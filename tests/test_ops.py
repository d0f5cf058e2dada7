"""The arithmetic formulas are written in (`quatarray._ops`): a formula compiled for Python
floats gives the bits of the same formula run operation by operation on `FLOATS`."""

import math
from types import SimpleNamespace

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
        w, x, y, z = (q / np.linalg.norm(q)).tolist()
        w2, v2 = _convert._squares([w, x, y, z], _ops.FLOATS, _ops.FLOAT_STACKS, None, None)
        t = _convert._tan_half(w2, v2, _ops.FLOATS, None)
        want = _convert._rotvec(w, [x, y, z], t, math.sqrt(v2), 2.0, _ops.FLOATS, _ops.FLOAT_STACKS, None, _ops.NONE)
        assert _convert._ROTVEC_FLOATS[_ops.F64](w, x, y, z, 2.0) == want


def test_compiled_guard_returns_none_where_its_test_fails():
    """`op.guard` in a compiled formula: None where the test fails, before the steps after it
    (no division by zero), the formula's value elsewhere."""
    def f(op, stack, a, b):
        s = op.mul(a, a, None)
        op.guard("{0} > {1}", s, 1e-300)
        return op.div(b, s, None)
    g = _ops.compiled(f, 2)
    assert g(0.0, 1.0) is None and g(1e-200, 1.0) is None
    assert g(3.0, 2.0) == 2.0 / 9.0
    assert g.float32(np.float32(3.0), np.float32(2.0)) == np.float32(2.0) / np.float32(9.0)
    with pytest.raises(TypeError, match="may not branch"):
        _ops.compiled(lambda op, stack, a: op.where(True, a, a), 1)


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


def _float32_checks():
    """NumPy's ufuncs on float32 scalars (``FLOATS32``' and the compiled float32 scope's
    calls) against the float32 array loops, on a sample of every magnitude (signed zeros,
    subnormals, huge arguments too); and `_every_operation` compiled for float32 scalars
    against the same formula on `FLOATS32` and on float32 rows (`ARRAYS`).  Returns a report
    (the functions whose scalar and array bits differ, and whether the formulas agree)."""
    rng = np.random.default_rng(12)
    x = np.concatenate([rng.uniform(-3, 3, 3000), rng.standard_normal(3000) * 100,
                        2.0 ** rng.uniform(-149, 127, 3000) * rng.choice([-1, 1], 3000),
                        [0.0, -0.0, 1.0, -1.0, np.pi, 88.7, -104.0, 1e-45]]).astype(np.float32)
    y = rng.permutation(x)
    differ = []
    with np.errstate(all="ignore"):
        for name in ("exp", "log", "cos", "sin", "tan", "arctan", "sqrt", "rint", "arctan2", "power", "copysign"):
            f = getattr(np, name)
            args = (np.abs(x),) if name in ("log", "sqrt") else (x,)
            if name in ("arctan2", "power", "copysign"):
                args = (np.abs(x), y * np.float32(0.01)) if name == "power" else (x, y)
            one = (lambda a, b: _ops.FLOATS32.copysign(a, b, None)) if name == "copysign" else f   # (`_copysign32`)
            got = np.array([one(*a) for a in zip(*args)])
            if not (got.dtype == np.float32 and np.array_equal(got.view(np.int32), f(*args).view(np.int32))):
                differ.append(name)
    f = _ops.compiled(_every_operation, 3)
    a, b, c = (rng.standard_normal((3, 700)) * 10.0 ** rng.uniform(-15, 15, (3, 700))).astype(np.float32)
    arrays = SimpleNamespace(**{**vars(_ops.ARRAYS), "copy": lambda a, out: a.copy()})   # (new rows: no out)
    rows = [np.asarray(r).reshape(-1, a.size) for r in _every_operation(arrays, _ops.STACKS, a, b, c)]
    assert all(r.dtype == np.float32 for r in rows)
    rows = np.concatenate(rows).T
    same = True
    for i in range(a.size):
        got = f.float32(a[i], b[i], c[i])
        want = _every_operation(_ops.FLOATS32, _ops.FLOAT_STACKS, a[i], b[i], c[i])
        same &= all(type(v) is np.float32 for v in got) and got == want
        same &= np.array_equal(np.array(got).view(np.int32), rows[i].view(np.int32))
    return {"svml": _ops.SVML, "differ": differ, "formula": bool(same)}


def test_float32_scalars_have_the_float32_loops_bits():
    assert _float32_checks() == {"svml": _ops.SVML, "differ": [], "formula": True}


def test_float32_scalars_without_avx512():
    """The same with NumPy's AVX-512 loops switched off (``NPY_DISABLE_CPU_FEATURES``),
    where NumPy runs other float32 loops and `_kernels.arctan2` its ratio route: the scalar
    calls follow the loops, and one float32 rotation's Euler angles, log and power keep
    the batch's bits."""
    code = ("import json, numpy as np, tests.test_ops as t\n"
            "from quatarray import QuatArray, Rotation, slerp\n"
            "q = (Rotation.random(300, rng=4).as_quat(scalar_first=True)\n"
            "     * np.linspace(0.5, 3.0, 300)[:, None]).astype(np.float32)\n"
            "q[::7, 0] = 1e-4\n"
            "P, Q = QuatArray(q[::-1]), QuatArray(q)\n"
            "ops = {'as_euler': lambda x, y: x.as_euler('xyz'),\n"
            "       'as_davenport': lambda x, y: x.as_davenport([[0, 0, 1], [1, 0, 0], [0, 1, 0]], 'e'),\n"
            "       'log': lambda x, y: x.log(), 'power': lambda x, y: x ** 0.3, 'exp': lambda x, y: x.exp(),\n"
            "       'as_rotvec': lambda x, y: x.as_rotvec(), 'slerp': lambda x, y: slerp(x, y, 0.3)}\n"
            "report = t._float32_checks()\n"
            "for name, f in ops.items():\n"
            "    whole = np.asarray(f(Q, P))\n"
            "    report[name] = all(np.array_equal(np.asarray(f(Q[i], P[i])), whole[i]) for i in range(300))\n"
            "print(json.dumps(report))\n")
    assert _without_avx512(code) == {"svml": False, "differ": [], "formula": True, "as_euler": True,
                                     "as_davenport": True, "log": True, "power": True, "exp": True,
                                     "as_rotvec": True, "slerp": True}


def _without_avx512(code):
    """The JSON report that Python `code` prints last, run from the repository in a new
    process with NumPy's AVX-512 loops switched off (``NPY_DISABLE_CPU_FEATURES``, where
    this CPU has them)."""
    import json
    import os
    import subprocess
    import sys
    env = dict(os.environ)
    if _ops.SVML:
        env["NPY_DISABLE_CPU_FEATURES"] = ("AVX512F AVX512CD AVX512_SKX AVX512_CLX AVX512_CNL AVX512_ICL "
                                           "AVX512_SPR X86_V4")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True,
                         cwd=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_branch_on_values_cannot_be_compiled():
    with pytest.raises(TypeError, match="may not branch on values"):
        _ops.compiled(lambda op, stack, a: op.where(a, a, a), 1)


def _arctan_checks():
    """What `arctan_float` must do on the CPU NumPy sees: the array loop's bits on a wide
    sample (signed zeros, subnormals, huge, infinite and NaN arguments too), and the C
    library's atan exactly where NumPy's loop is not SVML's.  Returns a report."""
    rng = np.random.default_rng(11)
    x = np.concatenate([rng.uniform(-3, 3, 20000), rng.standard_normal(20000) * 1e3,
                        10.0 ** rng.uniform(-320, 308, 20000) * rng.choice([-1, 1], 20000),
                        [0.0, -0.0, 5e-324, -5e-324, 1.0, -1.0, np.inf, -np.inf, np.nan]])
    want = np.arctan(x)
    got = np.array([_ops.arctan_float(v) for v in x.tolist()])
    same = bool(np.array_equal(got.view(np.int64)[:-1], want.view(np.int64)[:-1]) and np.isnan(got[-1]))
    return {"svml": _ops.SVML, "math": _ops.arctan_float is math.atan, "same": same}


def test_arctan_of_a_float_has_the_array_loops_bits():
    report = _arctan_checks()
    assert report["same"]
    assert report["math"] == (not report["svml"])


def test_arctan_of_a_float_without_svml(tmp_path):
    """With NumPy's AVX-512 loops switched off (``NPY_DISABLE_CPU_FEATURES``, where this CPU
    has them), NumPy's float64 arctan is the C library's atan, and `arctan_float` is
    ``math.atan`` with the same bits; as_euler of one rotation then keeps the batch's bits."""
    code = ("import json, numpy as np, tests.test_ops as t\n"
            "from quatarray import Rotation\n"
            "r = Rotation.random(200, rng=3)\n"
            "whole = r.as_euler('xyz')\n"
            "alone = np.array([r[i].as_euler('xyz') for i in range(200)])\n"
            "report = t._arctan_checks()\n"
            "report['euler'] = bool(np.array_equal(whole, alone))\n"
            "print(json.dumps(report))\n")
    assert _without_avx512(code) == {"svml": False, "math": True, "same": True, "euler": True}
