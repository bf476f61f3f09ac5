"""What the bench scripts share in their reports: the machine they ran on, and tables."""

from __future__ import annotations

import dataclasses
import os
import platform
from collections.abc import Sequence


def cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def load_average() -> str:
    """The 1/5/15-minute load at the end of the run: other work competing for the cores."""
    try:
        return "{:.2f} / {:.2f} / {:.2f} (1 / 5 / 15 min, at the end)".format(*os.getloadavg())
    except OSError:
        return "unknown"


def table_lines(
    headers: Sequence[str],
    right_aligned: Sequence[bool],
    rows: Sequence[Sequence[str]],
    markdown: bool,
) -> list[str]:
    """A table's lines: Markdown, or plain text with aligned columns."""
    if markdown:
        lines = ["| " + " | ".join(headers) + " |"]
        lines.append("|" + "|".join("---:" if right else "---" for right in right_aligned) + "|")
        lines += ["| " + " | ".join(row) + " |" for row in rows]
        return lines
    widths = [max(len(row[k]) for row in [headers, *rows]) for k in range(len(headers))]

    def line(values: Sequence[str]) -> str:
        padded = (
            value.rjust(width) if right else value.ljust(width)
            for value, width, right in zip(values, widths, right_aligned, strict=True)
        )
        return " | ".join(padded).rstrip()

    return [line(headers), "-+-".join("-" * w for w in widths), *(line(r) for r in rows)]


@dataclasses.dataclass
class Output:
    """Prints headings, tables and notes as plain text or Markdown."""

    markdown: bool

    def heading(self, text: str) -> None:
        print(f"\n### {text}\n" if self.markdown else f"\n{text}\n{'=' * len(text)}")

    def note(self, text: str) -> None:
        print(f"\n{text}" if self.markdown else text)

    def table(self, header: Sequence[str], rows: Sequence[Sequence[str]]) -> None:
        """The first column (names) left-aligned, the others (figures) right-aligned."""
        right = [False] + [True] * (len(header) - 1)
        print("\n".join(table_lines(header, right, rows, self.markdown)))
