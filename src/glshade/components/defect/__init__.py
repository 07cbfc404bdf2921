"""The defect slot: ``D(x, z)`` on the base surface, and the first-hit solve it needs."""
