"""Run the installed scipy's test_rotation_spline.py against quatarray (not collected by pytest).

Usage: python tests/scipy_harness/run_rotation_spline.py  (from the repo root).
"""

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import scipy.spatial.transform as sst

SRC = Path(sst.__file__).parent / "tests" / "test_rotation_spline.py"

PRIVATE = """from scipy.spatial.transform._rotation_spline import (
    _angular_rate_to_rotvec_dot_matrix,
    _rotvec_dot_to_angular_rate_matrix,
    _matrix_vector_product_of_stacks,
    _angular_acceleration_nonlinear_term,
    _create_block_3_diagonal_matrix)"""

# scipy's private maths helpers are public in quatarray.spline; the matrix-vector
# product of stacks is a test utility (einsum) and the banded-matrix builder is
# scipy's input format for solve_banded, which quatarray does not use (its
# interior-rate system is solved by block cyclic reduction): that test is deselected.
PUBLIC = """from quatarray.spline import (
    angular_rate_to_rotvec_dot_matrix as _angular_rate_to_rotvec_dot_matrix,
    rotvec_dot_to_angular_rate_matrix as _rotvec_dot_to_angular_rate_matrix,
    angular_acceleration_nonlinear_term as _angular_acceleration_nonlinear_term)


def _matrix_vector_product_of_stacks(A, b):
    return np.einsum("...ij,...j->...i", A, b)"""

DESELECT = ["--deselect", "test_copy.py::test_create_block_3_diagonal_matrix"]


def main():
    s = SRC.read_text()
    s = s.replace("from scipy.spatial.transform import Rotation, RotationSpline",
                  "from quatarray import Rotation, RotationSpline")
    assert PRIVATE in s
    s = s.replace(PRIVATE, PUBLIC)
    with tempfile.TemporaryDirectory() as d:
        Path(d, "test_copy.py").write_text(s)
        Path(d, "conftest.py").write_text(
            "import numpy as np, pytest\n@pytest.fixture\ndef xp():\n    return np\n")
        env = dict(os.environ, PYTHONPATH=os.getcwd())
        return subprocess.call([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                                "--tb=short", d, *DESELECT], env=env)


if __name__ == "__main__":
    sys.exit(main())
