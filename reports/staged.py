"""Write a set of files under temporary names, then put them all in place at the end.

A report is three files that belong together (``report.html``, ``report.pdf``,
``report-manifest.json``). Written one after the other, a Ctrl-C during the PDF (the
longest step) left a new ``report.html`` beside the previous report's PDF and manifest.
:func:`staged` writes them under hidden temporary names in the same directory and
renames them over the old ones only once all are written (``os.replace``, atomic per
file on POSIX). An error or an interrupt before that removes the temporary files and
leaves the previous set as it was. A Ctrl-C that arrives during the renames (a few
system calls) is ignored (:func:`feeler.children.sigint_ignored`), so the set is never split;
the files are then complete.
"""
from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import Iterator

from feeler.children import sigint_ignored

__all__ = ["StagedFiles", "staged"]


class StagedFiles:
    """Files being written into ``out`` under temporary names (see :func:`staged`)."""

    def __init__(self, out: Path):
        self.out = Path(out)
        self._temp: dict[str, Path] = {}

    def path(self, name: str) -> Path:
        """The temporary path to write ``name`` to (``out/.name.<pid>.partial``)."""
        temp = self.out / f".{name}.{os.getpid()}.partial"
        self._temp[name] = temp
        return temp

    def install(self) -> None:
        """Rename every written file to its final name, all together."""
        with sigint_ignored():                   # a Ctrl-C now is dropped: the set is never split
            for name, temp in list(self._temp.items()):
                os.replace(temp, self.out / name)
                del self._temp[name]

    def discard(self) -> None:
        """Remove the temporary files not installed (an error or an interrupt came first)."""
        for temp in self._temp.values():
            temp.unlink(missing_ok=True)
        self._temp.clear()


@contextlib.contextmanager
def staged(out: str | Path) -> Iterator[StagedFiles]:
    """Within: write each file to ``files.path(name)``, then call ``files.install()``.
    Leaving the block any other way (an exception, Ctrl-C) removes what was written."""
    files = StagedFiles(Path(out))
    try:
        yield files
    finally:
        files.discard()
