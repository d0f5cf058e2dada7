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


def test_doctests_collect_without_the_optional_extras(tmp_path):
    """``python -m pytest`` collects the package's doctests cleanly when dask, zarr,
    matplotlib and pygltflib cannot be imported (the root conftest leaves their modules out)."""
    code = """if True:
        import sys
        class Blocker:
            def find_spec(self, name, path=None, target=None):
                if name.split(".")[0] in {"dask", "zarr", "matplotlib", "pygltflib", "distributed"}:
                    raise ModuleNotFoundError(name, name=name)
        sys.meta_path.insert(0, Blocker())
        import pytest
        sys.exit(pytest.main(["--collect-only", "-q", "-p", "no:cacheprovider", "quatarray"]))
    """
    root = __file__.rsplit("/tests/", 1)[0]
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=root)
    assert out.returncode == 0, out.stdout[-2000:]
    assert "error" not in out.stdout.lower().splitlines()[-1]
