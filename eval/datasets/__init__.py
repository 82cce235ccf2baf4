"""Datasets: reading a set written by the generator, checking every file before any image is
scored (``reader``, ``check``: several processes for big sets), a set too big for memory
(``bigset``), and per-image results kept in a temporary file for big runs (``result_store``).
"""
