"""The arithmetic a formula is written in, for blocks of arrays and for Python floats.

A formula written over components with these operations (``op.mul(a, b, out)``) runs on
a block's rows, where each operation is the ufunc writing into its preallocated row, and on
the four Python floats of one float64 rotation, where the row is ignored and the value is
returned.  ``+ − × ÷`` and ``sqrt`` round alike on floats and float64 arrays (IEEE, no fused
multiply-add in either), so one formula evaluated in one order gives the same bits on both:
a single rotation skips the 16–60 ufunc calls of the block kernel without a second copy of
its maths.  Functions whose results differ between `math` and NumPy (atan2, sin, ...) are
not offered on floats as `math`'s; ``arctan`` has the bits of NumPy's loop (`arctan_float`), and
``exp``, ``log``, ``cos``, ``sin`` and ``power`` are NumPy's own ufuncs called on the floats.
`compiled` turns such a formula into plain Python statements on floats, once: the same
operations in the same order, without a call per operation.

One float32 quaternion runs the same statements on NumPy float32 scalars (`floats32`,
`FLOATS32`, a compiled formula's ``float32``): their ``+ − × ÷`` round as float32 rows
do, and NumPy's ufuncs on a float32 scalar give the bits of its float32 array loop.
"""

import functools
import math
from types import SimpleNamespace

import numpy as np


def numpy_simd_found():
    """The SIMD extensions NumPy dispatches to on this CPU beyond its build's baseline (for
    example ``['X86_V3', 'X86_V4', 'AVX512_ICL']``), from NumPy's public build and runtime
    report, ``numpy.show_config(mode="dicts")`` (as ``numpy.show_runtime`` prints them);
    ``[]`` where that report has no such entry (NumPy before 1.26)."""
    try:
        return list(np.show_config(mode="dicts")["SIMD Extensions"]["found"])
    except (TypeError, KeyError, AttributeError):
        return []


def numpy_simd_level():
    """NumPy's x86-64 SIMD level on this CPU, for reports: ``"X86_V4 (AVX-512)"``,
    ``"X86_V3 (AVX2)"``, else the last extension found, else ``"baseline"``."""
    found = numpy_simd_found()
    if "X86_V4" in found:
        return "X86_V4 (AVX-512)"
    if "X86_V3" in found:
        return "X86_V3 (AVX2)"
    return found[-1] if found else "baseline"


def _numpy_svml():
    """True when NumPy runs its float64 transcendental loops (tan, arctan, ...) as SVML's
    SIMD loops (AVX-512 builds)."""
    found = numpy_simd_found()
    return "AVX512_SKX" in found or "X86_V4" in found


#: NumPy's float64 tangent and arctangent are SVML's SIMD loops on this CPU.
SVML = _numpy_svml()

_ATAN_SAMPLE = [math.ldexp(k + 0.5, e) for e in range(-30, 31, 3) for k in range(1, 17)]


def _arctan_float():
    """`arctan_float`'s function: math.atan where NumPy's float64 arctan loop is the C
    library's atan (no SVML; checked on a sample), else NumPy's loop on the float."""
    if not SVML and np.arctan(_ATAN_SAMPLE).tolist() == [math.atan(x) for x in _ATAN_SAMPLE]:
        return math.atan
    return lambda x: float(np.arctan(x))


arctan_float = _arctan_float()
"""arctan of one Python float with the bits of NumPy's float64 array loop: there the C
library's atan on CPUs without SVML (``math.atan``: 0.05 µs, against 0.4 for a NumPy call
on a float), NumPy's own loop on the float where it is SVML's (AVX-512), which differs
from the C library's in about 1 case in 1000."""

ARRAYS = SimpleNamespace(add=np.add, sub=np.subtract, mul=np.multiply, div=np.divide, sqrt=np.sqrt,
                         where=np.where, max=lambda a, b, out: np.maximum(a, b, out=out),
                         min=lambda a, b, out: np.minimum(a, b, out=out),
                         add_where=lambda a, b, where, out: np.add(a, b, out=out, where=where),
                         abs=np.absolute, copysign=np.copysign, rint=np.rint, arctan=np.arctan,
                         copy=lambda a, out: np.copyto(out, a) or out,
                         exp=np.exp, log=np.log, cos=np.cos, sin=np.sin, power=np.power)
