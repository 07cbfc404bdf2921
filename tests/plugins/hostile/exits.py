"""A plug-in that ends the interpreter at its import, with a success code."""

raise SystemExit(0)
