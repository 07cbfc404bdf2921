"""Recorded fringe captures: the model, readers and writers, and decoding."""
