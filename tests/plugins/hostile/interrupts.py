"""A plug-in that raises KeyboardInterrupt at its import (no one pressed Ctrl-C)."""

raise KeyboardInterrupt
