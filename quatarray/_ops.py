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
"""

import functools
import math
from types import SimpleNamespace

import numpy as np


def _numpy_svml():
    """True when NumPy runs its float64 transcendental loops (tan, arctan, ...) as SVML's
    SIMD loops (AVX-512 builds): read from NumPy's public build and runtime report,
    ``numpy.show_config(mode="dicts")`` (the CPU features NumPy found, as
    ``numpy.show_runtime`` prints them); False where that report has no such entry (NumPy
    before 1.26)."""
    try:
        found = np.show_config(mode="dicts")["SIMD Extensions"]["found"]
    except (TypeError, KeyError, AttributeError):
        return False
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
                         abs=np.absolute, copysign=np.copysign, rint=np.rint, arctan=np.arctan,
                         copy=lambda a, out: np.copyto(out, a) or out,
                         exp=np.exp, log=np.log, cos=np.cos, sin=np.sin, power=np.power)
"""Each operation writes into its last argument (a row of the block) and returns it;
``where(c, a, b)`` picks by a condition."""


def _numpy_float(f):
    """NumPy's ufunc `f` on Python floats, as a float: the bits of its array loops (checked for
    exp, log, cos, sin, tan, arctan and power, with and without AVX-512, on rows of one, two and
    thousands of elements), at the cost of one NumPy call each."""
    return lambda *args: float(f(*args))


_NUMPY_FLOATS = {name: _numpy_float(getattr(np, name)) for name in ("exp", "log", "cos", "sin", "power")}

FLOATS = SimpleNamespace(add=lambda a, b, out: a + b, sub=lambda a, b, out: a - b,
                         mul=lambda a, b, out: a * b, div=lambda a, b, out: a / b,
                         sqrt=lambda a, out: math.sqrt(a), where=lambda c, a, b: a if c else b,
                         max=lambda a, b, out: max(a, b), abs=lambda a, out: abs(a),
                         copysign=lambda a, b, out: math.copysign(a, b), copy=lambda a, out: a,
                         rint=lambda a, out: float(round(a)),   # round: half to even, as np.rint
                         arctan=lambda a, out: arctan_float(a),   # the array loop's bits
                         exp=lambda a, out: _NUMPY_FLOATS["exp"](a), log=lambda a, out: _NUMPY_FLOATS["log"](a),
                         cos=lambda a, out: _NUMPY_FLOATS["cos"](a), sin=lambda a, out: _NUMPY_FLOATS["sin"](a),
                         power=lambda a, b, out: _NUMPY_FLOATS["power"](a, b))
"""The same operations on Python floats; the row argument is ignored.  ``arctan`` is
`arctan_float`, with the bits of NumPy's array loop."""

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
              "rint": "float(round({0}))", "arctan": "_arctan({0})",
              **{name: f"_np_{name}({{0}})" for name in ("exp", "log", "cos", "sin")}, "power": "_np_power({0}, {1})"}
"""`FLOATS`' operations as Python expressions (the same calls and operators, in place)."""


def _pairs(a, b):
    """The element pairs of two lists, or of a list and one value (applied to every element)."""
    if type(a) is list:
        return zip(a, b) if type(b) is list else ((x, b) for x in a)
    return ((a, y) for y in b)


def compiled(formula, nargs):
    """`formula` (a function ``formula(op, stack, *floats)`` written over `ARRAYS`' names,
    with no branch on values) as a plain Python function of `nargs` floats: the formula is
    run once on names, each operation recorded as the expression `FLOATS` evaluates, and
    the statements compiled.  `stack` does what `FLOAT_STACKS` and `FLOAT_ROWS` do on lists
    (element by element, a single value applying to every element; ``scale``, ``shifts``,
    ``interleave``).
    The result has their and `FLOATS`' bits (the same operations on the same operands, in
    the same order) without a call per operation: a third of the cost of a single
    rotation's formula on `FLOATS`.

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

    def emit(name):
        template = _TEMPLATES[name]

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

    trace = SimpleNamespace(**{name: emit(name) for name in _TEMPLATES}, copy=lambda a, out: a, where=raise_)
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
    scope = {"_sqrt": math.sqrt, "_copysign": math.copysign, "_arctan": arctan_float,
             **{f"_np_{name}": f for name, f in _NUMPY_FLOATS.items()}, **consts}
    exec(compile(source, f"<compiled {formula.__module__}.{formula.__qualname__}>", "exec"), scope)
    function = scope["formula"]
    function.source = source
    return function


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


def to_array(values, shape):
    """A float path's result, `values` (Python floats), as a float64 array of `shape`.

    One row, (k,), is ``np.array``; a batch of one, (1, k), an empty array whose elements
    are assigned (half the cost of ``np.array([values])`` or of reshaping); anything else
    is ``np.array`` reshaped.

    >>> from quatarray._ops import to_array
    >>> to_array([1.0, 2.0, 3.0], (1, 3))
    array([[1., 2., 3.]])
    """
    n = len(shape)
    if n == 1:
        return np.array(values)
    if n == 2 and shape[0] == 1:
        a = np.empty(shape)
        k = len(values)
        if k == 3:
            a[0, 0], a[0, 1], a[0, 2] = values
        elif k == 4:
            a[0, 0], a[0, 1], a[0, 2], a[0, 3] = values
        else:
            a[0] = values
        return a
    return np.array(values).reshape(shape)