"""Each operation writes into its last argument (a row of the block) and returns it;
``where(c, a, b)`` picks by a condition; ``add_where(a, b, mask, out)`` adds where mask
(rows only: one float's formula has no mask)."""


def _numpy_float(f):
    """NumPy's ufunc `f` on Python floats, as a float: the bits of its array loops (checked for
    exp, log, cos, sin, tan, arctan and power, with and without AVX-512, on rows of one, two and
    thousands of elements), at the cost of one NumPy call each."""
    return lambda *args: float(f(*args))


_NUMPY_FLOATS = {name: _numpy_float(getattr(np, name)) for name in ("exp", "log", "cos", "sin", "power")}

FLOATS = SimpleNamespace(add=lambda a, b, out: a + b, sub=lambda a, b, out: a - b,
                         mul=lambda a, b, out: a * b, div=lambda a, b, out: a / b,
                         sqrt=lambda a, out: math.sqrt(a), where=lambda c, a, b: a if c else b,
                         max=lambda a, b, out: max(a, b), min=lambda a, b, out: min(a, b),
                         abs=lambda a, out: abs(a),
                         copysign=lambda a, b, out: math.copysign(a, b), copy=lambda a, out: a,
                         rint=lambda a, out: float(round(a)),   # round: half to even, as np.rint
                         arctan=lambda a, out: arctan_float(a),   # the array loop's bits
                         exp=lambda a, out: _NUMPY_FLOATS["exp"](a), log=lambda a, out: _NUMPY_FLOATS["log"](a),
                         cos=lambda a, out: _NUMPY_FLOATS["cos"](a), sin=lambda a, out: _NUMPY_FLOATS["sin"](a),
                         power=lambda a, b, out: _NUMPY_FLOATS["power"](a, b))
"""The same operations on Python floats; the row argument is ignored.  ``arctan`` is
`arctan_float`, with the bits of NumPy's array loop."""

def _copysign32(a, b):
    """``np.copysign(a, b)`` of float32 scalars (|a| with b's sign bit, -0.0 included) at a
    third of the cost of NumPy's call on scalars."""
    return -abs(a) if math.copysign(1.0, b) < 0 else abs(a)


FLOATS32 = SimpleNamespace(**{**vars(FLOATS), "sqrt": lambda a, out: np.sqrt(a),
                              "copysign": lambda a, b, out: _copysign32(a, b), "rint": lambda a, out: np.rint(a),
                              **{name: (lambda f: lambda *args: f(*args[:-1]))(getattr(np, name))
                                 for name in ("arctan", "exp", "log", "cos", "sin", "power")}})
"""`FLOATS` on NumPy float32 scalars (``np.float32``), the four components of one float32
quaternion: their ``+ − × ÷`` round as float32 (a Python float operand is weak, NEP 50:
taken as float32 too), and NumPy's ufuncs on them (sqrt, arctan, exp, log, cos, sin,
power) return float32 scalars with the float32 array loops' bits (checked with and
without AVX-512 on samples of every magnitude, tests/test_ops.py); copysign is
`_copysign32`, the same bits."""

STACKS = SimpleNamespace(
    sub=lambda a, b, out: np.subtract(a, b, out=out, order="C"),
    add=lambda a, b, out: np.add(a, b, out=out, order="C"),
    mul=lambda a, b, out: np.multiply(a, b, out=out, order="C"),
    scale=lambda a, x, out: np.multiply(a, x, out=out, order="C"),
    div=lambda a, x, out: np.divide(a, x, out=out, order="C"),
    interleave=lambda a, b, out: out)
"""`ARRAYS`' operations on stacks of k rows (k, ...), one call for the stack: ``a - b``,
``a + b``, ``a * b`` element by element, ``scale(a, x)`` each row times the row `x`,
``div(a, x)`` each row over the row `x`;
``interleave(a, b, out)`` the rows of `a` and `b` alternately, where they were written into
`out`'s even and odd rows.
Iterated in C order, row after row: stacks may be component-major views of (n, k)
arrays (e.g. ``o.T``), which NumPy's default order would walk in n inner loops of k."""

