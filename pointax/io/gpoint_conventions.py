"""What gpoint's run files (:mod:`pointax.io.gpoint`) and model files
(:mod:`pointax.io.gpoint_model`) share: how gpoint counts azimuth, and the error that
names file, line and field.
"""

from __future__ import annotations

from .errors import FileFormatError

__all__ = ["GPOINT_AZIMUTH", "GpointFormatError"]

GPOINT_AZIMUTH = "S-W"
"""How gpoint (RTS2, libnova) counts azimuth: from South through West."""


class GpointFormatError(FileFormatError):
    """A gpoint file could not be read; the message names file, line and field."""
