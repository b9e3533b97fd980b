"""Plain-text helpers shared by the readers (no numerical library)."""

from __future__ import annotations

from pathlib import Path

from .errors import FileFormatError

__all__ = ["read_text", "is_number"]


def read_text(path: str, error: type[FileFormatError]) -> str:
    """The text of ``path`` (UTF-8, a byte-order mark dropped); a file that is not text
    raises ``error`` naming it."""
    try:
        return Path(path).read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as err:
        raise error(path, None, f"not a text file ({err})") from None


def is_number(token: str) -> bool:
    """Whether ``token`` reads as a float."""
    try:
        float(token)
    except ValueError:
        return False
    return True
