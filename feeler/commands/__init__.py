"""Sub-commands of ``feeler``; one module each (see :mod:`feeler.cli`)."""
