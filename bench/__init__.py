"""Benchmarks (``make bench``): each ``bench/NAME.py`` is a script with a ``__main__`` block.

Speed is measured here, never asserted in unit tests; every bench prints its figures as
ratios against a baseline measured in the same run, as well as absolute numbers.
"""
