"""A small report document written as both Markdown and self-contained-structure HTML.

A report is a list of blocks (headings, paragraphs, bullet lists, tables, images). The same
blocks give ``report.md`` (readable on GitHub) and ``report.html`` (readable in a browser,
images linked by the same relative paths), so the two never disagree.
"""

from __future__ import annotations

import html
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from pilerl.io import write_text_atomic


@dataclass
class Report:
    """Blocks in reading order; ``add_*`` methods append and return ``self``."""

    title: str
    blocks: list[tuple[str, object]] = field(default_factory=list)

    def heading(self, text: str, level: int = 2) -> Report:
        self.blocks.append(("heading", (level, text)))
        return self

    def paragraph(self, text: str) -> Report:
        self.blocks.append(("paragraph", text))
        return self

    def bullets(self, items: Sequence[str]) -> Report:
        self.blocks.append(("bullets", list(items)))
        return self

    def table(self, header: Sequence[str], rows: Sequence[Sequence[object]]) -> Report:
        for row in rows:
            if len(row) != len(header):
                raise ValueError(f"table row {row!r} has {len(row)} cells, header {len(header)}")
        self.blocks.append(("table", (list(header), [[str(c) for c in r] for r in rows])))
        return self

    def image(self, path: str, caption: str) -> Report:
        """``path`` relative to the report's directory."""
        self.blocks.append(("image", (path, caption)))
        return self

    def to_markdown(self) -> str:
        lines = [f"# {self.title}", ""]
        for kind, content in self.blocks:
            if kind == "heading":
                level, text = content
                lines += ["#" * level + " " + text, ""]
            elif kind == "paragraph":
                lines += [content, ""]
            elif kind == "bullets":
                lines += [f"- {item}" for item in content] + [""]
            elif kind == "table":
                header, rows = content
                lines.append("| " + " | ".join(header) + " |")
                lines.append("|" + "|".join("---" for _ in header) + "|")
                lines += ["| " + " | ".join(row) + " |" for row in rows]
                lines.append("")
            elif kind == "image":
                path, caption = content
                lines += [f"![{caption}]({path})", "", f"*{caption}*", ""]
        return "\n".join(lines)

    def to_html(self) -> str:
        e = inline_html
        parts = [
            "<!doctype html>",
            '<html><head><meta charset="utf-8">',
            f"<title>{html.escape(self.title)}</title>",
            "<style>body{font-family:sans-serif;max-width:60em;margin:2em auto;padding:0 1em}"
            "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;"
            "padding:.25em .6em;text-align:right}td:first-child,th:first-child{text-align:left}"
            "img{max-width:100%}figcaption{font-style:italic;color:#444}"
            "code{background:#f2f2f2;padding:0 .2em;border-radius:3px}</style>",
            "</head><body>",
            f"<h1>{e(self.title)}</h1>",
        ]
        for kind, content in self.blocks:
            if kind == "heading":
                level, text = content
                parts.append(f"<h{level}>{e(text)}</h{level}>")
            elif kind == "paragraph":
                parts.append(f"<p>{e(content)}</p>")
            elif kind == "bullets":
                parts.append("<ul>" + "".join(f"<li>{e(i)}</li>" for i in content) + "</ul>")
            elif kind == "table":
                header, rows = content
                parts.append("<table><tr>" + "".join(f"<th>{e(h)}</th>" for h in header) + "</tr>")
                for row in rows:
                    parts.append("<tr>" + "".join(f"<td>{e(c)}</td>" for c in row) + "</tr>")
                parts.append("</table>")
            elif kind == "image":
                path, caption = content
                parts.append(
                    f'<figure><img src="{html.escape(path)}" alt="{html.escape(caption)}">'
                    f"<figcaption>{e(caption)}</figcaption></figure>"
                )
        parts.append("</body></html>")
        return "\n".join(parts)

    def write(self, out_dir: str | Path, stem: str = "report") -> tuple[Path, Path]:
        """``<stem>.md`` and ``<stem>.html`` in ``out_dir``, each written atomically."""
        out_dir = Path(out_dir)
        markdown, page = out_dir / f"{stem}.md", out_dir / f"{stem}.html"
        write_text_atomic(markdown, self.to_markdown())
        write_text_atomic(page, self.to_html())
        return markdown, page


_CODE = re.compile(r"`([^`]+)`")
_LINK = re.compile(r"\[([^\]]+)\]\(([^)\s]+)\)")
_STRONG = re.compile(r"\*\*([^*]+)\*\*")
_EMPHASIS = re.compile(r"(?<![*\w])\*([^*\s][^*]*)\*(?![*\w])")


def inline_html(text: str) -> str:
    """Markdown's inline marks as HTML: `code`, [text](link), **strong**, *emphasis*.

    Everything else is escaped; code spans are kept verbatim (no marks inside them).
    """
    pieces = _CODE.split(text)  # odd indices: the insides of code spans
    out = []
    for i, piece in enumerate(pieces):
        if i % 2:
            out.append(f"<code>{html.escape(piece)}</code>")
            continue
        escaped = html.escape(piece, quote=False)
        escaped = _LINK.sub(lambda m: f'<a href="{html.escape(m[2])}">{m[1]}</a>', escaped)
        escaped = _STRONG.sub(r"<strong>\1</strong>", escaped)
        out.append(_EMPHASIS.sub(r"<em>\1</em>", escaped))
    return "".join(out)
