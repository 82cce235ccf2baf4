"""``arenabench bench``: the speed and memory measurements (``items``), the competition-style
script it times (``map_script``) and the big-set item (``bigset``); docs/benchmark.md.
"""
