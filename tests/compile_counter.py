"""Counts XLA compilations in a block: the tests' guard that a change of terms, fixes,
masks or readings does not compile again (counted, not timed)."""

from __future__ import annotations

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
