"""The toy detector writing ``Total Area:`` instead of ``Area:`` (some teams do)."""

import sys

from toy_arena import main

sys.exit(main(area_key="Total Area"))
