"""scipy's own rotation tests, run against quatarray.

The installed scipy's test files are copied to a temporary directory with
their imports swapped to quatarray and run by pytest in a subprocess.  Every
collected test must pass, except the ones listed in each entry's `deselect`;
a test may be listed only because it reaches into scipy's private backends
(``_rotation_cy``, ``_rotation_xp``, ``cython_backend``, ``xp_backend``) or
private attributes.

What the copy changes, and why no test is weakened:

* the ``from scipy.spatial.transform import ...`` line (each entry's
  `swaps`) import quatarray's classes instead;
* scipy's ``make_xp_test_case`` / ``make_xp_pytest_marks`` are replaced by
  no-ops before the file is imported: they look the tested methods up in
  scipy's array-API capability table when the module is imported (which fails
  for quatarray's methods) and only add skip marks for non-NumPy backends;
* an ``xp`` fixture returning NumPy stands in for scipy's conftest (whose
  default, without ``SCIPY_ARRAY_API=1``, is NumPy only as well).

To add a file, add an entry to `SUITES`.  Run this module with ``-s`` to see the counts.
"""

import json
import os
import re
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

SUITES = {
    "test_rotation.py": {
        "swaps": [("from scipy.spatial.transform import Rotation, Slerp",
                   "from quatarray import Rotation, Slerp")],
        "deselect": {
            # asserts `r._backend is cython_backend` / `xp_backend`: scipy's private
            # backend modules, which quatarray does not have
            "test_cython_backend_selection",
        },
    },
    "test_rotation_groups.py": {
        "swaps": [("from scipy.spatial.transform import Rotation\n", "from quatarray import Rotation\n")],
        "deselect": set(),
    },
    "test_rotation_spline.py": {
        "swaps": [
            ("from scipy.spatial.transform import Rotation, RotationSpline",
             "from quatarray import Rotation, RotationSpline"),
            # scipy's private maths helpers are public in quatarray.spline; the
            # matrix-vector product of stacks is a test utility (an einsum)
            ("""from scipy.spatial.transform._rotation_spline import (
    _angular_rate_to_rotvec_dot_matrix,
    _rotvec_dot_to_angular_rate_matrix,
    _matrix_vector_product_of_stacks,
    _angular_acceleration_nonlinear_term,
    _create_block_3_diagonal_matrix)""",
             """from quatarray.spline import (
    angular_rate_to_rotvec_dot_matrix as _angular_rate_to_rotvec_dot_matrix,
    rotvec_dot_to_angular_rate_matrix as _rotvec_dot_to_angular_rate_matrix,
    angular_acceleration_nonlinear_term as _angular_acceleration_nonlinear_term,
    block_tridiagonal_banded as _create_block_3_diagonal_matrix)


def _matrix_vector_product_of_stacks(A, b):
    return np.einsum("...ij,...j->...i", A, b)"""),
        ],
        "deselect": set(),
    },
    "test_rigid_transform.py": {
        "swaps": [
            ("from scipy.spatial.transform import Rotation, RigidTransform",
             "from quatarray import RigidTransform, Rotation"),
            # scipy's private helper, public in quatarray
            ("from scipy.spatial.transform._rigid_transform import normalize_dual_quaternion",
             "from quatarray import normalize_dual_quaternion"),
        ],
        "deselect": {
            # asserts isinstance(q._matrix, type(p._matrix)): scipy's private storage
            # attribute (quatarray stores a quaternion and a translation); the same
            # integer and fractional powers are checked in tests/test_rigid_transform.py
            "test_pow",
        },
        "deselected_items": 3,   # test_pow[1], [2], [3]
    },
}

CONFTEST = '''
import json
import numpy as np
import pytest
import scipy._lib._array_api as _xpapi

# scipy's capability decorators look the tested methods up in scipy's own
# table at import time; they only add skip marks for non-NumPy backends.
_xpapi.make_xp_test_case = lambda *funcs, **kwargs: (lambda f: f)
_xpapi.make_xp_pytest_marks = lambda *funcs, **kwargs: []

DESELECT = json.loads({deselect!r})


def pytest_configure(config):
    for name in ("skip_xp_backends", "xfail_xp_backends", "skip_xp_invalid_arg",
                 "array_api_backends", "thread_unsafe", "fail_slow", "slow"):
        config.addinivalue_line("markers", name + ": scipy's marker (no effect here)")


def pytest_collection_modifyitems(config, items):
    keep, drop = [], []
    for item in items:
        (drop if item.originalname in DESELECT else keep).append(item)
    if drop:
        config.hook.pytest_deselected(items=drop)
        items[:] = keep


@pytest.fixture
def xp():
    return np
'''


