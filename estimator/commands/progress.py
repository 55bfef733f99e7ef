"""The progress bar of commands that work through many logs, on stderr (a terminal only)."""

from __future__ import annotations

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn


def logs_progress(console: Console, label: str = "{task.description}") -> Progress:
    """A bar per task: ``label``, done of all, elapsed time; gone when finished, and silent
    when ``console`` is not a terminal."""
    return Progress(
        TextColumn(label),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
        transient=True,
        disable=not console.is_terminal,
    )
