"""The camera slot: how pixels become rays."""
