"""Column names, header units and the command line's ``--columns`` of offsets tables
(:mod:`pointax.io.offsets`), without any numerical library: :func:`pointax.io.detect_format`
and the ``pointax`` command's argument checks use them before JAX or NumPy is imported.

Units in header names, in any of these forms (case-insensitive; ``NAME`` is the
column's name, ``UNIT`` one of the words below)::

    NAME [UNIT]    NAME (UNIT)    NAME {UNIT}    NAME <UNIT>    NAME/UNIT    NAME_UNIT

=========  ==============================================================================
unit       words
=========  ==============================================================================
arcsec     ``arcsec arcsecs arcsecond arcseconds arc_sec asec "`` ``''`` (two quotes) ``″``
arcmin     ``arcmin arcmins arcminute arcminutes arc_min amin '`` ``′``
deg        ``deg degs degree degrees °``
rad        ``rad rads radian radians``
=========  ==============================================================================

``NAME/UNIT`` and ``NAME_UNIT`` count only with one of these words (``dxel_err`` has no
unit); a bracket always holds a unit, and one pointax does not know is an error for a
column the table uses (unless ``units`` is given: then the bracket is taken as a note).
"""

from __future__ import annotations

import re

__all__ = [
    "UNIT_NAMES",
    "COLUMN_ALIASES",
    "split_unit",
    "unit_of_word",
    "normalise",
    "role_of",
    "header_fields",
    "parse_columns_option",
    "READING_NAMES",
    "READING_UNITS",
    "reading_of",
    "reading_unit",
]

UNIT_NAMES = ("arcsec", "arcmin", "deg", "rad")
"""Units of offsets (and, from a header, of any column): the keys of
:data:`pointax.io.offsets.OFFSET_UNITS`."""

_UNIT_WORDS = {
    "arcsec": ("arcsec", "arcsecs", "arcsecond", "arcseconds", "arc_sec", "arc-sec", "arc sec", "asec", '"', "''", "″"),
    "arcmin": ("arcmin", "arcmins", "arcminute", "arcminutes", "arc_min", "arc-min", "arc min", "amin", "'", "′"),
    "deg": ("deg", "degs", "degree", "degrees", "°"),
    "rad": ("rad", "rads", "radian", "radians"),
}
_UNIT_OF = {word: unit for unit, words in _UNIT_WORDS.items() for word in words}
_SUFFIX_WORDS = sorted((w for w in _UNIT_OF if re.fullmatch(r"[a-z_]+", w)), key=len, reverse=True)

_BRACKET = re.compile(r"^(?P<base>.*?)\s*[\[({<]\s*(?P<unit>[^\])}>]*?)\s*[\])}>]\s*$")
_SLASH = re.compile(r"^(?P<base>.*?)\s*/\s*(?P<unit>[^/]+?)\s*$")
_SUFFIX = re.compile(r"^(?P<base>.+?)[_\s\-]+(?P<unit>" + "|".join(_SUFFIX_WORDS) + r")$", re.IGNORECASE)


def unit_of_word(word: str) -> str | None:
    """The unit (:data:`UNIT_NAMES`) a word names (``"arcmin"``, ``"'"``,
    ``"degrees"``), or None."""
    w = word.strip().lower()
    return _UNIT_OF.get(w) or _UNIT_OF.get(re.sub(r"\s+", " ", w))


def split_unit(name: str) -> tuple[str, str | None, str | None]:
    """``(base name, unit, unit as written)`` of a header name.

    ``"dxel [arcmin]"`` -> ``("dxel", "arcmin", "arcmin")``; ``"Az/deg"`` ->
    ``("Az", "deg", "deg")``; ``"el_deg"`` -> ``("el", "deg", "deg")``; ``"dxel"`` ->
    ``("dxel", None, None)``; ``"dxel [mas]"`` -> ``("dxel", None, "mas")`` (a bracket
    holds a unit, but not one pointax knows).
    """
    text = name.strip()
    if len(text) > 2 and text[0] == text[-1] and text[0] in "\"'":
        text = text[1:-1].strip()  # a quoted name
    m = _BRACKET.match(text)
    if m and m.group("base"):
        written = m.group("unit")
        return m.group("base").strip(), unit_of_word(written), written
    m = _SLASH.match(text)
    if m and m.group("base") and unit_of_word(m.group("unit")):
        return m.group("base").strip(), unit_of_word(m.group("unit")), m.group("unit")
    m = _SUFFIX.match(text)
    if m:
        return m.group("base").strip(), unit_of_word(m.group("unit")), m.group("unit")
    return text, None, None


