"""``python -m arenabench``: the same as the ``arenabench`` console script."""

from arenabench.cli import main

raise SystemExit(main())
