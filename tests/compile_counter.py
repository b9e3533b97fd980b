"""Counts XLA compilations in a block: the tests' guard that a change of terms, fixes,
masks or readings does not compile again (counted, not timed); and names the functions
JAX traces in a block."""

from __future__ import annotations

import contextlib

import jax


class CompileCounter:
    """Counts XLA compilations (JAX's backend-compile events) while active."""

    def __init__(self):
        self.count, self.active = 0, False
        jax.monitoring.register_event_duration_secs_listener(self._event)

    def _event(self, event, duration, **kwargs):
        if self.active and event == "/jax/core/compile/backend_compile_duration":
            self.count += 1

    def __enter__(self):
        self.count, self.active = 0, True
        return self

    def __exit__(self, *exc):
        self.active = False


COUNTER = CompileCounter()
"""One counter for the session (a listener cannot be unregistered per test)."""


@contextlib.contextmanager
def traces():
    """The names of the functions JAX traces for ``jit`` inside the block (JAX's
    trace-duration events)."""
    seen: list[str] = []

    def listener(event, duration, **kwargs):
        if event == "/jax/core/compile/jaxpr_trace_duration":
            seen.append(str(kwargs.get("fun_name")))

    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        yield seen
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)
