"""The readers' error and warnings (defined in :mod:`pointax.errors`, where the core's
input checks use them too)."""

from ..errors import FileFormatError, InputWarning, PointaxWarning, warn_input

__all__ = ["FileFormatError", "PointaxWarning", "InputWarning", "warn_input"]
