"""Benchmarks for quatarray: asv suites and a side-by-side comparison.

One module per area (``algebra``, ``rotate``, ``conversions``, ``pairwise``,
``tracks``, ``resample``); each class takes a ``lib`` parameter so that asv
shows quatarray, scipy, numpy-quaternion and quaternionic side by side on the
same data.  ``python -m benchmarks.compare`` times the same benchmarks
interleaved in one process and checks the targets of issue 5.

Nothing here is imported by quatarray itself; the peers are optional.
"""
