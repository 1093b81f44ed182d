"""Recordings: the mismatch tool's input (format: ``docs/recording-format.md``).

A recording is a CSV file with a header row, SI units, one sample per row:

=================  ======  ==========================================================
column             unit    required
=================  ======  ==========================================================
``time``           s       yes, strictly increasing
``field``          A/m     yes, or ``current`` (A) with ``turns_per_meter`` in the sidecar
``magnetization``  A/m     at least one of magnetization / flux_density / displacement
``flux_density``   T       instead of magnetization: B, read as M = B/mu0 - H
``displacement``   m
``temperature``    K       optional
=================  ======  ==========================================================

An optional sidecar ``<same stem>.json`` holds metadata (``turns_per_meter``,
``material``, ``notes``). Every problem with a file raises one ``ValueError`` whose
one-line message names the file, the row (1-based, counting the header as row 1) or
column, and the problem; nothing is guessed silently.
"""

from __future__ import annotations

import codecs
import csv
import json
import math
import os
from dataclasses import dataclass, field as dataclass_field
from pathlib import Path

import numpy as np

#: Fewest samples for which a blocked train/held-out split still leaves both parts usable.
MIN_SAMPLES = 200

OUTPUT_CHANNELS = ("magnetization", "displacement")
KNOWN_COLUMNS = ("time", "field", "current", "magnetization", "flux_density", "displacement", "temperature")
#: Vacuum permeability, H/m (B = mu0*(H + M)).
MU0 = 4e-7 * math.pi


@dataclass(frozen=True)
class Recording:
    """One recording, SI units; arrays are read-only and share the length of ``time``.

    Attributes
    ----------
    time : ndarray, s
    field : ndarray, applied field H in A/m (converted from ``current`` if needed)
    magnetization : ndarray or None, A/m
    displacement : ndarray or None, m
    temperature : ndarray or None, K
    metadata : dict, the sidecar's content (may be empty)
    source : str, where the recording came from (a path or a description)
    """

    time: np.ndarray
    field: np.ndarray
    magnetization: np.ndarray | None = None
    displacement: np.ndarray | None = None
    temperature: np.ndarray | None = None
    metadata: dict = dataclass_field(default_factory=dict)
    source: str = "<memory>"

    def __post_init__(self):
        where = self.source
        time = _column_array(self.time, "time", where)
        arrays = {"time": time}
        for name in ("field", "magnetization", "displacement", "temperature"):
            value = getattr(self, name)
            if value is None:
                if name == "field":
                    raise ValueError(f"{where}: missing column 'field' (or 'current')")
                continue
            arrays[name] = _column_array(value, name, where)
            if arrays[name].shape != time.shape:
                raise ValueError(f"{where}: column '{name}' has {arrays[name].size} samples but "
                                 f"'time' has {time.size}")
        if "magnetization" not in arrays and "displacement" not in arrays:
            raise ValueError(f"{where}: needs a 'magnetization' or a 'displacement' column")
        steps = np.diff(time)
        if np.any(steps <= 0):
            i = int(np.argmax(steps <= 0)) + 1
            raise ValueError(f"{where}: row {i + 2}: time {float(time[i])!r} s is not greater than the "
                             f"previous {float(time[i - 1])!r} s (time must be strictly increasing)")
        if time.size < MIN_SAMPLES:
            raise ValueError(f"{where}: only {time.size} samples; at least {MIN_SAMPLES} are needed "
                             f"to split the recording into a fitting block and a held-out block")
        for name, arr in arrays.items():
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "metadata", dict(self.metadata))

    @property
    def channels(self) -> tuple[str, ...]:
        """The output channels present, in the order ``magnetization``, ``displacement``."""
        return tuple(name for name in OUTPUT_CHANNELS if getattr(self, name) is not None)

    @property
    def size(self) -> int:
        return int(self.time.size)

    def output(self, name: str) -> np.ndarray:
        value = getattr(self, name)
        if value is None:
            raise KeyError(f"{self.source}: recording has no '{name}' column")
        return value


