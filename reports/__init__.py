"""Reports: one run directory → a self-contained ``report.html`` and ``report.pdf``.

``build_report(run_dir)`` (in :mod:`feeler.reports.build`) is the entry point;
:func:`discover` says which sections a run can fill and which files are missing.
Plotting and PDF libraries are imported only while a report is built.
"""
from feeler.reports.build import Report, build_report
from feeler.reports.discover import Inventory, discover

__all__ = ["build_report", "Report", "discover", "Inventory"]
