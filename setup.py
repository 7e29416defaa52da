"""Package discovery for the folder layout of DESIGN §2 (metadata is in pyproject.toml).

One import name covers several top-level folders: ``feeler/`` is ``feeler`` and
``models/``, ``calib/``, ``hardware/``, ``reports/`` are ``feeler.models`` and so on.
Every sub-folder holding an ``__init__.py`` becomes a sub-package, so adding one needs
no edit here.
"""
from pathlib import Path

from setuptools import setup

ROOTS = {"feeler": "feeler", "feeler.models": "models", "feeler.calib": "calib",
         "feeler.hardware": "hardware", "feeler.reports": "reports"}


def _packages():
    found = []
    for name, folder in ROOTS.items():
        for init in sorted(Path(folder).rglob("__init__.py")):
            rel = init.parent.relative_to(folder)
            found.append(".".join((name, *rel.parts)) if rel.parts else name)
    return sorted(set(found))


setup(packages=_packages(), package_dir=ROOTS)