def _column_array(values, name, where):
    arr = np.array(values, dtype=np.float64)
    if arr.ndim != 1:
        raise ValueError(f"{where}: column '{name}' must be 1-D, got shape {arr.shape}")
    bad = ~np.isfinite(arr)
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"{where}: row {i + 2}, column '{name}': value {float(arr[i])!r} is not finite")
    arr.setflags(write=False)
    return arr


def sidecar_path(path) -> Path:
    path = Path(path)
    return path.with_suffix(".json")


#: Delimiters a recording's CSV may use, tried in this order on the header row: the comma of the format,
#: and the semicolon and tab that spreadsheets in many locales write.
DELIMITERS = (",", ";", "\t")
#: Bytes read first to recognize a binary file (NUL bytes) before reading the whole of it.
SNIFF_BYTES = 65536


def read_recording(path) -> Recording:
    """Read a recording CSV (and its sidecar JSON, if present). See the module docstring.

    A UTF-8 byte-order mark is skipped and a ``;`` or tab delimiter is accepted (a spreadsheet's
    export), each said so in the recording's ``metadata["read_notes"]``. Raises ``ValueError`` (one
    line: file, row/column, problem) for any malformed input and ``OSError`` if the file cannot be opened.
    """
    path = Path(path)
    where = str(path)
    if path.is_dir():
        raise ValueError(f"{where}: is a directory, not a recording CSV")
    metadata = _read_sidecar(path)
    text, notes = _read_text(path, where)
    lines = text.splitlines()
    if not lines or not any(line.strip() for line in lines):
        raise ValueError(f"{where}: empty file (expected a header row and samples)")
    delimiter = _delimiter(lines[0])
    if delimiter != ",":
        notes.append(f"columns separated by {'a tab' if delimiter == chr(9) else repr(delimiter)}, not a comma")
    try:
        rows = list(csv.reader(lines, delimiter=delimiter))
    except csv.Error as error:
        raise ValueError(f"{where}: not a readable CSV file ({error})") from None
    header = _checked_header(rows[0], where)
    data = _columns(rows, header, where, delimiter)
    if notes:
        metadata = {**metadata, "read_notes": notes}
    return _recording(data, metadata, path, where)


def _read_text(path: Path, where: str) -> tuple[str, list]:
    """The file's text, and notes on what was accepted (a byte-order mark). A binary file is recognized
    from its first ``SNIFF_BYTES`` bytes, without reading the rest."""
    notes = []
    with open(path, "rb") as handle:
        head = handle.read(SNIFF_BYTES)
        if b"\x00" in head and not head.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
            raise ValueError(f"{where}: contains NUL bytes; not a text CSV file")
        raw = head + handle.read()
    if raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        raise ValueError(f"{where}: UTF-16 text (it starts with a UTF-16 byte-order mark); save it as UTF-8")
    if raw.startswith(codecs.BOM_UTF8):
        raw = raw[len(codecs.BOM_UTF8):]
        notes.append("a UTF-8 byte-order mark at the start of the file was skipped")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as error:
        raise ValueError(f"{where}: not a UTF-8 text file ({error.reason} at byte {error.start})") from None
    if "\x00" in text:
        raise ValueError(f"{where}: contains NUL bytes; not a text CSV file")
    return text, notes


def _delimiter(header_line: str) -> str:
    """The delimiter whose split of the header row names a ``time`` column (the comma if none does)."""
    for delimiter in DELIMITERS:
        if "time" in (cell.strip().lower() for cell in header_line.split(delimiter)):
            return delimiter
    return ","


def _checked_header(first_row, where) -> list:
    """The header row's column names (lower case), with the columns the format requires."""
    header = [cell.strip().lower() for cell in first_row]
    if len(set(header)) != len(header):
        duplicate = next(h for h in header if header.count(h) > 1)
        raise ValueError(f"{where}: row 1: column '{duplicate}' appears twice in the header")
    if "time" not in header:
        raise ValueError(f"{where}: row 1: missing column 'time' (header is {','.join(header)[:120]!r})")
    if "field" not in header and "current" not in header:
        raise ValueError(f"{where}: row 1: missing column 'field' (or 'current' with turns_per_meter "
                         f"in the sidecar)")
    if not any(name in header for name in OUTPUT_CHANNELS + ("flux_density",)):
        raise ValueError(f"{where}: row 1: needs a 'magnetization' or a 'displacement' column "
                         "('flux_density' in T may stand for magnetization)")
    if "magnetization" in header and "flux_density" in header:
        raise ValueError(f"{where}: row 1: give 'magnetization' or 'flux_density', not both")
    return header


