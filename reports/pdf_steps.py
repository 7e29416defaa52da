"""WeasyPrint's rendering steps as the report's progress stages.

Laying out the PDF is the longest stage of a report (WeasyPrint 70: about half of a
demo's report). WeasyPrint announces its steps on its ``weasyprint.progress`` logger at
INFO ("Step 5 - Creating layout - Page 3", "Step 6 - Creating PDF"; see its
``logger.py``); :func:`weasyprint_steps` turns them into ``progress`` calls: parsing,
styling, building the boxes, one per page laid out, and writing. Pages already laid out
("up-to-date" on a repagination) are not repeated.
"""
from __future__ import annotations

import contextlib
import logging
import re
from typing import Callable

__all__ = ["weasyprint_steps", "step_text"]

_LOGGER = "weasyprint.progress"
_PAGE = re.compile(r"Step 5 - Creating layout - Page (\d+)$")


def step_text(message: str) -> str | None:
    """The progress text of one WeasyPrint step message, or None for steps not shown."""
    page = _PAGE.match(message)
    if page:
        return f"pdf: laying out page {page.group(1)}"
    if message.startswith("Step 1 "):
        return "pdf: parsing the html"
    if message.startswith("Step 3 "):
        return "pdf: applying the styles"
    if message.startswith("Step 4 "):
        return "pdf: building the boxes"
    if message.startswith("Step 5 - Creating layout - Repagination"):
        return "pdf: " + message.split(" - ")[-1].lower().replace("#", "pass ")
    if message.startswith("Step 6 "):
        return "pdf: writing the file"
    return None


class _Steps(logging.Handler):
    def __init__(self, progress: Callable[[str], None]):
        super().__init__(logging.INFO)
        self.progress = progress

    def emit(self, record: logging.LogRecord) -> None:
        text = step_text(record.getMessage())
        if text is not None:
            self.progress(text)


@contextlib.contextmanager
def weasyprint_steps(progress: Callable[[str], None]):
    """Within: WeasyPrint's steps call ``progress(text)``; they do not reach other log
    handlers meanwhile (the root's would print them as INFO lines)."""
    log = logging.getLogger(_LOGGER)
    saved = log.level, log.propagate
    handler = _Steps(progress)
    log.setLevel(logging.INFO)
    log.propagate = False
    log.addHandler(handler)
    try:
        yield
    finally:
        log.removeHandler(handler)
        log.setLevel(saved[0])
        log.propagate = saved[1]
