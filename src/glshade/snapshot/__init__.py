"""Snapshot tests of inspection scenes: glshade's pytest plugin and what it is made of.

- :mod:`.plugin`: the pytest plugin (entry point group ``pytest11``): the
  ``glshade_snapshot`` fixture, its options and the session's summary;
- :mod:`.station`: what renders and measures a scene (the GL renderer, or the NumPy
  float64 oracle where no OpenGL context can be made);
- :mod:`.baseline`: a baseline's 16-bit PNG and JSON sidecar;
- :mod:`.tolerance`: the tolerances, in the emitter's peak, pixels and mm;
- :mod:`.compare`: a shot against its baseline;
- :mod:`.report`: the failures' images and the one-page HTML summary.

``docs/snapshot-testing.md`` shows a user's test, its baseline folder and the summary.
"""
