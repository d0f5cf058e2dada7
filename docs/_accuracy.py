"""Measure quatarray's float64 accuracy in ulp against 50-digit references (mpmath),
with scipy's on the same inputs where scipy has the operation.

Run ``python docs/_accuracy.py`` for the table; the docs build runs it too
(``guide/accuracy.rst`` includes the table it writes), so the figures follow the code.

Error measure ("normwise ulp"): for each result, ``max |x - x_ref|`` over its components
divided by ``spacing(‖x_ref‖)``, the float64 spacing at the size of the whole result
(1 ulp of 1.0 for a unit quaternion or a rotation matrix). Components near zero thus
count at the scale of the result, as they would in any later use of it. Quaternion
results are compared up to sign (q and -q are the same rotation).
"""

import numpy as np

DIGITS = 50


def _data(n, rng):
    """Unit quaternions: n generic (uniform on the sphere) and n near the identity
    (rotation angles log-uniform in [1e-9, 1e-2] rad), scalar-first float64."""
    generic = rng.normal(size=(n, 4))
    generic /= np.linalg.norm(generic, axis=1, keepdims=True)
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    angle = 10.0 ** rng.uniform(-9, -2, size=n)
    small = np.concatenate([np.cos(angle / 2)[:, None], np.sin(angle / 2)[:, None] * axis], axis=1)
    return {"generic": generic, "near identity": small}


# ---- 50-digit references (mpmath), one sample at a time -----------------------

def _refs():
    import mpmath as mp
    mp.mp.dps = DIGITS
    M = mp.mpf

    def qmul(p, q):
        a, b, c, d = p
        e, f, g, h = q
        return [a * e - b * f - c * g - d * h, a * f + b * e + c * h - d * g,
                a * g - b * h + c * e + d * f, a * h + b * g - c * f + d * e]

    def conj(q):
        return [q[0], -q[1], -q[2], -q[3]]

    def rotate(q, v):
        n2 = sum(x * x for x in q)
        r = qmul(qmul(q, [M(0)] + list(v)), conj(q))
        return [x / n2 for x in r[1:]]

    def vnorm(v):
        return mp.sqrt(sum(x * x for x in v))

    def exp(q):
        vn = vnorm(q[1:])
        e = mp.exp(q[0])
        s = mp.sin(vn) / vn if vn != 0 else M(1)
        return [e * mp.cos(vn)] + [e * s * x for x in q[1:]]

    def log(q):
        vn = vnorm(q[1:])
        qn = mp.sqrt(q[0] ** 2 + vn ** 2)
        s = mp.atan2(vn, q[0]) / vn if vn != 0 else 1 / qn
        return [mp.log(qn)] + [s * x for x in q[1:]]

    def slerp(p, q, t):
        if sum(a * b for a, b in zip(p, q)) < 0:
            q = [-x for x in q]
        # the angle of the actual (not exactly unit) inputs: acos of their dot product
        # would add the inputs' norm error, amplified near zero angle
        om = 2 * mp.atan2(vnorm([b - a for a, b in zip(p, q)]), vnorm([a + b for a, b in zip(p, q)]))
        if om == 0:
            return list(p)
        return [(mp.sin((1 - t) * om) * a + mp.sin(t * om) * b) / mp.sin(om) for a, b in zip(p, q)]

    def as_matrix(q):
        n = vnorm(q)
        w, x, y, z = (c / n for c in q)
        return [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
                2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]

    def as_rotvec(q):
        if q[0] < 0:
            q = [-c for c in q]
        vn = vnorm(q[1:])
        if vn == 0:
            return [M(0)] * 3
        return [2 * mp.atan2(vn, q[0]) / vn * x for x in q[1:]]

    def from_rotvec(v):
        th = vnorm(v)
        s = mp.sin(th / 2) / th if th != 0 else M(1) / 2
        return [mp.cos(th / 2)] + [s * x for x in v]

    def from_euler_xyz(a):       # extrinsic x, then y, then z: q = qz qy qx
        qs = [[mp.cos(t / 2)] + [mp.sin(t / 2) if i == k else M(0) for i in range(3)]
              for k, t in enumerate(a)]
        return qmul(qs[2], qmul(qs[1], qs[0]))

    return dict(mp=mp, qmul=qmul, rotate=rotate, exp=exp, log=log, slerp=slerp,
                as_matrix=as_matrix, as_rotvec=as_rotvec, from_rotvec=from_rotvec,
                from_euler_xyz=from_euler_xyz)


def _ulp(got, ref, quat=False):
    """Normwise ulp error per sample; `ref` is a list of lists of mpf."""
    import mpmath as mp
    got = np.asarray(got, dtype=np.float64).reshape(len(ref), -1)
    errs = np.empty(len(ref))
    for i, (g, r) in enumerate(zip(got, ref)):
        rn = mp.sqrt(sum(x * x for x in r))
        best = None
        for sign in ((1, -1) if quat else (1,)):
            e = max(abs(mp.mpf(float(sign * gx)) - rx) for gx, rx in zip(g, r))
            best = e if best is None else min(best, e)
        errs[i] = float(best) / np.spacing(float(rn)) if rn != 0 else float(best) / np.spacing(1.0)
    return errs


