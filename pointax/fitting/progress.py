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
each chunk of sites; :meth:`Progress.activity` names a wait (a compilation) on the bar
while it lasts, and :meth:`Progress.shifted` gives a part of the work its own
``progress(done, total)`` view of one bar.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from typing import TextIO

__all__ = ["Progress", "progress_bar", "is_terminal", "activity"]


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

    @contextlib.contextmanager
    def activity(self, text: str) -> Iterator[None]:
        """Show ``text`` as the bar's description while the block runs (drawn at once: a
        compilation blocks the bar's own refresh), then the description it had."""
        if self._bar is None:
            yield
            return
        before = self._bar.desc
        self._bar.set_description_str(text, refresh=True)
        try:
            yield
        finally:
            if self._bar is not None:
                self._bar.set_description_str(before, refresh=True)

    def shifted(self, offset: int, total: int) -> "ShiftedProgress":
        """A ``progress(done, part_total)`` callback for a part of the work that starts
        at ``offset`` of this bar's ``total`` (its activities shown here too)."""
        return ShiftedProgress(self, int(offset), int(total))

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class ShiftedProgress:
    """:meth:`Progress.shifted`: ``progress(done, part_total)`` sets ``offset + done`` of
    ``total`` on the bar; :meth:`activity` is the bar's."""

    def __init__(self, bar: Progress, offset: int, total: int):
        self.bar, self.offset, self.total = bar, offset, total

    def __call__(self, done: int, _part_total: int | None = None) -> None:
        self.bar(self.offset + int(done), self.total)

    def activity(self, text: str):
        return self.bar.activity(text)


def activity(progress, text: str):
    """``progress.activity(text)`` when ``progress`` has one (a :class:`Progress`), else
    a context that does nothing (a plain ``progress(done, total)`` callable, None)."""
    method = getattr(progress, "activity", None)
    return method(text) if callable(method) else contextlib.nullcontext()


def progress_bar(
    total: int | None = None, desc: str = "", unit: str = "it", *, enabled: bool = False, stream: TextIO | None = None
) -> Progress:
    """A :class:`Progress` of ``total`` steps, drawn on ``stream`` (standard error)
    when ``enabled`` and that stream is a terminal; a silent one otherwise."""
    return Progress(total, desc, unit, stream, bool(enabled))
