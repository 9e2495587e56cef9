"""A result's printable summary (statsmodels' ``Summary`` is the model): a header block of
``name: value`` lines and one table, as text (``str``, ``print``) and as HTML (Jupyter's
``_repr_html_``)."""
from __future__ import annotations

import html
import textwrap
from dataclasses import dataclass

__all__ = ["Summary"]

#: the notes below the table wrap at this many characters, or at the table's width if wider
TEXT_WIDTH = 100


@dataclass(frozen=True)
class Summary:
    """A header block and one table, already formatted as strings.

    Attributes
    ----------
    title : str
    header : tuple of (str, str)
        ``(name, value)`` lines above the table.
    columns : tuple of str
        The table's column names.
    rows : tuple of tuple of str
        The table's cells, one tuple per row.
    notes : tuple of str
        Lines below the table.
    align : tuple of str
        ``"<"`` (left) or ``">"`` (right, the default) per column of the text table.
    """

    title: str
    header: tuple[tuple[str, str], ...]
    columns: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    notes: tuple[str, ...] = ()
    align: tuple[str, ...] = ()

    def as_text(self) -> str:
        """The summary as fixed-width text."""
        width_name = max((len(k) for k, _ in self.header), default=0)
        lines = [self.title, "=" * max(len(self.title), 20)]
        lines += [f"{k + ':':<{width_name + 1}} {v}" for k, v in self.header]
        if self.columns:
            cells = [self.columns] + list(self.rows)
            widths = [max(len(r[j]) for r in cells) for j in range(len(self.columns))]
            align = tuple(self.align) + (">",) * (len(widths) - len(self.align))
            fmt = "  ".join(f"{{:{a}{w}}}" for a, w in zip(align, widths))
            rule = "-" * (sum(widths) + 2 * (len(widths) - 1))
            lines += [rule, fmt.format(*self.columns).rstrip(), rule] + [fmt.format(*r).rstrip() for r in self.rows]
            lines.append(rule)
        width = max(TEXT_WIDTH, max((len(x) for x in lines), default=0))
        lines += [textwrap.fill(n, width) for n in self.notes]
        return "\n".join(lines)

    def as_html(self) -> str:
        """The summary as an HTML fragment (escaped; no scripts, no styles beyond the table)."""
        e = html.escape
        head = "".join(f"<tr><th style='text-align:left'>{e(k)}</th><td style='text-align:left'>{e(v)}</td></tr>"
                       for k, v in self.header)
        parts = [f"<div><strong>{e(self.title)}</strong>", f"<table>{head}</table>"]
        if self.columns:
            th = "".join(f"<th>{e(c)}</th>" for c in self.columns)
            body = "".join("<tr>" + "".join(f"<td>{e(c)}</td>" for c in r) + "</tr>" for r in self.rows)
            parts.append(f"<table><thead><tr>{th}</tr></thead><tbody>{body}</tbody></table>")
        parts += [f"<p>{e(n)}</p>" for n in self.notes]
        return "".join(parts) + "</div>"

    def __str__(self) -> str:
        return self.as_text()

    def __repr__(self) -> str:
        return self.as_text()

    def _repr_html_(self) -> str:
        return self.as_html()
