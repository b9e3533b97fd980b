"""Plain-text helpers shared by the readers (no numerical library), and the one place
where a file's bytes become text (:func:`read_text`).

A file is UTF-8 (a byte-order mark dropped). One that is not is read as Latin-1 (every
byte a character: the files of older observatory software, ``é`` or ``°`` in a
comment), on one condition: its non-ASCII bytes lie only in comments (after the
format's comment characters) or in the caption (TPOINT's first record, free text),
which no reader interprets. A non-ASCII byte elsewhere, inside a data field, is an
error naming the file, the line, the column and the byte.
"""

from __future__ import annotations

from pathlib import Path

from .errors import FileFormatError

__all__ = ["read_text", "decode_text", "is_number"]


def read_text(path: str, error: type[FileFormatError], comments: str = "#!;", caption: bool = False) -> str:
    """The text of ``path`` (:func:`decode_text`); an unreadable byte raises ``error``
    naming the file, the line and the column."""
    return decode_text(Path(path).read_bytes(), str(path), error, comments, caption)


def decode_text(data: bytes, path: str, error: type[FileFormatError], comments: str = "#!;", caption: bool = False) -> str:
    """``data`` as text: UTF-8 (a byte-order mark dropped), else Latin-1 where every
    non-ASCII byte lies in a comment (after one of ``comments`` on its line) or, with
    ``caption``, in the first line that is neither blank nor a comment.

    Raises:
        error: a NUL byte (a binary file), or a non-ASCII byte of a file that is not
            UTF-8 inside a data field, naming the line and the column.
    """
    if b"\0" in data:
        offset = data.index(b"\0")
        raise error(path, None, f"not a text file (a NUL byte at offset {offset}: binary data)")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        first_bad = err.start
    text = data.decode("latin-1")
    seen_caption = not caption
    for lineno, line in enumerate(text.splitlines(), 1):
        stripped = line.strip()
        is_comment = stripped[:1] in tuple(comments) if stripped else False
        if not seen_caption and stripped and not is_comment:
            seen_caption = True
            continue  # the caption: free text
        comment_at = min((line.index(c) for c in comments if c in line), default=len(line))
        for column, char in enumerate(line[:comment_at], 1):
            if ord(char) > 127:
                raise error(
                    path,
                    lineno,
                    f"column {column}: byte 0x{ord(char):02x} ({char!r} in Latin-1) in a data field: the file is not "
                    f"UTF-8 (first bad byte at offset {first_bad}), and outside comments"
                    f"{' and the caption' if caption else ''} only ASCII can be read; write the unit or symbol in a "
                    f"comment, or save the file as UTF-8",
                )
    return text


def is_number(token: str) -> bool:
    """Whether ``token`` reads as a float."""
    try:
        float(token)
    except ValueError:
        return False
    return True
