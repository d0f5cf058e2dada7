"""Collection of the package's doctests (``testpaths`` includes ``quatarray``): a module that
needs an optional extra is left out when that extra is not installed, as its tests under
tests/ skip themselves, so ``python -m pytest`` collects cleanly with only NumPy and the
test tools."""

import importlib.util

#: package module -> the import it cannot do without
_OPTIONAL = {"quatarray/dask.py": "dask.array"}


def _missing(module):
    try:
        return importlib.util.find_spec(module) is None
    except ImportError:   # a parent package that is absent or fails to import
        return True


collect_ignore = [path for path, module in _OPTIONAL.items() if _missing(module)]
