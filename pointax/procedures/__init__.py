"""TPOINT procedures: the command language of TPOINT's sessions and procedure files.

* :mod:`~pointax.procedures.parser`: command lines (quotes, ``!`` and ``;`` comments),
  abbreviations, TPOINT's commands pointax notes, where each line is from.
* :mod:`~pointax.procedures.session`: the state (run, terms, values, masks, last fit).
* :mod:`~pointax.procedures.step`: FIT, one linearised (Gauss-Newton) adjustment.
* :mod:`~pointax.procedures.tpoint_commands`: the TPOINT commands, one function each.
* :mod:`~pointax.procedures.graphics`: G..., GC, CAPT and PLTZ (panels of a 3 x 3 page).
* :mod:`~pointax.procedures.runner`: scripts, PROC ... RETURN, INPRO, CALL, standard input.

``pointax tpoint [SCRIPT ...]`` (:mod:`pointax.cli.tpoint`) runs them; the README's
"TPOINT procedures" lists every command and the Python API it maps to.
"""

from __future__ import annotations

from ..core.lazy import lazy_namespace

__getattr__, __dir__ = lazy_namespace(
    __name__,
    {
        "Session": "session",
        "read_run": "session",
        "Runner": "runner",
        "ProcedureError": "parser",
        "gauss_newton_step": "step",
        "Step": "step",
        "COMMANDS": "parser",
    },
)

__all__ = ["Session", "Runner", "ProcedureError", "gauss_newton_step", "Step", "read_run", "COMMANDS"]
