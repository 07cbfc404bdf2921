"""The emitter slot: the light source reflected rays land on, and the pattern it shows."""
