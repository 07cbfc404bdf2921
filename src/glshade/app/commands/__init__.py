"""The command line's commands, one module each (:mod:`glshade.app.cli` lists them):
``add(sub)`` adds the command's parser to the subparsers ``sub``, ``run(args)`` runs it
on the parsed command line and returns its exit code. A module loads the machinery its
command runs (OpenGL, the measuring engine, Dask, ...) only inside ``run``, so that
``glshade --help`` or another command does not pay for it. Beside them: ``paper_pmd``
(``glshade paper --method pmd``) and ``distribution`` (where ``sweep`` and ``optimize``
run their cases)."""
