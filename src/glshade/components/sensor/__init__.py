"""The sensor slot: what the camera's sensor makes of the radiance (NumPy only)."""