def _source(name):
    try:
        import scipy.spatial.transform as sst
    except ImportError:
        return None
    path = Path(sst.__file__).parent / "tests" / name
    return path if path.is_file() else None


def run_suite(name, workdir, reference=False):
    """Copy, patch and run one scipy test file; return its counts and failed test ids."""
    spec = SUITES[name]
    text = _source(name).read_text()
    if not reference:
        for old, new in spec["swaps"]:
            if old not in text:
                raise AssertionError(f"{name}: expected the line {old!r} to swap, not found "
                                     f"(scipy changed its imports: update SUITES)")
            text = text.replace(old, new)
    d = Path(workdir, Path(name).stem)
    d.mkdir()
    Path(d, name).write_text(text)
    deselect = sorted(spec["deselect"]) if not reference else []
    Path(d, "conftest.py").write_text(CONFTEST.format(deselect=json.dumps(deselect)))
    xml = Path(d, "report.xml")
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    env.pop("SCIPY_ARRAY_API", None)
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:randomly",
         "--rootdir", str(d), "-o", "addopts=", "--tb=line", f"--junitxml={xml}", str(d / name)],
        cwd=d, env=env, capture_output=True, text=True, timeout=900)
    if not xml.exists():
        raise AssertionError(f"{name}: pytest did not run:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    suite = ET.parse(xml).getroot()
    suite = suite if suite.tag == "testsuite" else suite.find("testsuite")
    failed, skipped = [], []
    for case in suite.iter("testcase"):
        if case.find("failure") is not None or case.find("error") is not None:
            failed.append(case.get("name"))
        elif case.find("skipped") is not None:
            skipped.append(case.get("name"))
    total = int(suite.get("tests"))
    deselected = _deselected(proc.stdout)
    counts = {"collected": total + deselected, "passed": total - len(failed) - len(skipped),
              "failed": len(failed), "skipped": len(skipped), "deselected": deselected}
    return counts, failed, skipped, proc.stdout


def _deselected(stdout):
    found = re.findall(r"(\d+) deselected", stdout)
    return int(found[-1]) if found else 0


@pytest.mark.parametrize("name", sorted(SUITES))
def test_scipy_suite(name, tmp_path):
    """Every test of scipy's file passes with quatarray's classes swapped in."""
    if _source(name) is None:
        pytest.skip(f"the installed scipy has no spatial/transform/tests/{name} "
                    f"(scipy missing, or installed without its tests)")
    counts, failed, skipped, stdout = run_suite(name, tmp_path)
    print(f"\nscipy {name}: " + ", ".join(f"{k} {v}" for k, v in counts.items()))
    assert not failed and not skipped, (
        f"{name}: {len(failed)} failed, {len(skipped)} skipped of {counts['collected']}:\n"
        + "\n".join(failed + skipped) + "\n" + stdout[-4000:])
    expected = SUITES[name].get("deselected_items", len(SUITES[name]["deselect"]))   # parametrized: more items
    assert counts["deselected"] == expected, (
        f"{name}: expected {expected} deselected tests, got "
        f"{counts['deselected']} (a deselected name no longer exists?)")


if __name__ == "__main__":  # python tests/test_scipy_suite.py [--reference]: counts only
    ref = "--reference" in sys.argv
    for suite_name in sorted(SUITES):
        if _source(suite_name) is None:
            print(f"{suite_name}: not in the installed scipy")
            continue
        with tempfile.TemporaryDirectory() as tmp:
            c, f, s, _ = run_suite(suite_name, tmp, reference=ref)
        print(f"{suite_name}: " + ", ".join(f"{k} {v}" for k, v in c.items()))
        for n in f:
            print("  FAILED", n)
        for n in s:
            print("  SKIPPED", n)
