"""Broken plug-ins, one module each, named by entry points that tests/test_hostile_plugins.py
declares: each fails the way a careless plug-in does (at its import, or in what it
declares), and glshade must name it and go on without it."""