def normalise(name: str) -> str:
    """A header name without its unit, lower case, blanks, '-', '.' and '/' as '_'."""
    base = split_unit(name)[0].lower()
    return re.sub(r"[\s\-./]+", "_", base).strip("_")


# Header names (normalised) -> role.
NAMES = {
    "azimuth": {
        "az", "azimuth", "azim", "az_deg", "azimuth_deg", "raw_az", "az_raw", "cmd_az", "az_cmd", "commanded_az",
        "az_commanded", "enc_az", "az_enc", "encoder_az", "az_encoder", "requested_az", "az_req",
    },
    "elevation": {
        "el", "elevation", "elev", "alt", "altitude", "el_deg", "elevation_deg", "alt_deg", "raw_el", "el_raw",
        "cmd_el", "el_cmd", "commanded_el", "el_commanded", "enc_el", "el_enc", "encoder_el", "el_encoder",
        "raw_alt", "alt_raw", "requested_el", "el_req",
    },
    "azimuth_offset": {
        "daz", "dxel", "xel", "dx", "delta_az", "deltaaz", "delta_xel", "d_az", "d_xel", "az_off", "az_offset",
        "off_az", "offset_az", "xel_off", "xel_offset", "off_xel", "offset_xel", "cross_el", "cross_elevation",
        "crossel", "daz_cos_el", "dazcosel", "daz_cosel", "delta_cross_el", "az_offset_cos_el",
    },
    "elevation_offset": {
        "del", "delev", "delta_el", "deltael", "d_el", "el_off", "el_offset", "off_el", "offset_el", "dalt",
        "delta_alt", "d_alt", "alt_off", "alt_offset", "off_alt", "offset_alt", "dy",
    },
}  # fmt: skip
_ERROR_WORDS = ("err", "sigma", "unc", "std")
_AZ_WORDS = ("az", "xel", "cross")
_EL_TOKENS = {"el", "del", "alt", "dalt", "elev", "delev", "elevation", "altitude", "eloff"}


def role_of(name: str) -> str | None:
    """The role (:data:`pointax.io.offsets.OFFSET_ROLES`) a header name stands for, or
    None."""
    n = normalise(name)
    for role, names in NAMES.items():
        if n in names:
            return role
    if any(w in n for w in _ERROR_WORDS):
        rest = n
        for w in ("uncertainty", "sigma", "error", "err", "unc", "std"):
            rest = rest.replace(w, "_")
        parts = [p for p in rest.split("_") if p]
        az = any(any(w in p for w in _AZ_WORDS) for p in parts)
        el = any(p in _EL_TOKENS for p in parts)
        if az and not el:
            return "azimuth_error"
        if el and not az:
            return "elevation_error"
        if set(parts) <= {"pos", "position", "offset", "off", "pointing", "total", "radial"}:
            return "error"
    return None


def header_fields(record: str, csv: bool) -> list[str]:
    """The fields of a header record: split at commas (``csv``) or blanks; in a
    blank-separated header a unit written apart (``dxel [arcmin]``, ``el (deg)``)
    belongs to the name before it."""
    if csv:
        return [f.strip() for f in record.split(",")]
    fields: list[str] = []
    for token in record.split():
        if fields and re.fullmatch(r"[\[({<][^\])}>]*[\])}>]", token):
            fields[-1] = f"{fields[-1]} {token}"
        else:
            fields.append(token)
    return fields


# ------------------------------------------------------------------ auxiliary readings

