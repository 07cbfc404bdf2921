"""A plug-in that raises GeneratorExit at its import."""

raise GeneratorExit("closed")
