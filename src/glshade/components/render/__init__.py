"""The render slot: how a frame is computed (precision, rays per pixel); the program's preamble."""