READING_NAMES = {
    "temperature": {
        "temperature", "temp", "t_air", "tair", "air_temp", "air_temperature", "temp_air", "ambient_temperature",
        "ambient_temp", "t_amb", "tamb", "t_ambient", "outside_temperature", "outside_temp", "temperature_air",
    },
    "pressure": {
        "pressure", "press", "p_air", "pair", "air_pressure", "pressure_air", "barometric_pressure", "baro",
        "barometer", "atm_pressure", "atmospheric_pressure",
    },
    "humidity": {"humidity", "hum", "rh", "relative_humidity", "rel_humidity", "humidity_rel"},
    "rotator": {"rotator", "rot", "rotator_angle", "rot_angle", "rotangle", "rotator_position", "rot_pos"},
    "tilt_1": {"tilt_1", "tilt1", "tilt_x", "tiltx", "tilt_a", "tilta"},
    "tilt_2": {"tilt_2", "tilt2", "tilt_y", "tilty", "tilt_b", "tiltb"},
    "time": {
        "time", "mjd", "time_mjd", "mjd_utc", "mjd_obs", "jd", "time_jd", "date", "datetime", "date_time", "utc",
        "time_utc", "utc_time", "timestamp", "obs_time", "time_obs", "date_obs", "obs_date", "epoch", "unix_time",
    },
}  # fmt: skip
"""Standard reading (:data:`pointax.core.readings.READINGS`) -> the header names
(normalised: :func:`normalise`) an offsets table's extra column may carry for it."""
_READING_OF = {n: reading for reading, names in READING_NAMES.items() for n in names}

READING_UNITS = {
    "temperature": {
        "c": ("deg C", 1.0, 0.0), "degc": ("deg C", 1.0, 0.0), "deg_c": ("deg C", 1.0, 0.0), "°c": ("deg C", 1.0, 0.0),
        "celsius": ("deg C", 1.0, 0.0), "k": ("K", 1.0, -273.15), "kelvin": ("K", 1.0, -273.15),
        "f": ("deg F", 5.0 / 9.0, -32.0 * 5.0 / 9.0), "degf": ("deg F", 5.0 / 9.0, -32.0 * 5.0 / 9.0),
        "°f": ("deg F", 5.0 / 9.0, -32.0 * 5.0 / 9.0),
    },
    "pressure": {
        "hpa": ("hPa", 1.0, 0.0), "mbar": ("mbar", 1.0, 0.0), "mb": ("mb", 1.0, 0.0), "millibar": ("mbar", 1.0, 0.0),
        "pa": ("Pa", 0.01, 0.0), "kpa": ("kPa", 10.0, 0.0), "mmhg": ("mmHg", 1.33322387415, 0.0),
        "torr": ("Torr", 1.33322368421, 0.0), "inhg": ("inHg", 33.8638866667, 0.0), "bar": ("bar", 1000.0, 0.0),
    },
    "humidity": {
        "%": ("%", 0.01, 0.0), "percent": ("%", 0.01, 0.0), "pct": ("%", 0.01, 0.0), "fraction": ("fraction", 1.0, 0.0),
        "1": ("fraction", 1.0, 0.0),
    },
}  # fmt: skip
"""Standard reading -> unit word (lower case) -> ``(unit, scale, shift)``: the value in
the standard unit is ``scale * value + shift``."""


_READING_SUFFIX = re.compile(
    r"^(?P<base>.+?)[_\s\-]+(?P<unit>hpa|mbar|kpa|pa|mmhg|degc|degf|celsius|kelvin|percent|pct|mjd|jd)$", re.IGNORECASE
)


def _reading_parts(name: str) -> tuple[str, str | None, str | None]:
    """``(normalised base, angle unit, unit as written)`` of a header name, with the
    unit words of readings (``pressure_hpa``, ``temp_kelvin``) also taken off as a suffix."""
    base, unit, written = split_unit(name)
    if written is None:
        m = _READING_SUFFIX.match(base.strip())
        if m:
            base, written = m.group("base"), m.group("unit")
    return re.sub(r"[\s\-./]+", "_", base.lower()).strip("_"), unit, written


def reading_of(name: str) -> str | None:
    """The standard reading an offsets table's header name stands for (``"T_air [C]"``
    -> ``"temperature"``, ``"MJD"`` -> ``"time"``, ``"pressure_hpa"`` -> ``"pressure"``),
    or None."""
    base, _, written = _reading_parts(name)
    if written is not None and written.lower() in ("mjd", "jd") and base in READING_NAMES["time"]:
        return "time"
    return _READING_OF.get(base)


