"""Writing benchmark results into the Markdown files of docs/: one section per study."""

from __future__ import annotations

from pathlib import Path


def replace_section(path: Path, head: str, section: str, preamble: str = "") -> Path:
    """Replace the section that starts with the heading line ``head`` (up to the next ``## ``
    heading) by ``section``, or append it; other sections are kept as they are.  A missing
    file is created with ``preamble``."""
    path = Path(path)
    text = path.read_text(encoding="utf-8") if path.exists() else preamble
    if head in text:
        start = text.index(head)
        nxt = text.find("\n## ", start + len(head))
        text = text[:start] + section + (text[nxt + 1:] if nxt >= 0 else "")
    else:
        text = text.rstrip() + "\n\n" + section
    path.write_text(text, encoding="utf-8")
    return path
