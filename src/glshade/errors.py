"""The errors glshade raises on purpose.

Every error a user can cause derives from :class:`GlshadeError`; the CLI prints its
message as one line and exits with code 2. Anything else is a bug and keeps its
traceback.
"""

from __future__ import annotations


def printable(text: str) -> str:
    """``text`` with every control character (a line break in a key or file name)
    escaped, so that an error message stays one line."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


class GlshadeError(Exception):
    """Base class: a problem the user can fix (bad input, missing system library)."""


class SceneError(GlshadeError, ValueError):
    """A scene value outside its allowed range.

    ``field`` is the dotted name as it appears in a scene file (``camera.theta_deg``),
    ``allowed`` says what would be accepted.
    """

    def __init__(self, field: str, allowed: str, got: object = None) -> None:
        self.field = field
        self.allowed = allowed
        self.got = got
        shown = "" if got is None else f", got {shown_value(got)}"
        super().__init__(printable(f"{field}: must be {allowed}{shown}"))


def shown_value(value: object, limit: int = 80) -> str:
    """``repr(value)`` for a message, shortened to about ``limit`` characters (an integer
    of 400 digits shows its first digits and its length; Python refuses to print one of
    more than 4300)."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 200:
        digits = len(str(abs(value))) if value.bit_length() < 14000 else None
        length = f"{digits} digits" if digits is not None else "thousands of digits"
        return f"an integer of {length}"
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


class ContextError(GlshadeError, RuntimeError):
    """No OpenGL context could be created (missing libEGL, driver or device)."""


class ShaderCompileError(GlshadeError, RuntimeError):
    """The driver rejected a composed shader; the message shows the faulty lines."""


class GlshadeWarning(UserWarning):
    """A value or file glshade accepts but doubts (the CLI prints ``glshade: warning:``)."""
