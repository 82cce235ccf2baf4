"""The toy detector writing ``Total Area:`` instead of ``Area:`` (some teams do)."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from toy_arena import main

sys.exit(main(area_key="Total Area"))