def measure(n=400, seed=0):
    """[(operation, data set, quatarray (median, max), scipy (median, max) or None)]."""
    from scipy.spatial.transform import Rotation as SR

    from quatarray import QuatArray, Rotation, slerp

    R = _refs()
    mp = R["mp"]
    rng = np.random.default_rng(seed)
    rows = []

    def mpq(a):
        return [[mp.mpf(float(x)) for x in row] for row in np.asarray(a).reshape(len(a), -1)]

    def last(q):                 # scalar-first -> scalar-last
        return np.roll(q, -1, axis=-1)

    def first(q):
        return np.roll(np.asarray(q), 1, axis=-1)

    def add(op, data, ref, ours, theirs=None, quat=False):
        e = _ulp(ours, ref, quat)
        s = _ulp(theirs, ref, quat) if theirs is not None else None
        rows.append((op, data, (np.median(e), e.max()), None if s is None else (np.median(s), s.max())))

    for data, q in _data(n, rng).items():
        p = _data(n, rng)[data]
        mq, mpp = mpq(q), mpq(p)
        Q, P = QuatArray(q), QuatArray(p)
        v = rng.normal(size=(n, 3))
        t = rng.uniform(0, 1, size=n)
        if data == "generic":
            add("product p q", data, [R["qmul"](a, b) for a, b in zip(mpp, mq)], P * Q,
                first((SR.from_quat(last(p)) * SR.from_quat(last(q))).as_quat()), quat=True)
            add("rotate / apply", data, [R["rotate"](a, b) for a, b in zip(mq, mpq(v))],
                Q.rotate(v), SR.from_quat(last(q)).apply(v))
            g = rng.normal(size=(n, 4))
            add("exp (any quaternion)", data, [R["exp"](a) for a in mpq(g)], QuatArray(g).exp())
            add("as_matrix", data, [R["as_matrix"](a) for a in mq],
                Rotation.from_quat(last(q)).as_matrix(), SR.from_quat(last(q)).as_matrix())
            m = np.array([[float(x) for x in R["as_matrix"](a)] for a in mq]).reshape(n, 3, 3)
            add("from_matrix (rounded exact matrix)", data, mq,
                first(Rotation.from_matrix(m).as_quat()), first(SR.from_matrix(m).as_quat()), quat=True)
            ang = rng.uniform(-np.pi, np.pi, size=(n, 3))
            add("from_euler('xyz')", data, [R["from_euler_xyz"](a) for a in mpq(ang)],
                first(Rotation.from_euler("xyz", ang).as_quat()),
                first(SR.from_euler("xyz", ang).as_quat()), quat=True)
        add("log", data, [R["log"](a) for a in mq], Q.log())
        add("log, vector part", data, [R["log"](a)[1:] for a in mq], Q.log().vec)
        add("slerp(p, q, t)", data, [R["slerp"](a, b, mp.mpf(float(s))) for a, b, s in zip(mpp, mq, t)],
            slerp(P, Q, t), quat=True)
        add("slerp(1, q, t)", data, [R["slerp"](mpq([[1, 0, 0, 0]])[0], b, mp.mpf(float(s)))
                                     for b, s in zip(mq, t)],
            slerp(QuatArray([1.0, 0, 0, 0]), Q, t), quat=True)
        add("as_rotvec", data, [R["as_rotvec"](a) for a in mq],
            Rotation.from_quat(last(q)).as_rotvec(), SR.from_quat(last(q)).as_rotvec())
        rv = np.asarray(Rotation.from_quat(last(q)).as_rotvec())
        add("from_rotvec", data, [R["from_rotvec"](a) for a in mpq(rv)],
            first(Rotation.from_rotvec(rv).as_quat()), first(SR.from_rotvec(rv).as_quat()), quat=True)
    return rows


def rst_table(rows, n):
    import platform

    import scipy

    import quatarray
    from quatarray import _ops
    fmt = "{:.1f}".format
    out = [".. list-table::", "   :header-rows: 1", "",
           "   * - operation", "     - data", "     - quatarray median", "     - quatarray max",
           "     - scipy median", "     - scipy max"]
    for op, data, ours, theirs in rows:
        out += [f"   * - {op}", f"     - {data}", f"     - {fmt(ours[0])}", f"     - {fmt(ours[1])}",
                f"     - {fmt(theirs[0]) if theirs else '—'}", f"     - {fmt(theirs[1]) if theirs else '—'}"]
    worst = [(op, data, ours[1]) for op, data, ours, _ in rows if ours[1] > 10]
    if worst:
        listed = "; ".join(f"{op} ({data}): {m:.3g} ulp" for op, data, m in worst)
        out += ["", f"Rows above 10 ulp at their maximum: {listed}."]
    else:
        out += ["", f"Every row is within {max(r[2][1] for r in rows):.1f} ulp at its maximum."]
    out += ["", f"{n} samples per row; quatarray {quatarray.__version__}, NumPy {np.__version__}, "
            f"scipy {scipy.__version__}, Python {platform.python_version()}, {platform.machine()}, "
            f"NumPy SIMD level {_ops.numpy_simd_level()}; references with mpmath at {DIGITS} digits.", ""]
    return "\n".join(out)


if __name__ == "__main__":
    import sys
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 400
    print(rst_table(measure(n), n))
