"""WeasyPrint's notices about its own installation, kept from the user while a PDF is written.

WeasyPrint 70 subsets each embedded font. Without the system library HarfBuzz-Subset
(>= 4.1.0) it uses fontTools instead, which gives the same PDF, and it logs a WARNING
once per font ("Using fontTools instead of HarfBuzz-Subset for font ..."). That was
five lines on every `feeler report` and every `feeler demo`, about no file of the user's.
:func:`font_subsetting_notices_dropped` removes those records from the ``weasyprint``
logger and says it once at DEBUG (``feeler -vv``). WeasyPrint's other warnings and
errors (a CSS rule it ignores, a resource it cannot fetch) still come through.
"""
from __future__ import annotations

import contextlib
import logging
from typing import Iterator

__all__ = ["font_subsetting_notices_dropped", "FONT_SUBSETTING"]

_LOGGER = "weasyprint"
FONT_SUBSETTING = "Using fontTools instead of HarfBuzz-Subset"     # how the notice starts
_log = logging.getLogger(__name__)


class _DropFontSubsetting(logging.Filter):
    def __init__(self):
        super().__init__()
        self.fonts: list[str] = []

    def filter(self, record: logging.LogRecord) -> bool:
        if isinstance(record.msg, str) and record.msg.startswith(FONT_SUBSETTING):
            self.fonts.append(str(record.args[0]) if record.args else "?")
            return False
        return True


@contextlib.contextmanager
def font_subsetting_notices_dropped() -> Iterator[None]:
    """Within: WeasyPrint's font-subsetting notices are not emitted (one DEBUG line after)."""
    log = logging.getLogger(_LOGGER)
    drop = _DropFontSubsetting()
    log.addFilter(drop)
    try:
        yield
    finally:
        log.removeFilter(drop)
        if drop.fonts:
            _log.debug("WeasyPrint subset %d font(s) with fontTools (no HarfBuzz-Subset >= 4.1.0): %s",
                       len(drop.fonts), ", ".join(sorted(set(drop.fonts))))
