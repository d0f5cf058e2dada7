"""Issue 14: every docstring example runs on its own in an empty namespace.

Each example must import what it uses (``import numpy as np``,
``from quatarray import ...``) so a user can copy any one of them alone.
quatarray._array, quatarray._convert and quatarray._validate are covered by
tests/test_domain.py on another branch.
"""

import doctest
import importlib
import pkgutil

import pytest

import quatarray

_COVERED_ELSEWHERE = {"quatarray._array", "quatarray._convert", "quatarray._validate"}
_OPTIONAL = {"quatarray.dask": "dask"}


def _modules():
    names = ["quatarray"] + [
        info.name
        for info in pkgutil.walk_packages(quatarray.__path__, "quatarray.")
    ]
    return sorted(n for n in names if n not in _COVERED_ELSEWHERE)


@pytest.mark.parametrize("module", _modules())
def test_docstring_examples_import_what_they_use(module):
    if module in _OPTIONAL:
        pytest.importorskip(
            _OPTIONAL[module], reason=f"{module} needs {_OPTIONAL[module]}"
        )

    class Runner(doctest.DocTestRunner):
        def report_unexpected_exception(self, out, test, example, exc_info):
            if issubclass(exc_info[0], NameError):
                missing.append(f"{test.name}: {exc_info[1]}")

    missing = []
    tests = doctest.DocTestFinder().find(importlib.import_module(module))
    for test in tests:
        test.globs = {}
        Runner(optionflags=doctest.ELLIPSIS).run(test, out=lambda s: None)
    assert not missing, missing
