"""The components: one folder per kind of each slot of a scene
(``components/<slot>/<name>/``), each with its parameters (a table dataclass), its GLSL,
its NumPy float64 oracle and its docs; :mod:`.base` is the shape they share,
:mod:`.registry` finds them (the ``glshade.components`` entry points) and collects their
schema."""
