"""Smoke test of the benchmark suites: every benchmark runs once at its smallest size.

A broken benchmark (renamed API, bad data, wrong signature) fails here in
seconds instead of in an asv run.  Benchmarks of a library that is not
installed, or of an operation it lacks, are skipped as asv skips them.
"""

import importlib
import inspect
import itertools
import os

import numpy as np
import pytest

from benchmarks import _common

MODULES = ["algebra", "rotate", "conversions", "pairwise", "tracks", "resample", "rigid", "chunked", "sweep",
           "memory", "timeseries"]


def _classes():
    for name in MODULES:
        mod = importlib.import_module(f"benchmarks.{name}")
        for cname, cls in vars(mod).items():
            if inspect.isclass(cls) and cls.__module__ == mod.__name__ and hasattr(cls, "params"):
                yield pytest.param(cls, id=f"{name}.{cname}")


def _smallest(cls):
    """Every parameter combination with the smallest numeric sizes (named sizes: the
    class's `smoke_params`)."""
    axes = [[min(p)] if all(isinstance(v, int) for v in p) else p
            for p in getattr(cls, "smoke_params", cls.params)]
    return list(itertools.product(*axes))


def _benchmarks(cls):
    return [n for n in dir(cls) if n.startswith(("time_", "peakmem_"))]


@pytest.mark.parametrize("cls", list(_classes()))
def test_benchmarks_run(cls, tmp_path, monkeypatch):
    if cls.__name__ == "Resample":
        monkeypatch.setattr("benchmarks.resample.SCALE", {"npz": (40, 3), "bvh": (30, 4)})
        monkeypatch.chdir(tmp_path)
        cache = (cls().setup_cache(),)
    else:
        cache = ()
    ran = 0
    for params in _smallest(cls):
        bench = cls()
        try:
            bench.setup(*cache, *params)
        except NotImplementedError:  # library not installed, or module not landed
            continue
        for name in _benchmarks(cls):
            try:
                getattr(bench, name)(*cache, *params)
            except NotImplementedError:  # operation missing in that library (asv: skipped)
                continue
            ran += 1
    if "quatarray" in [p for ps in cls.params for p in ps]:
        assert ran > 0, f"no benchmark of {cls.__name__} ran"


@pytest.mark.parametrize("cls", list(_classes()))
def test_benchmarks_documented(cls):
    assert cls.__doc__
    for name in _benchmarks(cls):
        assert getattr(cls, name).__doc__, f"{cls.__name__}.{name} has no docstring"
    assert len(cls.param_names) == len(cls.params)


def test_same_data_for_every_library():
    q = _common.unit_quats(100, "float32", salt=1)
    assert q.dtype == np.float32 and q.shape == (100, 4)
    np.testing.assert_array_equal(q, _common.unit_quats(100, "float32", salt=1))
    assert _common.unit_quats(1, "float64").shape == (4,)
    m = _common.matrices(5, "float64")
    np.testing.assert_allclose(m @ np.swapaxes(m, -1, -2), np.broadcast_to(np.eye(3), (5, 3, 3)), atol=1e-12)


def test_missing_library_skips(monkeypatch):
    monkeypatch.setitem(_common._MODULES, "quaternionic", "no_such_module_xyz")
    assert not _common.installed("quaternionic")
    monkeypatch.setitem(_common._ADAPTERS, "quaternionic", lambda: importlib.import_module("no_such_module_xyz"))
    with pytest.raises(NotImplementedError, match="not installed"):
        _common.adapter("quaternionic")


def test_missing_operation_skips():
    lib = _common.adapter("quatarray")
    with pytest.raises(NotImplementedError, match="no frobnicate"):
        lib.frobnicate(1)
    assert os.path.basename(_common.__file__) == "_common.py"


def test_no_accidental_benchmarks():
    """asv treats every module-level function named time_*, track_*, mem_*, peakmem_* or
    timeraw_* in benchmarks/ as a benchmark (a helper named track_data once failed asv)."""
    prefixes = ("time_", "timeraw_", "track_", "mem_", "peakmem_")
    for name in MODULES + ["_common", "compare"]:
        mod = importlib.import_module(f"benchmarks.{name}")
        for fname, obj in vars(mod).items():
            if inspect.isfunction(obj) and obj.__module__ == mod.__name__:
                assert not fname.startswith(prefixes), f"benchmarks.{name}.{fname} looks like an asv benchmark"


def test_size_sweep_reports_a_ratio_per_operation_and_size():
    from benchmarks import compare, sweep
    table = compare.sweep(repeat=1, min_time=1e-4, sizes=[None, 3], ops=["as_matrix", "Slerp call"], log=lambda s: None)
    assert set(table) == {"as_matrix", "Slerp call"}
    for row in table.values():
        assert set(row) == {None, 3} and all(r is None or r > 0 for r in row.values())
    assert set(sweep.TRANSCENDENTAL + sweep.COPIES) <= set(sweep.OPS)


def test_size_sweep_marks_the_cells_below_their_targets():
    """The issue's targets by size (1 for one rotation and a batch of one, 0.33 at 10 and
    100, from 10³ on 1 for transcendental methods and 1/2 for copies and products): cells
    below them are bold, and listed."""
    from benchmarks import compare, sweep
    assert [sweep.target("as_matrix", n) for n in (None, 1, 10, 100, 1000, 10**6)] == [1, 1, 0.33, 0.33, 0.5, 0.5]
    assert sweep.target("as_euler", 1000) == 1 and sweep.target("identity", 1000) is None
    table = {"as_matrix": {None: 0.9, 10: 0.34, 1000: 0.4}, "as_euler": {1000: 1.2}, "identity": {1000: 0.1}}
    assert compare._sweep_misses(table) == ["as_matrix at single: 0.90 < 1.00", "as_matrix at 1 000: 0.40 < 0.50"]
    assert compare._sweep_cell(0.4, 0.5) == "**0.40**" and compare._sweep_cell(0.6, 0.5) == "0.60"
    assert compare._sweep_cell(None, 1.0) == "-" and compare._sweep_cell(0.1, None) == "0.10"


def test_float32_targets_time_float64_in_the_same_row():
    """The float32 rows of the float32 targets time quatarray in float64 too, interleaved in
    the row, and the target is their ratio (not that of two rows timed apart)."""
    from benchmarks import compare
    from benchmarks.algebra import Algebra
    rows = [r for r in compare._rows(False) if r.op in compare.FLOAT32_OPS and r.dtype == "float32"]
    assert rows and all(r.twin == "float64" for r in rows)
    row = compare.Row("product", Algebra, "time_product", (10, "float32"), libs=["quatarray"], twin="float64")
    (res,) = compare.run_rows([row], repeat=1, min_time=1e-4)
    assert res["times"]["quatarray float64"] > 0
    times = {"quatarray": 2.0, "quatarray float64": 5.0, "np.add": 1.0}
    results = [dict(op="product", n=compare.BIG, dtype="float32", times=times),
               dict(op="product", n=compare.BIG, dtype="float64", times={"quatarray": 1.0})]
    got = dict((d, v) for d, v, _ in compare.targets(results, {}, None))
    assert got["float32 product: float64 / float32 time >= 1.5"] == "2.50x"
