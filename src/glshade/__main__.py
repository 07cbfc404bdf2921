"""``python -m glshade``: the command line (:mod:`glshade.app.cli`)."""

import sys

from glshade.app.cli import main

sys.exit(main())