def reading_unit(reading: str, name: str) -> tuple[str, float, float] | None:
    """``(unit, scale, shift)`` of the unit a header name ``name`` gives the standard
    reading ``reading`` (``"T_air [K]"``), None when it gives none. For ``time`` the
    unit is returned as written (``("mjd", 1, 0)``, ``("jd", 1, 0)``) for the reader.

    Raises:
        ValueError: for a unit this reading does not take.
    """
    _, unit, written = _reading_parts(name)
    if written is None:
        return None
    word = written.strip().lower().replace(" ", "")
    if reading == "time":
        if word in ("mjd", "jd", "iso", "utc", "s", "unix"):
            return (word, 1.0, 0.0)
        raise ValueError(f"unit {written!r} is not one pointax reads for time (mjd, jd, unix, iso)")
    table = READING_UNITS.get(reading)
    if table is not None and word in table:
        return table[word]
    if reading in ("rotator", "tilt_1", "tilt_2") and unit is not None:
        return (unit, 1.0, 0.0)  # an angle unit: converted by the reader
    known = ", ".join(sorted(table)) if table else "none"
    raise ValueError(f"unit {written!r} is not one pointax reads for {reading} (units it reads: {known})")


# ------------------------------------------------------------------ the command line's --columns

COLUMN_ALIASES = {
    "azimuth": ("az", "azimuth"),
    "elevation": ("el", "elevation", "alt"),
    "azimuth_offset": ("daz", "dxel", "xel", "azimuth_offset"),
    "elevation_offset": ("del", "delev", "dalt", "elevation_offset"),
    "azimuth_error": ("daz_err", "dxel_err", "az_err", "azimuth_error"),
    "elevation_error": ("del_err", "el_err", "elevation_error"),
    "error": ("err", "error", "sigma"),
}
"""Role -> the words ``--columns`` accepts for it (whether the azimuth offset is
``dA cos E`` or a plain ``dA`` is ``--plain-daz``'s business, not the word's)."""
_ALIAS = {word: role for role, words in COLUMN_ALIASES.items() for word in words}
_SKIP = ("-", "_", "skip", "")


def _role(word: str, where: str) -> str:
    role = _ALIAS.get(word.strip().lower())
    if role is None:
        known = "; ".join(f"{role}: {' '.join(words)}" for role, words in COLUMN_ALIASES.items())
        raise ValueError(f"--columns: {where}{word!r} is not a column role (roles and their words: {known}; '_' skips a column)")
    return role


def parse_columns_option(text: str) -> dict[str, int | str] | tuple[str | None, ...]:
    """The ``columns`` of :func:`pointax.io.read_offsets` from the text of
    ``--columns``.

    * roles in column order, ``_`` (or ``-``, ``skip``) skipping one:
      ``"_,az,el,dxel,del"`` (a name column, then the four) -> ``(None, "azimuth",
      "elevation", ...)``; on the command line a list that starts with ``-`` needs
      ``--columns=-,az,...``, hence ``_``;
    * ``ROLE=WHERE`` pairs, ``WHERE`` a 1-based column number or a header name:
      ``"az=2,el=3,dxel=6,del=7"``, ``"az=AZ_CMD,dxel=xoff"``.

    Items are separated by commas (or blanks when there is no comma). Role words:
    :data:`COLUMN_ALIASES`.

    Raises:
        ValueError: naming the item that is not understood.
    """
    items = [s.strip() for s in (text.split(",") if "," in text else text.split())]
    if not any(items):
        raise ValueError("--columns is empty: give the roles of the columns in order (az,el,dxel,del) or ROLE=COLUMN pairs")
    if any("=" in s for s in items):
        mapping: dict[str, int | str] = {}
        for item in items:
            if not item:
                continue
            if "=" not in item:
                raise ValueError(f"--columns: {item!r} has no '=': give every column as ROLE=NUMBER or ROLE=NAME, or only roles in order")
            word, where = (s.strip() for s in item.split("=", 1))
            role = _role(word, "")
            if role in mapping:
                raise ValueError(f"--columns: {role} ({word!r}) is given twice")
            if not where:
                raise ValueError(f"--columns: {item!r}: no column after '='")
            if re.fullmatch(r"[0-9]+", where):
                if int(where) < 1:
                    raise ValueError(f"--columns: {item!r}: columns are numbered from 1")
                mapping[role] = int(where)
            else:
                mapping[role] = where
        return mapping
    roles: list[str | None] = []
    for k, item in enumerate(items, 1):
        roles.append(None if item.lower() in _SKIP else _role(item, f"column {k}: "))
    repeated = sorted({r for r in roles if r is not None and roles.count(r) > 1})
    if repeated:
        raise ValueError(f"--columns: {', '.join(repeated)} given twice")
    return tuple(roles)
