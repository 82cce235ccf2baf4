"""The reference pipeline, as a team would submit it."""

import sys

from arenabench.detect import main

sys.exit(main(sys.argv[1:]))