FLOAT_STACKS = SimpleNamespace(
    sub=lambda a, b, out: [x - y for x, y in zip(a, b)], add=lambda a, b, out: [x + y for x, y in zip(a, b)],
    mul=lambda a, b, out: [x * y for x, y in zip(a, b)], scale=lambda a, x, out: [v * x for v in a],
    div=lambda a, x, out: [v / x for v in a],
    interleave=lambda a, b, out: [x for pair in zip(a, b) for x in pair])
"""The same on lists of k Python floats (the stack argument is ignored)."""


def _rows_add(a, b, out=None):
    """``a + b`` element by element on rows of three floats (lists; a float operand applies
    to every element)."""
    if type(a) is list:
        if type(b) is list:
            return [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
        return [a[0] + b, a[1] + b, a[2] + b]
    return [a + b[0], a + b[1], a + b[2]]


def _rows_sub(a, b, out=None):
    """``a - b``, as `_rows_add`."""
    if type(a) is list:
        if type(b) is list:
            return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
        return [a[0] - b, a[1] - b, a[2] - b]
    return [a - b[0], a - b[1], a - b[2]]


def _rows_mul(a, b, out=None):
    """``a * b``, as `_rows_add`."""
    if type(a) is list:
        if type(b) is list:
            return [a[0] * b[0], a[1] * b[1], a[2] * b[2]]
        return [a[0] * b, a[1] * b, a[2] * b]
    return [a * b[0], a * b[1], a * b[2]]


ARRAYS.shifts = lambda row, rows: (np.copyto(rows[3:], rows[:2]), rows[1:4], rows[2:5])[1:]
"""``ARRAYS.shifts(t, rows)``: the cyclic shifts ``(t1, t2, t0)`` and ``(t2, t0, t1)`` of
the three rows ``t = rows[:3]``, as views of `rows` (five rows) after copying ``t0, t1``
into its last two."""


def _component_rows(f):
    """The ufunc `f` on rows of three given as lists of three arrays, one call per component
    (a single array operand applies to every component), into the list `out`."""
    def op(a, b, out):
        if type(a) is list:
            if type(b) is list:
                return [f(a[0], b[0], out[0]), f(a[1], b[1], out[1]), f(a[2], b[2], out[2])]
            return [f(a[0], b, out[0]), f(a[1], b, out[1]), f(a[2], b, out[2])]
        return [f(a, b[0], out[0]), f(a, b[1], out[1]), f(a, b[2], out[2])]
    return op


ARRAY_ROWS = SimpleNamespace(add=_component_rows(np.add), sub=_component_rows(np.subtract),
                             mul=_component_rows(np.multiply),
                             shifts=lambda row, rows: (row[1:] + row[:1], row[2:] + row[:2]))
"""`ARRAYS` on rows of three given as lists of three component rows: one call per component
(on long blocks, where stacking would first copy the rows into shifted layouts); the
shifts of a row are the same arrays in another order."""

FLOAT_ROWS = SimpleNamespace(add=_rows_add, sub=_rows_sub, mul=_rows_mul,
                             shifts=lambda row, rows: (row[1:] + row[:1], row[2:] + row[:2]))
"""`FLOATS` on rows of three of one rotation's components, lists of three Python floats
(formulas written on rows of three, e.g. a cross product as two products of shifted
rows): the same operations element by element; the row arguments are ignored."""

class _Name(str):
    """A traced float: the name of a local of the function `compiled` writes."""
    __slots__ = ()


_TEMPLATES = {"add": "{0} + {1}", "sub": "{0} - {1}", "mul": "{0} * {1}", "div": "{0} / {1}",
              "sqrt": "_sqrt({0})", "abs": "abs({0})", "copysign": "_copysign({0}, {1})", "max": "max({0}, {1})",
              "min": "min({0}, {1})",
              "rint": "_rint({0})", "arctan": "_arctan({0})",
              **{name: f"_np_{name}({{0}})" for name in ("exp", "log", "cos", "sin")}, "power": "_np_power({0}, {1})"}
"""`FLOATS`' operations as Python expressions (the same calls and operators, in place)."""


def _pairs(a, b):
    """The element pairs of two lists, or of a list and one value (applied to every element)."""
    if type(a) is list:
        return zip(a, b) if type(b) is list else ((x, b) for x in a)
    return ((a, y) for y in b)


def compiled(formula, nargs, calls=None):
    """`formula` (a function ``formula(op, stack, *floats)`` written over `ARRAYS`' names,
    with no branch on values) as a plain Python function of `nargs` floats: the formula is
    run once on names, each operation recorded as the expression `FLOATS` evaluates, and
    the statements compiled.  `stack` does what `FLOAT_STACKS` and `FLOAT_ROWS` do on lists
    (element by element, a single value applying to every element; ``scale``, ``shifts``,
    ``interleave``).
    The result has their and `FLOATS`' bits (the same operations on the same operands, in
    the same order) without a call per operation: a third of the cost of a single
    rotation's formula on `FLOATS`.  The same source is also defined on float32 scalars
    (`FLOATS32`' calls): the result's attribute ``float32``; ``kinds`` maps each `Kind` to
    its function (``f.kinds[F32] is f.float32``).

    `calls`: further operations the formula calls as ``op.name(*args, out)``, as
    ``{name: (number of args, function on Python floats, function on float32 scalars)}``.
    ``op.guard(test, *args)`` (compiled formulas only) makes the function return None
    unless the Python expression `test` holds, its ``{0}, {1}, ...`` the values `args`: a
    float path's range test between two steps of its formula, without a second call.

    >>> from quatarray._ops import FLOATS, FLOAT_STACKS, compiled
    >>> def f(op, stack, a, b):
    ...     s = op.add(a, b, None)
    ...     return [op.sqrt(s, None), *stack.scale([a, b], s, None)]
    >>> g = compiled(f, 2)
    >>> g(1.0, 3.0) == f(FLOATS, FLOAT_STACKS, 1.0, 3.0)
    True
    """
    lines, consts = [], {}

    def term(v):
        if type(v) is _Name:
            return v
        key = f"_c{len(consts)}"
        consts[key] = v
        return key

    def emit(name, template):
        def op(*args):
            v = _Name(f"v{len(lines)}")
            if name == "mul" and type(args[1]) is float and args[1] == -1.0:   # x · -1 is -x, to
                lines.append(f"    {v} = -{term(args[0])}")                     # the bit, without a
            else:                                                               # constant's lookup
                lines.append(f"    {v} = " + template.format(*map(term, args[:template.count("{")])))
            return v
        return op

    def raise_(*args):
        raise TypeError("a compiled formula may not branch on values (where)")

    def guard(test, *args):   # the function returns None unless `test` holds
        lines.append(f"    if not ({test.format(*map(term, args))}):\n        return None")

    calls = calls or {}
    templates = {**_TEMPLATES, **{name: f"_call_{name}(" + ", ".join(f"{{{i}}}" for i in range(n)) + ")"
                                  for name, (n, *_) in calls.items()}}
    trace = SimpleNamespace(**{name: emit(name, t) for name, t in templates.items()}, copy=lambda a, out: a, where=raise_,
                            guard=guard)
    elementwise = {name: (lambda f: lambda a, b, out: [f(x, y, None) for x, y in _pairs(a, b)])(getattr(trace, name))
                   for name in ("add", "sub", "mul", "div")}
    stack = SimpleNamespace(**elementwise, scale=elementwise["mul"], shifts=FLOAT_ROWS.shifts,
                            interleave=FLOAT_STACKS.interleave)
    names = [_Name(f"a{i}") for i in range(nargs)]
    result = formula(trace, stack, *names)
    if type(result) in (list, tuple):
        body = "[" + ", ".join(map(term, result)) + "]"
    else:
        body = term(result)
    source = f"def formula({', '.join(names)}):\n" + "\n".join(lines + [f"    return {body}"])
    code = compile(source, f"<compiled {formula.__module__}.{formula.__qualname__}>", "exec")
    scopes = [{**scope, **{f"_call_{name}": fs[k] for name, (_, *fs) in calls.items()}}
              for k, scope in enumerate((_SCOPE64, _SCOPE32))]
    function, function.float32 = (_defined(code, scope, consts) for scope in scopes)
    function.kinds = {F64: function, F32: function.float32}
    function.source = function.float32.source = source
    return function


def _defined(code, scope, consts):
    """The function the compiled `code` defines, run with the names of `scope` and `consts`."""
    scope = {**scope, **consts}
    exec(code, scope)
    return scope["formula"]


_SCOPE64 = {"_sqrt": math.sqrt, "_copysign": math.copysign, "_arctan": arctan_float,
            "_rint": lambda a: float(round(a)),   # round: half to even, as np.rint
            **{f"_np_{name}": f for name, f in _NUMPY_FLOATS.items()}}
"""The calls of `compiled`'s source on Python floats (`FLOATS`')."""

_SCOPE32 = {"_sqrt": np.sqrt, "_copysign": _copysign32, "_arctan": np.arctan, "_rint": np.rint,
            **{f"_np_{name}": getattr(np, name) for name in _NUMPY_FLOATS}}
"""The same calls on float32 scalars (`FLOATS32`'): NumPy's ufuncs (copysign: its bits),
returning float32 scalars.  The formula's constants stay Python floats, weak operands
taken as float32."""


NONE = (None,) * 16
"""Rows for `FLOATS` (any number up to 16): the results are returned, not written."""


def const(value, dtype):
    """`value` as a 0-d array of `dtype`, made once: a ufunc call with a Python or NumPy
    scalar operand pays about 0.4 µs to convert it (NumPy 2.4), the cost of the whole call
    on a small array; a 0-d array of the operand's dtype computes the same (a weak Python
    scalar takes the array's dtype too) without that cost.

    >>> import numpy as np
    >>> from quatarray._ops import const
    >>> const(0.5, np.float32)
    array(0.5, dtype=float32)
    """
    key = (value, dtype)
    c = _CONSTS.get(key)
    if c is None:
        c = _CONSTS[key] = np.array(value, dtype)
        c.flags.writeable = False
    return c


_CONSTS = {}


@functools.lru_cache(maxsize=16)
def row(value, dtype, shape):
    """`value` as a read-only array of `shape` and `dtype`, made once for the few block shapes
    a program uses: ``np.maximum`` with a scalar operand runs NumPy's scalar loop (0.48 ns
    an element at 32768, AVX-512), with an array of the block's shape the SIMD one (0.10).

    >>> import numpy as np
    >>> from quatarray._ops import row
    >>> row(0.5, np.dtype(np.float32), (2,))
    array([0.5, 0.5], dtype=float32)
    """
    r = np.full(shape, value, dtype)
    r.flags.writeable = False
    return r


def operands(*values):
    """The float64 constants `values` as operands of `ARRAYS` (0-d arrays, `const`) and of
    `FLOATS` (the floats themselves), indexed by ``op is FLOATS``: a formula written for
    both picks its constants with its namespace.

    >>> from quatarray._ops import FLOATS, operands
    >>> operands(0.5)[FLOATS is FLOATS]
    (0.5,)
    """
    return tuple(const(v, np.float64) for v in values), values


def floats64(q, k=4):
    """The `k` components of one float64 quaternion (or vector), shape (k,) or (1, k), as
    Python floats (so that a formula runs on `FLOATS`), or None for any other input (the
    block kernel's).  `q`'s last axis has length k (a validated array of quaternions or
    vectors: (k, 1) is not one).

    >>> import numpy as np
    >>> from quatarray._ops import floats64
    >>> floats64(np.array([1.0, 0, 0, 0])), floats64(np.ones((2, 4)))
    ([1.0, 0.0, 0.0, 0.0], None)
    """
    if q.size == k and q.dtype is _FLOAT64:   # `is`: a fifth of ==
        ndim = q.ndim
        if ndim == 1:
            return q.tolist()
        if ndim == 2:
            return q.tolist()[0]   # (1, k): half a reshape's cost
    return None


def first64(q, k=4):
    """The first component (w) of one float64 quaternion (or vector), `q` of shape (..., k)
    holding one, as a Python float, or None for any other input: for formulas whose other
    components enter as one array operation with that float (`floats64` without the list).

    >>> import numpy as np
    >>> from quatarray._ops import first64
    >>> first64(np.array([[0.5, 0, 0, 1]])), first64(np.ones((2, 4)))
    (0.5, None)
    """
    if q.size == k and q.dtype is _FLOAT64:
        return q.item(0)
    return None


_FLOAT64 = np.dtype(np.float64)   # NumPy's one native float64 dtype (another one: the block path)
_FLOAT32 = np.dtype(np.float32)


class Kind:
    """The arithmetic of one quaternion's components of a dtype, for the float paths.

    Attributes
    ----------
    dtype : numpy.dtype
        float64 (components as Python floats) or float32 (as ``np.float32`` scalars).
    op : SimpleNamespace
        `FLOATS` or `FLOATS32`.
    sqrt : callable
        ``math.sqrt`` or ``np.sqrt`` (a float32 scalar's, float32).
    name : str
        ``"float64"`` or ``"float32"``.

    A `compiled` formula's function for a kind is ``f.kinds[kind]``.
    """
    __slots__ = ("dtype", "op", "sqrt", "name")

    def __init__(self, dtype, op, sqrt):
        self.dtype, self.op, self.sqrt, self.name = np.dtype(dtype), op, sqrt, np.dtype(dtype).name

    def __repr__(self):
        return f"Kind({self.name})"


F64 = Kind(np.float64, FLOATS, math.sqrt)
F32 = Kind(np.float32, FLOATS32, np.sqrt)
KINDS = (F64, F32)


def by_kind(make):
    """``{kind: make(kind)}`` for both `KINDS`: a float path made once per kind, with its
    kind's compiled formulas, ranges and calls bound (no lookups per call: a single
    rotation's float path costs a few µs, where each lookup shows).

    >>> from quatarray._ops import F32, by_kind
    >>> by_kind(lambda kind: kind.name)[F32]
    'float32'
    """
    return {kind: make(kind) for kind in KINDS}


def floats32(q, k=4):
    """``(components, F32)`` of one float32 quaternion (or vector), `q` of shape (k,) or
    (1, k): `floats64` for float32, the components as NumPy float32 scalars (formulas then
    run on `FLOATS32`, compiled ones as ``f.kinds[F32]``); ``(None, None)`` for any other
    input, and for components of magnitude `_BOUND32` or more (or NaN).  Float paths call
    it where `floats64` gave None, as ``one, kind = floats64(q), F64`` then ``if one is
    None: one, kind = floats32(q)``: the float64 path pays no more than a name.

    >>> import numpy as np
    >>> from quatarray._ops import floats32
    >>> floats32(np.array([[1.0, 0, 0, 0]], np.float32))
    ([np.float32(1.0), np.float32(0.0), np.float32(0.0), np.float32(0.0)], Kind(float32))
    """
    if q.size == k and q.dtype is _FLOAT32:
        ndim = q.ndim
        if ndim == 2:
            q = q[0]
        elif ndim != 1:
            return None, None
        b = _BOUND32   # (tested on Python floats, NaN failing too: cheaper than on float32 scalars)
        if k == 4:
            w, x, y, z = q.tolist()
            if -b < w < b and -b < x < b and -b < y < b and -b < z < b:
                return [q[0], q[1], q[2], q[3]], F32   # (indexing: half list(q)'s cost)
        elif k == 3:
            x, y, z = q.tolist()
            if -b < x < b and -b < y < b and -b < z < b:
                return [q[0], q[1], q[2]], F32
        elif all(-b < v < b for v in q.tolist()):
            return [q[i] for i in range(k)], F32
    return None, None


_BOUND32 = 2.0 ** 60
"""`floats32` gives float32 components below it in magnitude only: their squares and products
of two stay far from overflow, which NumPy's float32 scalars would warn of (the block
kernels compute them under ``np.errstate`` and rescale; the float paths' own range tests
come after these products).  NaN and infinities give None too."""


def to_array(values, shape, dtype=_FLOAT64):
    """A float path's result, `values` (Python floats, or float32 scalars), as an array of
    `shape` and `dtype` (a `Kind`'s).

    One row, (k,), is ``np.array``; a batch of one, (1, k), an empty array whose elements
    are assigned (half the cost of ``np.array([values])`` or of reshaping); anything else
    is ``np.array`` reshaped.

    >>> from quatarray._ops import to_array
    >>> to_array([1.0, 2.0, 3.0], (1, 3))
    array([[1., 2., 3.]])
    """
    n = len(shape)
    if n == 1:
        return np.array(values) if dtype is _FLOAT64 else np.array(values, dtype)
    if n == 2 and shape[0] == 1:
        a = np.empty(shape, dtype)
        k = len(values)
        if k == 3:
            a[0, 0], a[0, 1], a[0, 2] = values
        elif k == 4:
            a[0, 0], a[0, 1], a[0, 2], a[0, 3] = values
        else:
            a[0] = values
        return a
    return np.array(values, dtype).reshape(shape)
