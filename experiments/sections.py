"""Generated sections of a page: the text between ``<!-- section:AREA -->`` and ``<!-- /section:AREA -->``."""

from __future__ import annotations

import pathlib


def update_readme(path: pathlib.Path, body: str, area: str = "benchmark"):
    """Replace only the text between ``<!-- section:AREA -->`` and ``<!-- /section:AREA -->``."""
    text = path.read_text()
    start, end = f"<!-- section:{area} -->", f"<!-- /section:{area} -->"
    if text.count(start) != 1 or text.count(end) != 1 or text.index(start) > text.index(end):
        raise ValueError(f"{path}: expected exactly one {start} ... {end} pair")
    head, rest = text.split(start)
    _, tail = rest.split(end)
    path.write_text(f"{head}{start}\n{body.strip()}\n{end}{tail}")
