"""The surface slot: the base surface ``y = f(x, z)`` and its first hit. Its table holds
``kind``, the selector; each kind's folder adds its parameters. Shared here: the quadric
surfaces' oracle (:mod:`.quadric`) and the free-form surfaces' march (:mod:`.freeform`)."""
