"""A Markdown page's marked section, rewritten by the command that measures what it holds."""

import sys
from pathlib import Path


def write_marked(path: Path, section: str, text: str):
    """Replaces what lies between `<!-- SECTION:begin -->` and `<!-- SECTION:end -->` in `path`
    by `text`; stops with an error naming the file where it has no such section."""
    begin, end = f"<!-- {section}:begin -->", f"<!-- {section}:end -->"
    page = path.read_text()
    if begin not in page or end not in page:
        sys.exit(f"error: {path}: no `{begin}` … `{end}` section to write the table into")
    head, rest = page.split(begin, 1)
    _, tail = rest.split(end, 1)
    path.write_text(f"{head}{begin}\n{text}\n{end}{tail}")
