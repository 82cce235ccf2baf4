"""Takes far longer than any --timeout the tests give."""

import time

time.sleep(120)
