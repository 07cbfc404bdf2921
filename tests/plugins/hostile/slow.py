"""A plug-in whose import takes a while (it says when it starts on stdout) and that
turns a KeyboardInterrupt into an ImportError, as a C extension's import does."""

import sys
import time

print("plug-in importing", flush=True)
sys.stdout.flush()
try:
    time.sleep(60)
except KeyboardInterrupt:
    raise ImportError("a C extension interrupted") from None