def _columns(rows, header, where, delimiter=",") -> dict:
    """The known columns' values, row by row, each a finite number."""
    wanted = [name for name in KNOWN_COLUMNS if name in header]
    index = {name: header.index(name) for name in wanted}
    data = {name: [] for name in wanted}
    for row_number, row in enumerate(rows[1:], start=2):
        if not row or all(not cell.strip() for cell in row):
            continue  # blank lines carry no sample
        if len(row) != len(header):
            raise ValueError(f"{where}: row {row_number}: has {len(row)} cells but the header has "
                             f"{len(header)}")
        for name in wanted:
            data[name].append(_number(row[index[name]].strip(), where, row_number, name, delimiter))
    if not data["time"]:
        raise ValueError(f"{where}: no samples after the header row")
    return data


def _number(cell, where, row_number, name, delimiter) -> float:
    try:
        value = float(cell)
    except ValueError:
        hint = " (a decimal comma? write a decimal point)" if delimiter != "," and "," in cell else ""
        raise ValueError(f"{where}: row {row_number}, column '{name}': {cell[:40]!r} is not "
                         f"a number{hint}") from None
    if not math.isfinite(value):
        raise ValueError(f"{where}: row {row_number}, column '{name}': {cell[:40]!r} is not a "
                         f"finite number")
    return value


def _recording(data, metadata, path, where) -> Recording:
    """The :class:`Recording` in SI units: the field from a current (H = n*I) and M from B where given."""
    if "field" in data:
        field = np.array(data["field"])
    else:
        turns = metadata.get("turns_per_meter")
        if not isinstance(turns, (int, float)) or isinstance(turns, bool) or not (turns > 0) \
                or not math.isfinite(turns):
            raise ValueError(f"{where}: column 'current' needs a positive number 'turns_per_meter' (1/m) "
                             f"in the sidecar {sidecar_path(path).name}, got {turns!r}")
        field = np.array(data["current"]) * float(turns)  # H = n*I, eq. (11)
    magnetization = np.array(data["magnetization"]) if "magnetization" in data else None
    if "flux_density" in data:
        magnetization = np.array(data["flux_density"]) / MU0 - field  # B = mu0*(H + M), B in T
    return Recording(
        time=np.array(data["time"]), field=field, magnetization=magnetization,
        displacement=np.array(data["displacement"]) if "displacement" in data else None,
        temperature=np.array(data["temperature"]) if "temperature" in data else None,
        metadata=metadata, source=where,
    )


def _read_sidecar(path: Path) -> dict:
    side = sidecar_path(path)
    if not side.exists():
        return {}
    try:
        content = json.loads(side.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"{side}: sidecar is not valid JSON ({str(error).splitlines()[0]})") from None
    if not isinstance(content, dict):
        raise ValueError(f"{side}: sidecar must hold a JSON object, got {type(content).__name__}")
    return content


def write_recording(path, recording: Recording, metadata: dict | None = None) -> Path:
    """Write ``recording`` as CSV (17 significant digits) plus a sidecar if ``metadata``."""
    path = Path(path)
    if path.parent and not path.parent.exists():
        os.makedirs(path.parent, exist_ok=True)
    names = ["time", "field"] + list(recording.channels)
    if recording.temperature is not None:
        names.append("temperature")
    columns = np.column_stack([getattr(recording, n) for n in names])
    with open(path, "w", newline="", encoding="utf-8") as handle:
        handle.write(",".join(names) + "\n")
        np.savetxt(handle, columns, delimiter=",", fmt="%.17g")
    if metadata:
        sidecar_path(path).write_text(json.dumps(metadata, indent=2) + "\n", encoding="utf-8")
    return path
