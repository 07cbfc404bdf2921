"""glshade's version, on the ground floor: the package's face, the oracle's renderer
string and the records all read it here."""

__version__ = "0.1.0"
