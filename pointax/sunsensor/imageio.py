"""Reading sun-sensor frames from files: PNG (8 and 16 bit), FITS and NumPy ``.npy``.

Each reader returns the frame as a 2-D NumPy array in its stored integer or float type
(no scaling), or raises :class:`FrameReadError`, whose message names the file and says
what is wrong. PNG goes through Pillow (grayscale 8-bit ``L``, 16-bit ``I;16``, 32-bit
``I``); FITS through ``astropy.io.fits`` (the first HDU holding an image, with BZERO /
BSCALE applied, so unsigned 16-bit data come back as ``uint16``); ``.npy`` through
``numpy.load`` without pickles.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io.errors import FileFormatError

__all__ = ["FrameReadError", "read_frame", "FORMATS"]

FORMATS = {".png": "PNG", ".fits": "FITS", ".fit": "FITS", ".fts": "FITS", ".fits.gz": "FITS", ".npy": "NumPy"}
"""File suffixes read, and their formats."""


class FrameReadError(FileFormatError):
    """A frame file that cannot be read as one grayscale frame (the message names it)."""

    def __init__(self, path, message: str):
        super().__init__(str(path), None, message)


def _suffix(path: Path) -> str:
    name = path.name.lower()
    return ".fits.gz" if name.endswith(".fits.gz") else path.suffix.lower()


def _read_png(path: Path) -> np.ndarray:
    try:
        from PIL import Image
    except ImportError as err:  # pragma: no cover - depends on the environment
        raise FrameReadError(path, "reading PNG needs Pillow (pip install pillow)") from err
    try:
        with Image.open(path) as image:
            mode = image.mode
            if mode not in ("L", "I;16", "I;16B", "I;16L", "I", "F"):
                raise FrameReadError(
                    path, f"PNG mode {mode!r}: expected a grayscale frame (8-bit 'L' or 16-bit 'I;16'); a sun sensor frame has one channel"
                )
            array = np.array(image)
    except FrameReadError:
        raise
    except Exception as err:  # noqa: BLE001 - Pillow raises many kinds
        raise FrameReadError(path, f"not a readable PNG ({type(err).__name__}: {err})") from err
    return array


def _read_fits(path: Path) -> np.ndarray:
    from astropy.io import fits

    try:
        with fits.open(path, memmap=False) as hdus:
            for hdu in hdus:
                if getattr(hdu, "is_image", False) and hdu.data is not None:
                    data = np.asarray(hdu.data)
                    if data.ndim == 3 and data.shape[0] == 1:
                        data = data[0]
                    if data.ndim != 2:
                        raise FrameReadError(path, f"HDU {hdu.name!r} holds data of shape {data.shape}; expected a 2-D frame")
                    # FITS is big-endian: give native byte order to the numerics.
                    return data.astype(data.dtype.newbyteorder("="), copy=False)
    except FrameReadError:
        raise
    except Exception as err:  # noqa: BLE001 - astropy raises many kinds
        raise FrameReadError(path, f"not a readable FITS file ({type(err).__name__}: {err})") from err
    raise FrameReadError(path, "no image HDU with data")


def _read_npy(path: Path) -> np.ndarray:
    try:
        array = np.load(path, allow_pickle=False)
    except Exception as err:  # noqa: BLE001
        raise FrameReadError(path, f"not a readable .npy array ({type(err).__name__}: {err})") from err
    if not isinstance(array, np.ndarray):
        raise FrameReadError(path, "holds no array")
    return array


def read_frame(path) -> np.ndarray:
    """Read one frame from a PNG, FITS or ``.npy`` file (by suffix).

    Raises:
        FrameReadError: the file is missing, of an unknown type, unreadable, or not a
            grayscale image. Shape and dtype are checked later, per frame, by
            :func:`pointax.sunsensor.centroids.check_frame`.
    """
    path = Path(path)
    if not path.is_file():
        raise FrameReadError(path, "no such file")
    suffix = _suffix(path)
    if suffix not in FORMATS:
        raise FrameReadError(path, f"unknown frame format {suffix or '(no suffix)'!r}; expected one of {', '.join(sorted(FORMATS))}")
    kind = FORMATS[suffix]
    if kind == "PNG":
        return _read_png(path)
    if kind == "FITS":
        return _read_fits(path)
    return _read_npy(path)
