"""Run the installed scipy's test_rigid_transform.py against quatarray (not collected by pytest).

Usage: python tests/scipy_harness/run_rigid_transform.py  (from the repo root).
Imports are swapped to quatarray, scipy's array-API decorators removed and an
``xp`` fixture returning NumPy supplied; prints pytest's summary.
"""

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import scipy.spatial.transform as sst

SRC = Path(sst.__file__).parent / "tests" / "test_rigid_transform.py"


# test_pow asserts isinstance(q._matrix, type(p._matrix)): scipy's private storage attribute
# (quatarray stores quaternion + translation); the same integer/fractional powers are
# checked against scipy in tests/test_rigid_transform.py.
DESELECT = [a for n in (1, 2, 3) for a in ("--deselect", f"test_copy.py::test_pow[{n}]")]


def _strip_decorators(s, name="@make_xp_test_case("):
    out, i = [], 0
    while (j := s.find(name, i)) >= 0:
        out.append(s[i:j])
        k, depth = j + len(name), 1
        while depth:
            depth += {"(": 1, ")": -1}.get(s[k], 0)
            k += 1
        i = s.index("\n", k) + 1
    return "".join(out) + s[i:]


def main():
    s = SRC.read_text()
    s = s.replace("from scipy.spatial.transform import Rotation, RigidTransform",
                  "from quatarray import RigidTransform, Rotation")
    s = s.replace("from scipy.spatial.transform._rigid_transform import normalize_dual_quaternion",
                  "from quatarray import normalize_dual_quaternion")
    with tempfile.TemporaryDirectory() as d:
        Path(d, "test_copy.py").write_text(_strip_decorators(s))
        Path(d, "conftest.py").write_text(
            "import numpy as np, pytest\n@pytest.fixture\ndef xp():\n    return np\n")
        env = dict(os.environ, PYTHONPATH=os.getcwd())
        return subprocess.call([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                                "--tb=short", d, *DESELECT], env=env)


if __name__ == "__main__":
    sys.exit(main())
