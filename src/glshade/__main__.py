"""``python -m glshade``: the command line (:mod:`glshade.app.entry`)."""

import sys

from glshade.app.entry import main

sys.exit(main())
