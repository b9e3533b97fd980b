"""File formats: TPOINT input and model files (more formats to come)."""

from .tpoint import (
    ModelTerm,
    RunParameters,
    TpointFormatError,
    TpointModelFile,
    TpointRun,
    format_model,
    parse_model,
    parse_tpoint,
    read_model,
    read_tpoint,
    write_model,
)

__all__ = [
    "ModelTerm",
    "RunParameters",
    "TpointFormatError",
    "TpointModelFile",
    "TpointRun",
    "format_model",
    "parse_model",
    "parse_tpoint",
    "read_model",
    "read_tpoint",
    "write_model",
]
