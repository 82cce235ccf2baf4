"""The generator's sub-commands, each a module with ``build_parser`` and ``main`` (named by the
command table in :mod:`arenabench.cli`).
"""
