"""WeasyPrint's advertised steps (its ``weasyprint.progress`` logger) as report stages."""
import logging

import pytest

from feeler.reports.pdf_steps import step_text, weasyprint_steps


@pytest.mark.parametrize("message, text", [
    ("Step 1 - Fetching and parsing HTML - HTML string", "pdf: parsing the html"),
    ("Step 2 - Fetching and parsing CSS - CSS string", None),
    ("Step 3 - Applying CSS", "pdf: applying the styles"),
    ("Step 4 - Creating formatting structure", "pdf: building the boxes"),
    ("Step 5 - Creating layout - Page 12", "pdf: laying out page 12"),
    ("Step 5 - Creating layout - Page 3 (up-to-date)", None),
    ("Step 5 - Creating layout - Repagination #1", "pdf: repagination pass 1"),
    ("Step 6 - Creating PDF", "pdf: writing the file"),
    ("Step 7 - Adding PDF metadata", None),
])
def test_step_text(message, text):
    assert step_text(message) == text


def test_steps_reach_progress_and_not_the_root_handlers(caplog):
    seen = []
    log = logging.getLogger("weasyprint.progress")
    with caplog.at_level(logging.INFO):
        with weasyprint_steps(seen.append):
            log.info("Step 5 - Creating layout - Page %d", 2)
            log.info("Step 5 - Creating layout - Page %d (up-to-date)", 1)
        log.info("Step 6 - Creating PDF")                   # after: no longer ours
    assert seen == ["pdf: laying out page 2"]
    assert [r.getMessage() for r in caplog.records] == ["Step 6 - Creating PDF"]
    assert log.handlers == [] and log.propagate
