"""The part slot: where the part (its surface and its dent) stands in the world (NumPy only)."""
