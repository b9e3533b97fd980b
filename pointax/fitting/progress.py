"""Progress bars for long work (comparison folds, model building, leave-one-out, network
fits), through tqdm, on a terminal only: pointax's one progress-bar module.

    with progress_bar(total=8, desc="folds", enabled=progress) as bar:
        for ...:
            ...
            bar.update()

``enabled``: ``True`` draws the bar (on standard error unless ``stream`` is given)
when that stream is a terminal, ``False`` (the library's default) draws nothing.
Output that is not a terminal (a pipe, a log file, a test's captured stream) never gets
a bar, so logs and JSON stay clean; ``--quiet`` on the command line passes ``False``.
A :class:`Progress` is also the ``progress(done, total)`` callback that
:func:`pointax.fit_batch` and :func:`pointax.analysis.network.fit_network` call after
each chunk of sites.
"""

from __future__ import annotations

import sys
from typing import TextIO

__all__ = ["Progress", "progress_bar", "is_terminal"]


def is_terminal(stream) -> bool:
    """Whether ``stream`` is an interactive terminal."""
    isatty = getattr(stream, "isatty", None)
    try:
        return bool(isatty and isatty())
    except ValueError:  # a closed stream
        return False


class Progress:
    """A progress bar (tqdm) or nothing. ``update(n)`` advances it, ``__call__(done,
    total)`` sets it (the ``progress(done, total)`` callback form), ``close()`` ends it;
    also a context manager. ``active`` says whether a bar is drawn."""

    def __init__(self, total: int | None, desc: str, unit: str, stream: TextIO | None, enabled: bool):
        self._bar = None
        stream = stream if stream is not None else sys.stderr
        if enabled and is_terminal(stream):
            from tqdm import tqdm

            self._bar = tqdm(total=total, desc=desc, unit=unit, file=stream, leave=True, dynamic_ncols=True)

    @property
    def active(self) -> bool:
        return self._bar is not None

    def update(self, n: int = 1) -> None:
        if self._bar is not None:
            self._bar.update(n)

    def set_description(self, text: str) -> None:
        if self._bar is not None:
            self._bar.set_description_str(text)

    def __call__(self, done: int, total: int | None = None) -> None:
        if self._bar is None:
            return
        if total is not None and total != self._bar.total:
            self._bar.total = int(total)
        self._bar.update(int(done) - self._bar.n)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def progress_bar(
    total: int | None = None, desc: str = "", unit: str = "it", *, enabled: bool = False, stream: TextIO | None = None
) -> Progress:
    """A :class:`Progress` of ``total`` steps, drawn on ``stream`` (standard error)
    when ``enabled`` and that stream is a terminal; a silent one otherwise."""
    return Progress(total, desc, unit, stream, bool(enabled))
