"""The package as a user imports it: public names, submodules, and what importing costs."""

import subprocess
import sys

import quatarray


def test_testing_reachable_as_attribute():
    # `import quatarray; quatarray.testing.assert_allclose(...)` must work without
    # a separate `import quatarray.testing`.
    code = "import quatarray; print(quatarray.testing.assert_allclose.__name__)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "assert_allclose"


def test_all_names_exist():
    missing = [name for name in quatarray.__all__ if not hasattr(quatarray, name)]
    assert missing == []


def test_import_loads_no_optional_dependency():
    code = ("import sys, quatarray; "
            "print(sorted(m for m in ('scipy', 'matplotlib', 'dask', 'zarr', 'pygltflib') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
