"""Reports: one run directory → a self-contained ``report.html`` and ``report.pdf``.

``build_report(run_dir)`` (in :mod:`feeler.reports.build`) is the entry point;
:func:`discover` says what a run directory holds (recognised by its files, under any
names), the sections it fills and what each missing one would need.
Plotting and PDF libraries are imported only while a report is built.
"""
from feeler.reports.build import Report, build_report
from feeler.reports.discover import Inventory, discover

__all__ = ["build_report", "Report", "discover", "Inventory"]
