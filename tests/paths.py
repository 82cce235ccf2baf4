"""Folders and files the tests use, named once (test modules live in subfolders that mirror the
packages, so none of them finds these from its own ``__file__``)."""

from pathlib import Path

#: The ``tests/`` folder.
TESTS = Path(__file__).resolve().parent
#: The repository's root.
ROOT = TESTS.parent
